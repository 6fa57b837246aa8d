//! The plan stage: decomposition and coverage planner on each map snapshot, and
//! the bumper marks' second look.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Point2;

use super::{gone, wall_until};
use crate::clock::SharedClock;
use crate::daemon::contact::ContactMark;
use crate::daemon::messages::{MapMsg, MapSnapshot, PathMsg};
use crate::daemon::shared::Shared;
use crate::daemon::snapshot::PlanStageSnapshot;
use crate::decomp::Decomposer;
use crate::geom::Pose;
use crate::grid::Grid;
use crate::pipeline::checkpoint::TriedPlaces;
use crate::pipeline::supervisor::Control;
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};
use crate::plan::{CoveragePlanner, PlanSnapshot, PlanStatus, Task};

/// The plan stage: online cell decomposition and the coverage planner on
/// each new map snapshot, rate-limited (more so when degraded); tells the
/// supervisor when nothing reachable is left.
pub struct PlanStage {
    /// The decomposer.
    pub decomposer: Decomposer,
    /// The planner.
    pub planner: CoveragePlanner,
    /// Map snapshots in.
    pub rx: Rx<MapSnapshot>,
    /// Executed poses in (the tool swept the floor there).
    pub poses: Rx<Pose>,
    /// Paths out.
    pub tx: Tx<PathMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// Asks the supervisor to stop when coverage is done.
    pub control: Control,
    /// The injected clock.
    pub clock: SharedClock,
    /// Shortest time between two planning updates (clock s).
    pub(crate) min_interval: f64,
    /// Clock time of the last update.
    pub last: f64,
    /// Sequence number of the last path sent.
    pub seq: u64,
    /// Updates so far.
    pub updates: u64,
    /// The planner's snapshot as of its last update (the one restored
    /// before the first): the next one reuses what did not change.
    pub(crate) records: PlanSnapshot,
    /// New bumper contacts the planner has been told of.
    pub(crate) contacts_seen: u64,
    /// Clock time of the last bump whose contact the planner has seen.
    pub(crate) bump_handled: f64,
    /// Longest a plan update waits for a bump's contact to reach the map
    /// (clock s).
    pub(crate) contact_settle: f64,
    /// Contact marks that wall off floor, taken out once at the end.
    pub probe: MarkProbe,
}

/// The plan stage's second look at bumper contact marks when coverage is
/// otherwise done (see `MarkProbe::walled_floor`).
pub struct MarkProbe {
    /// Requests to take a contact mark out go to the map stage here.
    pub(crate) to_map: Tx<MapMsg>,
    /// Whether marks that wall off floor are taken out at all.
    pub on: bool,
    /// Least floor a mark must wall off to be taken out (m²): as much as
    /// the planner sends a lane for (`plan.min_lane_area`).
    pub least: f64,
    /// A mark this close to one taken out before stays (m): the floor
    /// behind it has had its try.
    pub spacing: f64,
    /// Where marks were taken out.
    pub(crate) probed: Vec<Point2<f64>>,
    /// Requests to take a mark out sent so far.
    pub sent: u64,
    /// Clock time of the last such request.
    pub(crate) sent_at: f64,
}

impl Stage for PlanStage {
    type Work = MapSnapshot;

