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
use crate::decomp::Decomposer;
use crate::geom::Pose;
use crate::grid::Grid;
use crate::pipeline::checkpoint::TriedPlaces;
use crate::pipeline::supervisor::Control;
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};
use crate::plan::{CoveragePlanner, PlanStatus, Task};

/// A planner record to publish: `get`'s, when its `generation` differs
/// from the one `published` last (which it then becomes); `None` when
/// unchanged, so the record (a scan of the whole grid) is copied out only
/// when it changed.
fn changed<T>(
    generation: u64,
    published: &mut u64,
    get: impl FnOnce() -> Option<T>,
) -> Option<Arc<T>> {
    if generation == *published {
        return None;
    }
    let record = get().map(Arc::new);
    if record.is_some() {
        *published = generation;
    }
    record
}

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
    pub min_interval: f64,
    /// Clock time of the last update.
    pub last: f64,
    /// Sequence number of the last path sent.
    pub seq: u64,
    /// Updates so far.
    pub updates: u64,
    /// The planner's tries generation last published (see
    /// [`CoveragePlanner::tries_generation`]).
    pub tries_published: u64,
    /// The planner's reach generation last published (see
    /// [`CoveragePlanner::reach_generation`]).
    pub reach_published: u64,
    /// New bumper contacts the planner has been told of.
    pub contacts_seen: u64,
    /// Clock time of the last bump whose contact the planner has seen.
    pub bump_handled: f64,
    /// Longest a plan update waits for a bump's contact to reach the map
    /// (clock s).
    pub contact_settle: f64,
    /// Contact marks that wall off floor, taken out once at the end.
    pub probe: MarkProbe,
}

