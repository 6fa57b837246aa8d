//! The map stage: registered scans and bumper contacts merged into the evidence
//! grid.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Point2;

use super::gone;
use crate::daemon::contact::ContactMark;
use crate::daemon::messages::{MapMsg, MapSnapshot};
use crate::daemon::shared::Shared;
use crate::daemon::snapshot::MapStageSnapshot;
use crate::grid::Grid;
use crate::pipeline::checkpoint::{ContactArc, ContactArcs};
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};

/// The map stage: merges registered scans into the explored-area grid and
/// publishes immutable `Arc` snapshots for the planner.
pub struct MapStage {
    /// The map.
    pub grid: Grid,
    /// Registered scans and bumper contacts in.
    pub rx: Rx<MapMsg>,
    /// Snapshots out (newest wins).
    pub tx: Tx<MapSnapshot>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// Longest range merged (m); farther echoes are too uncertain.
    pub max_range: f64,
    /// Bumper contacts: obstacles the scanner cannot see, kept occupied
    /// even when later rays pass over them.
    pub contacts: Vec<ContactMark>,
    /// Contacts that were new (not a repeat of a marked one).
    pub(crate) new_contacts: u64,
    /// A contact this close to a marked one is a repeat of it (m).
    pub same_contact: f64,
    /// Requests to take a mark out handled (see [`MapSnapshot::retired`]).
    pub(crate) retired: u64,
    /// The grid as last handed to the planner (none before the first
    /// scan of a fresh run), for the snapshot.
    published: Option<Arc<Grid>>,
    /// [`Self::contacts`] as the checkpoint stores them, rebuilt when they
    /// change (none before the first), for the snapshot.
    arcs: Option<Arc<ContactArcs>>,
}

/// The checkpoint section of contact `marks`.
pub fn contact_arcs(marks: &[ContactMark]) -> ContactArcs {
    ContactArcs {
        arcs: marks.iter().map(ContactArc::from).collect(),
    }
}

impl MapStage {
    /// A map stage starting on `grid` without contact marks (see
    /// [`Self::restore`] for a resumed run).
    pub fn new(
        grid: Grid,
        rx: Rx<MapMsg>,
        tx: Tx<MapSnapshot>,
        shared: Arc<Shared>,
        max_range: f64,
        same_contact: f64,
    ) -> Self {
        Self {
            grid,
            rx,
            tx,
            shared,
            max_range,
            contacts: Vec::new(),
            new_contacts: 0,
            same_contact,
            retired: 0,
            published: None,
            arcs: None,
        }
    }

    /// What a restart needs of this stage: the grid as last handed to the
    /// planner and the contact marks.
    pub fn snapshot(&self) -> MapStageSnapshot {
        MapStageSnapshot {
            grid: self.published.clone(),
            contacts: self.arcs.clone(),
        }
    }

    /// Hands [`Self::snapshot`] to the checkpoint and to the stages that
    /// read the map or the marks (through the live status).
    fn publish(&self) {
        let snapshot = self.snapshot();
        self.shared.with_status(|s| s.map = snapshot);
    }

    /// Picks up a resumed run: the restored grid, with the restored
    /// contact marks marked in it at once (the checkpointed grid may have
    /// lost them to later rays).
    pub fn restore(&mut self, snapshot: MapStageSnapshot) {
        if let Some(g) = &snapshot.grid {
            self.grid = Grid::clone(g);
        }
        self.contacts = snapshot
            .contacts
            .as_deref()
            .map(|c| c.arcs.iter().map(|&a| a.into()).collect())
            .unwrap_or_default();
        if !self.contacts.is_empty() {
            log::info!(
                "resume: {} bumper contact mark(s) restored",
                self.contacts.len()
            );
        }
        self.published = snapshot.grid;
        self.arcs = snapshot.contacts;
        self.publish();
        self.mark_contacts();
    }

    /// The contact marks changed: the snapshot gets the new list.
    fn contacts_changed(&mut self) {
        self.arcs = Some(Arc::new(contact_arcs(&self.contacts)));
        self.publish();
    }

    /// Merges a registered scan or a bumper contact into the grid; the
    /// contact marks are occupied again afterwards, whatever the rays
    /// crossed.
    pub fn merge(&mut self, msg: MapMsg) {
        match msg {
            MapMsg::Scan { pose: p, scan } => {
                let o: Point2<f64> = p.translation.vector.into();
                for b in scan.beams.iter() {
                    if !(b.valid && b.range.is_finite() && b.angle.is_finite()) {
                        continue;
                    }
                    let r = b.range.min(self.max_range);
                    let (s, c) = b.angle.sin_cos();
                    let end = p * Point2::new(r * c, r * s);
                    self.grid.integrate_ray(&o, &end, r >= b.range);
                }
            }
            MapMsg::Contact(mark) => {
                if !self
                    .contacts
                    .iter()
                    .any(|c| c.same_as(&mark, self.same_contact))
                {
                    self.contacts.push(mark);
                    self.new_contacts += 1;
                    self.contacts_changed();
                }
            }
            MapMsg::Retire(at) => {
                self.retired += 1;
                let (gone, kept): (Vec<ContactMark>, Vec<ContactMark>) = self
                    .contacts
                    .iter()
                    .partition(|c| (c.at - at).norm() <= self.same_contact);
                if !gone.is_empty() {
                    self.contacts = kept;
                    self.shared.marks_taken_out.fetch_add(1, Ordering::Relaxed);
                    // Unknown, not free: a mark beside a wall must not open
                    // a hole in it; the next scan sees what is there.
                    for c in &gone {
                        set_arc(&mut self.grid, c, crate::grid::CellState::Unknown);
                    }
                    self.contacts_changed();
                    log::info!(
                        "map: contact mark at ({:.2}, {:.2}) m taken out; {} mark(s) left",
                        at.x,
                        at.y,
                        self.contacts.len()
                    );
                }
            }
        }
        self.mark_contacts();
    }

    fn mark_contacts(&mut self) {
        for c in &self.contacts {
            set_arc(&mut self.grid, c, crate::grid::CellState::Occupied);
        }
    }
}

/// Sets every cell of `grid` the arc of `mark` lies in to `state`.
fn set_arc(grid: &mut Grid, mark: &ContactMark, state: crate::grid::CellState) {
    for cell in mark.cells(grid) {
        grid.set_state(cell, state);
    }
}

impl Stage for MapStage {
    type Work = MapMsg;

    fn wait(&mut self, timeout: Duration) -> Poll<MapMsg> {
        match self.rx.recv_timeout(timeout) {
            Recv::Msg(m) => Poll::Work(m),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, msg: MapMsg, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        self.merge(msg);
        let snap = Arc::new(self.grid.clone());
        self.published = Some(snap.clone());
        self.publish();
        let msg = MapSnapshot {
            grid: snap,
            contacts: self.new_contacts,
            retired: self.retired,
        };
        ctx.hand_off();
        self.tx
            .send(msg)
            .map_or_else(|_| gone(&self.shared, "plan"), |_| Ok(()))
    }
}