    fn wait(&mut self, timeout: Duration) -> Poll<MapSnapshot> {
        if self.shared.done.load(Ordering::Relaxed) {
            std::thread::sleep(timeout);
            return Poll::Idle;
        }
        let due = self.last + self.min_interval;
        let now = self.clock.now();
        if now < due {
            std::thread::sleep(wall_until(&self.clock, now, due, timeout));
            return Poll::Idle;
        }
        match self.rx.recv_timeout(timeout) {
            Recv::Msg(g) => match self.rx.try_recv_newest() {
                Recv::Msg(newer) => Poll::Work(newer),
                _ => Poll::Work(g),
            },
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, snap: MapSnapshot, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        // The one clock reading of this update: everything below that
        // decides by time is given this `now`.
        let now = self.clock.now();
        self.last = now + self.min_interval * f64::from(ctx.degrade());
        while let Recv::Msg(p) = self.poses.try_recv() {
            self.planner.record_pose(&p);
        }
        let grid = snap.grid;
        let bump = self.shared.last_bump();
        if snap.contacts > self.contacts_seen {
            // The path ran into an obstacle the map did not show; the map
            // has it now: plan again, the floor it was after is not at fault.
            self.contacts_seen = snap.contacts;
            self.bump_handled = bump;
            self.planner.interrupt();
        } else if bump > self.bump_handled {
            if now - bump < self.contact_settle {
                // A bump whose contact is not in this snapshot yet: wait
                // for the one that has it rather than plan without it.
                return Ok(());
            }
            // A repeat of a marked contact: nothing new to plan around.
            self.bump_handled = bump;
        }
        if snap.retired < self.probe.sent && now - self.probe.sent_at < self.contact_settle {
            // A mark was taken out: plan on the map without it.
            return Ok(());
        }
        let decomp = self.decomposer.update(&grid, &[]);
        let progress = self.shared.progress();
        let progress = if progress.path_seq == self.seq {
            progress.next
        } else {
            Some(0)
        };
        let here = self.shared.with_status(|s| s.pose);
        self.planner.set_time(now);
        let status = self
            .planner
            .update(&grid, decomp, &here, progress)
            .map_err(|e| StageFault::Transient(format!("planner: {e}")))?;
        self.updates += 1;
        let res = self.planner.cspace().frame.res;
        let covered = self.planner.covered().iter().filter(|c| **c).count() as f64 * res * res;
        let decomposition = (self.updates % 5 == 1).then(|| Arc::new(decomp.clone()));
        // The decomposition coverage finished on, for the pictures.
        let last_decomposition =
            matches!(status, PlanStatus::Done(_)).then(|| Arc::new(decomp.clone()));
        let task = match status {
            PlanStatus::Working { task, .. } => task.to_string(),
            PlanStatus::Done(_) => crate::plan::Task::Done.to_string(),
        };
        self.records = self.planner.snapshot(&self.records);
        let snapshot = self.snapshot();
        self.shared.with_status(|s| {
            s.plan = snapshot;
            s.covered_area = covered;
            s.task = task;
            if let Some(d) = decomposition {
                s.decomposition = Some(d);
            }
        });
        // Coverage just done, the way back planned but not yet sent: a
        // bumper mark walling off floor is taken out before the robot
        // leaves (after, it would drive back out again).
        let just_done = match status {
            PlanStatus::Done(_) => true,
            PlanStatus::Working {
                task: Task::Home,
                new_path: true,
            } => self.planner.home_plans() == 1,
            _ => false,
        };
        match status {
            _ if just_done && self.retry_walled_floor(now, &grid, &here) => {}
            PlanStatus::Done(r) => {
                let stats = self.planner.stats();
                self.shared.with_status(|s| {
                    s.decomposition = last_decomposition;
                    s.plan_stats = stats;
                });
                self.shared.done.store(true, Ordering::Relaxed);
                log::info!(
                    "coverage finished: {:.2} m² swept, {:.2} m² unreachable, {:.2} m² behind passages tighter than the clearance, {:.2} m² abandoned, {:.2} m² of leftovers declined, {:.2} m of frontier left unexplored; drive back to the start: {} ({:.2} m from it)",
                    r.covered_area,
                    r.unreachable_area,
                    r.behind_tight_passages,
                    r.abandoned_area,
                    r.declined_area,
                    r.unexplored_frontier,
                    r.home.describe(),
                    r.home_distance
                );
                self.shared.with_status(|s| s.home_outcome = Some(r.home));
                self.control.stop("coverage finished");
            }
            PlanStatus::Working { new_path: true, .. } => {
                self.seq += 1;
                let (points, final_heading) = self.planner.path();
                let motions = crate::daemon::shared::PathMotions {
                    seq: self.seq,
                    task: u32::try_from(self.planner.stats().tasks).unwrap_or(u32::MAX),
                    motions: self.planner.motions().into(),
                };
                let stats = self.planner.stats();
                self.shared.with_status(|s| {
                    s.path_motions = Some(motions);
                    s.path = Some((self.seq, std::sync::Arc::from(points)));
                    s.plan_stats = stats;
                });
                let msg = PathMsg {
                    seq: self.seq,
                    points: points.to_vec(),
                    final_heading,
                };
                ctx.hand_off();
                if self.tx.send(msg).is_err() {
                    return gone(&self.shared, "control");
                }
            }
            PlanStatus::Working { .. } => {}
        }
        Ok(())
    }
}

impl PlanStage {
    /// What a restart needs of this stage: the planner's records and the
    /// places contact marks were tried.
    pub fn snapshot(&self) -> PlanStageSnapshot {
        PlanStageSnapshot {
            planner: self.records.clone(),
            contacts_tried: self.probe.tried(),
        }
    }

