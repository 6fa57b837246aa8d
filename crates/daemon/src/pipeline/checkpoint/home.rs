//! Where the robot started ([`HomePlace`]) as checkpoint section
//! `plan.home`, so that after a restart the robot drives back to where it
//! was put down (`plan.return_home`), not to where it was resumed.
//!
//! Payload, version 1: [`HomePlace`] in postcard: x (m), y (m), heading
//! (rad), f64, all finite.

use super::checks::finite;
use super::Section;
use crate::plan::HomePlace;

impl Section for HomePlace {
    const NAME: &'static str = "plan.home";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        finite("start x", self.x)?;
        finite("start y", self.y)?;
        finite("start heading", self.heading)?;
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::pipeline::checkpoint::testing::{refusal, round_trips};
    use crate::pipeline::checkpoint::Checkpoint;
    use crate::plan::test_support::{follow_to_done, planner, walled_room as room};
    use crate::plan::{HomeOutcome, Task};

    #[test]
    fn the_start_survives_a_restart_and_the_robot_drives_back_there() {
        let grid = room();
        let start = pose(0.6, 0.5, 0.3);
        let mut a = planner();
        assert_eq!(a.home(), None, "nothing recorded before the first update");
        a.update(&grid, &Decomposition::default(), &start, None)
            .unwrap();
        let saved = a.home().expect("the first update records the start");
        assert_eq!((saved.x, saved.y, saved.heading), (0.6, 0.5, 0.3));

        let mut cp = Checkpoint::new();
        cp.put(&saved).unwrap();
        let back: HomePlace = Checkpoint::from_bytes(&cp.to_bytes())
            .unwrap()
            .require()
            .unwrap();
        assert_eq!(back, saved);

        // Resumed at the far end of the room: the run ends back at the
        // restored start, not where the resumed run began.
        let resumed_at = pose(2.4, 1.5, 0.0);
        for (restored, to) in [(Some(back), (0.6, 0.5)), (None, (2.4, 1.5))] {
            let mut b = planner();
            if let Some(h) = restored {
                b.restore_home(h);
            }
            let (r, tasks) = follow_to_done(&mut b, &grid, resumed_at, 400).expect("done");
            assert_eq!(tasks.last(), Some(&Task::Home), "{tasks:?}");
            assert_eq!(r.home, HomeOutcome::Back);
            let end = b.history().iter().rev().find(|t| t.task == Task::Home);
            let end = *end.unwrap().path.last().unwrap();
            assert!(
                (end - nalgebra::Point2::new(to.0, to.1)).norm() < 1e-9,
                "restored {}: ends at {end}",
                restored.is_some()
            );
        }
        // A non-finite record is not taken.
        let mut c = planner();
        c.restore_home(HomePlace {
            x: f64::NAN,
            ..saved
        });
        assert_eq!(c.home(), None);
    }

    #[test]
    fn bad_records_are_clear_errors() {
        round_trips(&HomePlace {
            x: 1.5,
            y: -0.25,
            heading: 0.3,
        });
        let bad = HomePlace {
            x: 1.0,
            y: f64::INFINITY,
            heading: 0.0,
        };
        assert!(refusal(&bad).contains("start y is not a finite number"));
    }
}
