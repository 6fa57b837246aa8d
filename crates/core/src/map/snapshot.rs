//! The map as other threads see it: an immutable [`PointMapSnapshot`] behind an
//! `Arc`, handed over through a [`SnapshotCell`].
//!
//! Publication: the writer (the map stage) fills a snapshot and swaps the
//! `Arc` into the cell; a reader's [`SnapshotCell::load`] clones the `Arc`
//! (a reference-count increment under a mutex held for a pointer copy, never
//! while anything is built or read). Readers never copy map data and never
//! hold up the writer; the writer reuses the buffers of a snapshot no reader
//! holds any more, so steady-state publication does not allocate.

use std::sync::{Arc, Mutex};

use super::lines::Curve;
use super::segments::MapSegment;
use crate::geom::{IPoint, Pose, Segment};
use crate::grid::Grid;

/// An immutable picture of the map at one moment.
#[derive(Clone, Debug)]
pub struct PointMapSnapshot {
    /// Increases by one with every publication.
    pub version: u64,
    /// Scans merged into the map so far.
    pub scans_merged: u64,
    /// The sparse point map (world frame), points with their intensity.
    pub points: Vec<IPoint>,
    /// Wall segments, end points snapped to corners.
    pub segments: Vec<MapSegment>,
    /// The same segments as plain [`Segment`]s, the form the decomposition
    /// takes (`decomp` reads `&snapshot.walls`).
    pub walls: Vec<Segment>,
    /// Curved surfaces as polylines.
    pub(crate) curves: Vec<Curve>,
    /// The explored-area grid: unknown / free / occupied. Its free cells next
    /// to unknown ones are the explored boundary.
    pub grid: Grid,
    /// The robot's (sensor's) pose after the last merged scan.
    pub pose: Pose,
    /// Poses of the merged scans, in order, one kept every 5 cm or 0.1 rad of motion.
    pub trajectory: Vec<Pose>,
}

impl PointMapSnapshot {
    /// An empty snapshot over `grid` at `pose`.
    pub fn empty(grid: Grid, pose: Pose) -> Self {
        Self {
            version: 0,
            scans_merged: 0,
            points: Vec::new(),
            segments: Vec::new(),
            walls: Vec::new(),
            curves: Vec::new(),
            grid,
            pose,
            trajectory: Vec::new(),
        }
    }
}

/// The newest snapshot, shared between the writer and any number of readers.
#[derive(Debug)]
pub struct SnapshotCell {
    current: Mutex<Arc<PointMapSnapshot>>,
}

impl SnapshotCell {
    /// A cell holding `first`.
    pub fn new(first: Arc<PointMapSnapshot>) -> Self {
        Self {
            current: Mutex::new(first),
        }
    }

    /// The newest snapshot (an `Arc` clone: no map data is copied).
    pub fn load(&self) -> Arc<PointMapSnapshot> {
        // A poisoned lock only means a thread panicked while swapping a pointer:
        // the Arc inside is still whole.
        let g = self.current.lock().unwrap_or_else(|e| e.into_inner());
        Arc::clone(&g)
    }

    /// Replaces the snapshot; returns the previous one.
    pub fn store(&self, next: Arc<PointMapSnapshot>) -> Arc<PointMapSnapshot> {
        let mut g = self.current.lock().unwrap_or_else(|e| e.into_inner());
        std::mem::replace(&mut *g, next)
    }
}
