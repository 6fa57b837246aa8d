//! Where the planner's robot could once get to, and its waits and further
//! rounds ([`PlanReach`]), as checkpoint section `plan.reach`: after a
//! restart the planner still waits for floor a person walls off (it waits
//! only for floor once within reach), and does not get its waits and rounds
//! of given-up floor afresh.
//!
//! Payload, version 1: [`PlanReach`] in postcard: the grid geometry, one bit
//! per cell (once within reach), then the waits and the further rounds so
//! far.

use super::checks::check_frame;
use super::Section;
use crate::plan::PlanReach;

/// Most waits or further rounds a record may hold: far above the planner's
/// own limits (20 waits, 10 rounds), far below what would wrap.
const MAX_COUNT: u32 = 1_000_000;

impl Section for PlanReach {
    const NAME: &'static str = "plan.reach";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        check_frame(
            &self.frame,
            Some(("once-within-reach", self.ever_reachable.len())),
        )?;
        for (what, v) in [
            ("waits", self.clear_waits),
            ("further rounds", self.extra_retries),
        ] {
            if v > MAX_COUNT {
                return Err(format!("{v} {what}: more than {MAX_COUNT}"));
            }
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point2;

    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::grid::CellState;
    use crate::pipeline::checkpoint::testing::{refusal, round_trips};
    use crate::pipeline::checkpoint::Checkpoint;
    use crate::plan::cspace::Frame;
    use crate::plan::test_support::{planner, walled_room as room};
    use crate::plan::{PlanStatus, Task};

    #[test]
    fn a_resumed_planner_still_waits_for_floor_once_within_reach() {
        // The walled room, all of it seen and within reach at first.
        let open = room();
        let empty = Decomposition::default();
        let at = pose(0.5, 0.5, 0.0);
        let mut a = planner();
        a.set_time(0.0);
        a.update(&open, &empty, &at, None).unwrap();
        assert!(a.reach_generation() > 0);
        let saved = a.reach().unwrap();
        assert!(saved.ever_reachable.iter().any(|&r| r));

        let mut cp = Checkpoint::new();
        cp.put(&saved).unwrap();
        let back = Checkpoint::from_bytes(&cp.to_bytes()).unwrap();
        let loaded: PlanReach = back.require().unwrap();
        assert_eq!(loaded, saved);

        // After the restart a wall of people stands across the room at
        // x = 1.5 m: the far half is walled off. Everything near is swept.
        let mut shut = room();
        for y in 0..60 {
            if let Some(c) = shut.cell_of(&Point2::new(1.5, 0.025 + 0.05 * f64::from(y))) {
                if shut.state(c) == CellState::Free {
                    shut.set_state(c, CellState::Occupied);
                }
            }
        }
        let sweep_near = |p: &mut crate::plan::CoveragePlanner| {
            for ky in 0..40 {
                for kx in 0..30 {
                    p.record_pose(&pose(0.05 * f64::from(kx), 0.05 * f64::from(ky), 0.0));
                }
            }
        };
        // Without the record, the far half was never within reach: the
        // resumed planner finishes.
        let mut forgot = planner();
        forgot.set_time(0.0);
        forgot.update(&shut, &empty, &at, None).unwrap();
        sweep_near(&mut forgot);
        let mut st = forgot.update(&shut, &empty, &at, None).unwrap();
        for _ in 0..200 {
            if matches!(st, PlanStatus::Done(_)) {
                break;
            }
            st = forgot.update(&shut, &empty, &at, None).unwrap();
        }
        assert!(matches!(st, PlanStatus::Done(_)), "{st:?}");

        // With it, restored before the first update as on a resume, the
        // planner waits for the far half instead.
        let mut b = planner();
        b.restore_reach(loaded);
        assert!(b.reach().is_none(), "no grid yet");
        b.set_time(0.0);
        b.update(&shut, &empty, &at, None).unwrap();
        sweep_near(&mut b);
        let mut st = b.update(&shut, &empty, &at, None).unwrap();
        let mut waited = false;
        for _ in 0..200 {
            waited |= matches!(
                st,
                PlanStatus::Working {
                    task: Task::Wait | Task::Idle,
                    ..
                }
            );
            if waited || matches!(st, PlanStatus::Done(_)) {
                break;
            }
            st = b.update(&shut, &empty, &at, None).unwrap();
        }
        assert!(waited, "{st:?}");
    }

    #[test]
    fn bad_records_are_clear_errors() {
        let frame = Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.05,
            w: 9,
            h: 3,
        };
        let good = PlanReach {
            frame,
            ever_reachable: (0..27).map(|i| i % 4 != 0).collect(),
            clear_waits: 2,
            extra_retries: 1,
        };
        round_trips(&good);
        let short = PlanReach {
            ever_reachable: vec![true; 26],
            ..good.clone()
        };
        assert!(refusal(&short).contains("26 once-within-reach flags"));
        let waits = PlanReach {
            clear_waits: u32::MAX,
            ..good
        };
        assert!(refusal(&waits).contains("waits"));
    }
}