/// The plan stage's second look at bumper contact marks when coverage is
/// otherwise done (see [`MarkProbe::walled_floor`]).
pub struct MarkProbe {
    /// Requests to take a contact mark out go to the map stage here.
    pub to_map: Tx<MapMsg>,
    /// Whether marks that wall off floor are taken out at all.
    pub on: bool,
    /// Least floor a mark must wall off to be taken out (m²): as much as
    /// the planner sends a lane for (`plan.min_lane_area`).
    pub least: f64,
    /// A mark this close to one taken out before stays (m): the floor
    /// behind it has had its try.
    pub spacing: f64,
    /// Where marks were taken out.
    pub probed: Vec<Point2<f64>>,
    /// Requests to take a mark out sent so far.
    pub sent: u64,
    /// Clock time of the last such request.
    pub sent_at: f64,
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
        let snapshot = (self.updates % 5 == 1).then(|| Arc::new(decomp.clone()));
        let task = match status {
            PlanStatus::Working { task, .. } => task.to_string(),
            PlanStatus::Done(_) => crate::plan::Task::Done.to_string(),
        };
        let swept = self.planner.swept().map(Arc::new);
        let lattice = self.planner.lattice();
        let home = self.planner.home();
        let planner = &self.planner;
        let tries = changed(
            planner.tries_generation(),
            &mut self.tries_published,
            || planner.tries(),
        );
        let reach = changed(
            planner.reach_generation(),
            &mut self.reach_published,
            || planner.reach(),
        );
        self.shared.with_status(|s| {
            if tries.is_some() {
                s.tries = tries;
            }
            if reach.is_some() {
                s.reach = reach;
            }
            s.covered_area = covered;
            if swept.is_some() {
                s.swept = swept;
            }
            if lattice != crate::plan::LatticePhase::default() {
                s.lattice = Some(lattice);
            }
            if home.is_some() {
                s.home = home;
            }
            s.task = task;
            if let Some(d) = snapshot {
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
            _ if just_done
                && self
                    .probe
                    .walled_floor(&mut self.planner, &self.shared, now, &grid, &here) => {}
            PlanStatus::Done(r) => {
                let stats = self.planner.stats();
                self.shared.with_status(|s| {
                    s.decomposition = Some(Arc::new(decomp.clone()));
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

impl MarkProbe {
    /// A probe sending its requests on `to_map`, with the places `tried`
    /// before a restart (published at once for the next checkpoint).
    pub fn new(
        to_map: Tx<MapMsg>,
        on: bool,
        least: f64,
        spacing: f64,
        tried: Vec<Point2<f64>>,
        shared: &Shared,
    ) -> Self {
        if !tried.is_empty() {
            log::info!(
                "resume: {} place(s) where contact marks were tried restored; marks near them stay",
                tried.len()
            );
        }
        let probe = Self {
            to_map,
            on,
            least,
            spacing,
            probed: tried,
            sent: 0,
            sent_at: f64::NEG_INFINITY,
        };
        probe.publish(shared);
        probe
    }

    /// Hands the tried places to the checkpoint (none yet: nothing).
    fn publish(&self, shared: &Shared) {
        if self.probed.is_empty() {
            return;
        }
        let tried = Arc::new(TriedPlaces {
            places: self.probed.clone(),
        });
        shared.with_status(|s| s.contacts_tried = Some(tried));
    }

    /// At the end of coverage (the `planner` is done): takes out the
    /// bumper contact mark that walls off the most unswept floor, if that is
    /// at least `least` and no mark was taken out near it before; reopens
    /// the planner and returns true (coverage goes on). A one-bit bumper cannot tell where on its arc it
    /// closed; its mark is a guess that can stand in open floor and shut a
    /// passage the robot fits through. Tried again, the floor is swept, or
    /// the bumper closes again and marks the obstacle from a new bearing
    /// (that mark stays). Marks on an unseen obstacle wall off floor too
    /// (the obstacle's own, free in the map): one mark per end of coverage,
    /// the one walling off the most, and none within `spacing` of a place
    /// tried before, so an obstacle costs at most one more bump.
    pub fn walled_floor(
        &mut self,
        planner: &mut CoveragePlanner,
        shared: &Shared,
        now: f64,
        grid: &Grid,
        here: &Pose,
    ) -> bool {
        if !self.on {
            return false;
        }
        let Some(arcs) = shared.with_status(|s| s.contacts.clone()) else {
            return false;
        };
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
        let Some((at, area)) = best else {
            return false;
        };
        log::warn!(
            "plan: the contact mark at ({:.2}, {:.2}) m walls off {:.3} m² of unswept floor; a bumper's mark is a guess at where it closed, so it is taken out and that floor tried once more",
            at.x,
            at.y,
            area
        );
        // Tried before the request goes: a checkpoint between the two keeps
        // the mark and the place, and the resumed run leaves the mark.
        self.probed.push(at);
        self.publish(shared);
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
        shared.with_status(|s| s.contacts = Some(arcs));
        (g, p, shared, at)
    }

    #[test]
    fn a_mark_is_taken_out_once_and_the_place_tried_outlives_a_restart() {
        let (g, mut p, shared, at) = passage_shut_by_a_mark();
        let here = crate::geom::pose(0.4, 0.4, 0.0);
        let (tx, rx) = queue("map_msgs", 8, Overflow::DropOldest);
        let mut probe = MarkProbe::new(tx.clone(), true, 0.05, 0.34, Vec::new(), &shared);
        assert!(shared.with_status(|s| s.contacts_tried.is_none()));
        assert!(probe.walled_floor(&mut p, &shared, 1.0, &g, &here));
        assert!(matches!(rx.try_recv(), Recv::Msg(MapMsg::Retire(q)) if q == at));
        // The place is handed to the checkpoint, and not tried again.
        let saved = shared.with_status(|s| s.contacts_tried.clone()).unwrap();
        assert_eq!(saved.places, vec![at]);
        assert!(!probe.walled_floor(&mut p, &shared, 2.0, &g, &here));
        assert_eq!(probe.sent, 1);

        // A resumed run with the checkpoint's places leaves the mark, and
        // its next checkpoint still holds them.
        let (g, mut p, shared, _) = passage_shut_by_a_mark();
        let mut resumed = MarkProbe::new(tx, true, 0.05, 0.34, saved.places.clone(), &shared);
        let kept = shared.with_status(|s| s.contacts_tried.clone()).unwrap();
        assert_eq!(kept.places, vec![at]);
        assert!(!resumed.walled_floor(&mut p, &shared, 1.0, &g, &here));
        assert_eq!(resumed.sent, 0);
        assert!(matches!(rx.try_recv(), Recv::Empty));
    }
}
