//! What a restart needs, one snapshot per stage that owns checkpointed
//! state, and how each is laid out in the checkpoint's sections.
//!
//! Each stage makes its snapshot in one place (its `snapshot`, published
//! into [`super::LiveStatus`] whenever a piece changes) and is restored
//! from it in one place (its `restore`, called by [`super::Daemon::start`]
//! with the snapshot [`super::resume::load`] read). The supervisor's hooks
//! write the snapshots they find there into the checkpoint
//! ([`super::DaemonHooks::checkpoint`]).
//!
//! On disk every piece stays a section of its own (the sections and their
//! payloads are those of the per-piece checkpoints before, see
//! `docs/checkpoints.md`): a piece that cannot be read is left out alone,
//! with its own line in the log, and the run resumes without it.
//!
//! The cut: the localise stage owns the scan tracker's keyframes and the
//! scanner mount it refitted; the map stage the grid and the bumper
//! contact marks (the motor stage finds the contacts, the map stage keeps
//! the list); the plan stage the planner's records and the places where
//! its second look took contact marks out. The pose is the run's, not the
//! control stage's although control publishes the estimate: after a
//! restart every stage starts from it (the tracker's seed and the
//! relocalisation's guess, the control estimate, the planner's first swept
//! pose, the map frame's centre).

use std::sync::Arc;

use crate::geom::Pose;
use crate::grid::Grid;
use crate::icp::TrackerState;
use crate::pipeline::checkpoint::{
    Checkpoint, CheckpointError, ContactArcs, MountRecord, RunFinished, RunProgress, Section,
    TriedPlaces,
};
use crate::plan::PlanSnapshot;

/// The run's own part: how far it got, where the robot is, whether it
/// finished its coverage.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSnapshot {
    /// Progress counters (section `progress`).
    pub progress: RunProgress,
    /// The robot's pose (section `pose`).
    pub pose: Pose,
    /// Set once the run finished its coverage (section `run.finished`):
    /// the next start is a new run. Never set in a [`super::Resume`].
    pub finished: Option<RunFinished>,
}

/// What the localise stage needs after a restart.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LocaliseSnapshot {
    /// The scan tracker's keyframes as of its newest one (section
    /// `icp.keyframes`; none: a new local map at the resume pose).
    pub keyframes: Option<Arc<TrackerState>>,
    /// The scanner mount the checks refitted and the configured one it
    /// replaced (section `robot.mount`; none: as configured).
    pub mount: Option<MountRecord>,
}

/// What the map stage needs after a restart.
#[derive(Clone, Debug, Default)]
pub struct MapStageSnapshot {
    /// The grid as last handed to the planner (section `grid`; none before
    /// the first scan of a fresh run; always set in a [`super::Resume`]).
    pub grid: Option<Arc<Grid>>,
    /// The bumper contact marks (section `daemon.contacts`; none before the
    /// first): rays may clear them from the grid, a resumed run marks them
    /// again.
    pub contacts: Option<Arc<ContactArcs>>,
}

/// What the plan stage needs after a restart.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanStageSnapshot {
    /// The planner's records (sections `plan.swept`, `plan.lattice`,
    /// `plan.home`, `plan.tries`, `plan.reach`).
    pub planner: PlanSnapshot,
    /// Where contact marks were taken out to try the floor behind them
    /// (section `daemon.contacts_tried`; none before the first): a resumed
    /// run does not try one place again.
    pub contacts_tried: Option<Arc<TriedPlaces>>,
}

/// Section `S` of `cp`, or `None` when it is missing or unreadable (logged
/// as `unreadable`, then the error): the run resumes without it.
fn optional<S: Section>(cp: &Checkpoint, unreadable: &str) -> Option<S> {
    cp.get::<S>().unwrap_or_else(|e| {
        log::warn!("{unreadable}: {e}");
        None
    })
}

impl RunSnapshot {
    /// Puts the run's sections into `cp`.
    pub(crate) fn put(&self, cp: &mut Checkpoint) -> Result<(), CheckpointError> {
        cp.put(&self.progress)?;
        cp.put(&self.pose)?;
        if let Some(f) = &self.finished {
            cp.put(f)?;
        }
        Ok(())
    }
}

impl LocaliseSnapshot {
    /// Puts the localise stage's sections into `cp`.
    pub(crate) fn put(&self, cp: &mut Checkpoint) -> Result<(), CheckpointError> {
        if let Some(k) = &self.keyframes {
            cp.put(&**k)?;
        }
        if let Some(m) = &self.mount {
            cp.put(m)?;
        }
        Ok(())
    }

    /// The localise stage's sections of `cp`, each one unreadable left out
    /// (and logged).
    pub(crate) fn read(cp: &Checkpoint) -> Self {
        Self {
            keyframes: optional(cp, "tracker keyframes unreadable, starting a new local map")
                .map(Arc::new),
            mount: optional(
                cp,
                "refitted scanner mount unreadable, the checks fit it again",
            ),
        }
    }
}

impl MapStageSnapshot {
    /// Puts the map stage's sections into `cp`.
    pub(crate) fn put(&self, cp: &mut Checkpoint) -> Result<(), CheckpointError> {
        if let Some(g) = &self.grid {
            cp.put(&**g)?;
        }
        if let Some(c) = &self.contacts {
            cp.put(&**c)?;
        }
        Ok(())
    }

    /// The map stage's sections of `cp` with its `grid` (read first: a
    /// checkpoint without one is no run to resume), an unreadable contact
    /// list left out (and logged).
    pub(crate) fn read(cp: &Checkpoint, grid: Grid) -> Self {
        let contacts = optional::<ContactArcs>(
            cp,
            "bumper contact marks unreadable, only the map's copy of them is left",
        );
        Self {
            grid: Some(Arc::new(grid)),
            contacts: contacts.filter(|c| !c.arcs.is_empty()).map(Arc::new),
        }
    }
}

impl PlanStageSnapshot {
    /// Puts the plan stage's sections into `cp`.
    pub(crate) fn put(&self, cp: &mut Checkpoint) -> Result<(), CheckpointError> {
        let p = &self.planner;
        if let Some(s) = &p.swept {
            cp.put(&**s)?;
        }
        if let Some(l) = &p.lattice {
            cp.put(l)?;
        }
        if let Some(h) = &p.home {
            cp.put(h)?;
        }
        if let Some(t) = &p.tries {
            cp.put(&**t)?;
        }
        if let Some(r) = &p.reach {
            cp.put(&**r)?;
        }
        if let Some(t) = &self.contacts_tried {
            cp.put(&**t)?;
        }
        Ok(())
    }

    /// The plan stage's sections of `cp`, each one unreadable left out
    /// (and logged).
    pub(crate) fn read(cp: &Checkpoint) -> Self {
        let mut planner = PlanSnapshot::default();
        planner.swept = optional(cp, "swept-floor record unreadable, covering again").map(Arc::new);
        planner.lattice = optional(cp, "lane lattice record unreadable, choosing it again");
        planner.home = optional(
            cp,
            "start record unreadable, the robot drives back to where it was resumed",
        );
        planner.tries = optional(
            cp,
            "planner tries record unreadable, floor given up gets its tries again",
        )
        .map(Arc::new);
        planner.reach = optional(
            cp,
            "planner record of places once within reach unreadable, floor walled off before the restart is not waited for",
        )
        .map(Arc::new);
        let tried = optional::<TriedPlaces>(
            cp,
            "places where contact marks were tried unreadable, a mark may be tried once more",
        );
        Self {
            planner,
            contacts_tried: tried.filter(|t| !t.places.is_empty()).map(Arc::new),
        }
    }
}