    /// Hands [`Self::snapshot`] to the checkpoint (through the live status).
    fn publish(&self) {
        let snapshot = self.snapshot();
        self.shared.with_status(|s| s.plan = snapshot);
    }

    /// Picks up a resumed run: the planner's records (they stand in the
    /// snapshot until its first update) and the places contact marks were
    /// tried. `return_home`: the robot drives back to its start once
    /// coverage is done (`plan.return_home`), so a checkpoint without the
    /// start is worth a line in the log.
    pub fn restore(&mut self, snapshot: PlanStageSnapshot, return_home: bool) {
        self.planner.restore(&snapshot.planner);
        if snapshot.planner.home.is_none() && return_home {
            log::info!(
                "resume: the checkpoint holds no start (an older build wrote it); once coverage is done the robot drives back to where it was resumed"
            );
        }
        self.probe.restore(snapshot.contacts_tried.as_deref());
        // Until the planner's first update, the checkpointed record stands.
        if let Some(sw) = &snapshot.planner.swept {
            let area = sw.area();
            self.shared.with_status(|s| s.covered_area = area);
        }
        self.records = snapshot.planner;
        self.publish();
    }

    /// At the end of coverage: takes out the contact mark walling off the
    /// most floor, if any (see [`MarkProbe::walled_floor`]); true when it
    /// did and coverage goes on.
    fn retry_walled_floor(&mut self, now: f64, grid: &Grid, here: &Pose) -> bool {
        let Some(at) = self
            .probe
            .walled_floor(&self.planner, &self.shared, grid, here)
        else {
            return false;
        };
        // Tried before the request goes: a checkpoint between the two keeps
        // the mark and the place, and the resumed run leaves the mark.
        self.publish();
        self.probe.take_out(at, &mut self.planner, now)
    }
}

impl MarkProbe {
    /// A probe sending its requests on `to_map` (see [`Self::restore`] for
    /// a resumed run).
    pub fn new(to_map: Tx<MapMsg>, on: bool, least: f64, spacing: f64) -> Self {
        Self {
            to_map,
            on,
            least,
            spacing,
            probed: Vec::new(),
            sent: 0,
            sent_at: f64::NEG_INFINITY,
        }
    }

    /// Picks up the places `tried` before a restart: marks near them stay.
    pub fn restore(&mut self, tried: Option<&TriedPlaces>) {
        self.probed = tried.map(|t| t.places.clone()).unwrap_or_default();
        if !self.probed.is_empty() {
            log::info!(
                "resume: {} place(s) where contact marks were tried restored; marks near them stay",
                self.probed.len()
            );
        }
    }

    /// The places tried, as the checkpoint stores them (none yet: none).
    pub fn tried(&self) -> Option<Arc<TriedPlaces>> {
        (!self.probed.is_empty()).then(|| {
            Arc::new(TriedPlaces {
                places: self.probed.clone(),
            })
        })
    }

    /// At the end of coverage (the `planner` is done): the bumper contact
    /// mark that walls off the most unswept floor, if that is at least
    /// `least` and no mark was taken out near it before, recorded as tried
    /// (see [`Self::take_out`] for the rest). A one-bit bumper cannot tell
    /// where on its arc it closed; its mark is a guess that can stand in
    /// open floor and shut a passage the robot fits through. Tried again, the floor is swept, or
    /// the bumper closes again and marks the obstacle from a new bearing
    /// (that mark stays). Marks on an unseen obstacle wall off floor too
    /// (the obstacle's own, free in the map): one mark per end of coverage,
    /// the one walling off the most, and none within `spacing` of a place
    /// tried before, so an obstacle costs at most one more bump.
    pub(crate) fn walled_floor(
        &mut self,
        planner: &CoveragePlanner,
        shared: &Shared,
        grid: &Grid,
        here: &Pose,
    ) -> Option<Point2<f64>> {
        if !self.on {
            return None;
        }
        let arcs = shared.with_status(|s| s.map.contacts.clone())?;
        let robot: Point2<f64> = here.translation.vector.into();
        let mut best: Option<(Point2<f64>, f64)> = None;
        for m in arcs.arcs.iter().map(|&a| ContactMark::from(a)) {
            if self
                .probed
                .iter()
                .any(|p| (p - m.at).norm() <= self.spacing)
            {
                continue;
            }
            let cells: Vec<_> = m.cells(grid).collect();
            let area = planner.floor_walled_off(grid, &cells, &robot);
            log::debug!(
                "plan: the contact mark at ({:.2}, {:.2}) m walls off {area:.3} m² of unswept floor",
                m.at.x,
                m.at.y
            );
            if area + 1e-9 >= self.least && best.is_none_or(|(_, a)| area > a) {
                best = Some((m.at, area));
            }
        }
        let (at, area) = best?;
        log::warn!(
            "plan: the contact mark at ({:.2}, {:.2}) m walls off {:.3} m² of unswept floor; a bumper's mark is a guess at where it closed, so it is taken out and that floor tried once more",
            at.x,
            at.y,
            area
        );
        self.probed.push(at);
        Some(at)
    }

    /// Takes the mark at `at` (chosen by [`Self::walled_floor`]) out of the
    /// map and reopens the `planner` around it; true when the request went
    /// (coverage goes on).
    pub(crate) fn take_out(
        &mut self,
        at: Point2<f64>,
        planner: &mut CoveragePlanner,
        now: f64,
    ) -> bool {
        if self.to_map.send(MapMsg::Retire(at)).is_err() {
            return false;
        }
        self.sent += 1;
        self.sent_at = now;
        planner.reopen(&[at], self.spacing);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::Decomposition;
    use crate::grid::CellState;
    use crate::pipeline::checkpoint::{ContactArc, ContactArcs};
    use crate::pipeline::{queue, Overflow, Recv};

    /// The walled room (3 m × 2 m) split at x = 1.5 m by a wall with a
    /// 0.6 m passage at the top, a bumper's mark standing in the passage;
    /// the planner has seen it once from (0.4, 0.4).
    fn passage_shut_by_a_mark() -> (Grid, CoveragePlanner, Shared, Point2<f64>) {
        let mut g = crate::plan::test_support::walled_room();
        for y in 0..27 {
            g.set_state((30, y), CellState::Occupied);
        }
        g.set_state((30, 33), CellState::Occupied);
        let at = g.centre_of((30, 33));
        let mut p = crate::plan::test_support::planner();
        p.update(
            &g,
            &Decomposition::default(),
            &crate::geom::pose(0.4, 0.4, 0.0),
            None,
        )
        .unwrap();
        let shared = Shared::default();
        let arc = ContactArc {
            centre: at - nalgebra::Vector2::new(0.18, 0.0),
            at,
            half_length: 0.02,
        };
        let arcs = Arc::new(ContactArcs { arcs: vec![arc] });
        shared.with_status(|s| s.map.contacts = Some(arcs));
        (g, p, shared, at)
    }

    #[test]
    fn a_mark_is_taken_out_once_and_the_place_tried_outlives_a_restart() {
        let (g, mut p, shared, at) = passage_shut_by_a_mark();
        let here = crate::geom::pose(0.4, 0.4, 0.0);
        let (tx, rx) = queue("map_msgs", 8, Overflow::DropOldest);
        let mut probe = MarkProbe::new(tx.clone(), true, 0.05, 0.34);
        assert!(probe.tried().is_none());
        let chosen = probe.walled_floor(&p, &shared, &g, &here);
        assert_eq!(chosen, Some(at));
        // The place is recorded for the checkpoint before the request goes.
        let saved = probe.tried().unwrap();
        assert_eq!(saved.places, vec![at]);
        assert!(probe.take_out(at, &mut p, 1.0));
        assert!(matches!(rx.try_recv(), Recv::Msg(MapMsg::Retire(q)) if q == at));
        // Not tried again.
        assert_eq!(probe.walled_floor(&p, &shared, &g, &here), None);
        assert_eq!(probe.sent, 1);

        // A resumed run with the checkpoint's places leaves the mark, and
        // its next checkpoint still holds them.
        let (g, p, shared, _) = passage_shut_by_a_mark();
        let mut resumed = MarkProbe::new(tx, true, 0.05, 0.34);
        resumed.restore(Some(&saved));
        assert_eq!(resumed.tried().unwrap().places, vec![at]);
        assert_eq!(resumed.walled_floor(&p, &shared, &g, &here), None);
        assert_eq!(resumed.sent, 0);
        assert!(matches!(rx.try_recv(), Recv::Empty));
    }
}
