//! The planner's tries and give-ups ([`PlanTries`]) as checkpoint section
//! `plan.tries`: a resumed run does not give floor it already failed to
//! reach all its tries again, nor a second round it already had.
//!
//! Payload, version 1: [`PlanTries`] in postcard: the grid geometry, the
//! listed cells (row-major index, strictly increasing and inside the grid;
//! tries; abandoned as a cover target; given up as an exploration goal),
//! then whether given-up floor has had its second round.

use super::checks::check_frame;
use super::Section;
use crate::plan::PlanTries;

impl Section for PlanTries {
    const NAME: &'static str = "plan.tries";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        let n = check_frame(&self.frame, None)?;
        let (w, h) = (self.frame.w, self.frame.h);
        let mut last = None;
        for c in &self.cells {
            if c.index as usize >= n {
                return Err(format!("cell {} outside the {w} x {h} grid", c.index));
            }
            if last.is_some_and(|l| l >= c.index) {
                return Err(format!("cell {} listed out of order", c.index));
            }
            last = Some(c.index);
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
    use crate::pipeline::checkpoint::testing::{payload, read, refusal, round_trips};
    use crate::pipeline::checkpoint::Checkpoint;
    use crate::plan::cspace::Frame;
    use crate::plan::test_support::{planner, walled_room as room};
    use crate::plan::{PlanParams, PlanStatus, Task, TriedCell};

    /// Every cell of `frame` abandoned after `tries` tries.
    fn all_given_up(frame: Frame, retried: bool) -> PlanTries {
        PlanTries {
            frame,
            cells: (0..frame.len() as u32)
                .map(|index| TriedCell {
                    index,
                    tries: 2,
                    abandoned: true,
                    given_up: index % 7 == 0,
                })
                .collect(),
            retried,
        }
    }

    #[test]
    fn a_resumed_planner_keeps_what_it_gave_up_and_its_second_round() {
        let grid = room();
        let empty = Decomposition::default();
        let at = pose(1.5, 1.0, 0.0);
        let mut a = planner();
        a.update(&grid, &empty, &at, None).unwrap();
        let fresh = a.tries().unwrap();
        assert!(fresh.cells.is_empty() && !fresh.retried, "{fresh:?}");
        let frame = fresh.frame;

        // All floor given up and its second round had: saved, loaded.
        let saved = all_given_up(frame, true);
        let mut cp = Checkpoint::new();
        cp.put(&saved).unwrap();
        let back = Checkpoint::from_bytes(&cp.to_bytes()).unwrap();
        let loaded: PlanTries = back.require().unwrap();
        assert_eq!(loaded, saved);

        // Restored before the first update (no grid yet), as on a resume:
        // nothing is left to try now, and so much given up (people may
        // have kept crossing the robot's paths) that the planner waits
        // `plan.clear_wait` rather than finish, then tries it again.
        let mut b = planner();
        b.restore_tries(loaded.clone());
        assert!(b.tries().is_none(), "no grid yet");
        b.set_time(0.0);
        let st = b.update(&grid, &empty, &at, None).unwrap();
        assert_eq!(b.tries().unwrap(), saved);
        assert!(
            matches!(
                st,
                PlanStatus::Working {
                    task: Task::Idle,
                    ..
                }
            ),
            "{st:?}"
        );
        b.set_time(PlanParams::default().clear_wait + 1.0);
        let st = b.update(&grid, &empty, &at, None).unwrap();
        assert!(
            matches!(
                st,
                PlanStatus::Working {
                    task: Task::Cover(_),
                    ..
                }
            ),
            "{st:?}"
        );
        assert!(b.tries().unwrap().cells.iter().all(|t| !t.abandoned));

        // Without the second round had, the given-up floor gets it.
        let mut c = planner();
        c.restore_tries(all_given_up(frame, false));
        let st = c.update(&grid, &empty, &at, None).unwrap();
        assert!(!matches!(st, PlanStatus::Done(_)), "{st:?}");
        assert!(c.tries().unwrap().retried);
        assert!(c.tries().unwrap().cells.iter().all(|t| !t.abandoned));
    }

    #[test]
    fn a_record_of_another_grid_is_ignored() {
        let grid = room();
        let empty = Decomposition::default();
        let at = pose(1.5, 1.0, 0.0);
        let mut a = planner();
        a.update(&grid, &empty, &at, None).unwrap();
        let mut other = a.tries().unwrap().frame;
        other.w -= 1;
        let mut b = planner();
        b.restore_tries(all_given_up(other, true));
        let st = b.update(&grid, &empty, &at, None).unwrap();
        assert!(!matches!(st, PlanStatus::Done(_)), "{st:?}");
        assert!(b.tries().unwrap().cells.is_empty());
    }

    #[test]
    fn bad_records_are_clear_errors() {
        let frame = Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.05,
            w: 4,
            h: 3,
        };
        let cell = |index, tries| TriedCell {
            index,
            tries,
            abandoned: tries > 1,
            given_up: tries == 1,
        };
        let good = PlanTries {
            frame,
            cells: vec![cell(3, 1), cell(11, 2)],
            retried: false,
        };
        round_trips(&good);
        let outside = PlanTries {
            cells: vec![cell(3, 1), cell(12, 2)],
            ..good.clone()
        };
        assert!(refusal(&outside).contains("cell 12 outside the 4 x 3 grid"));
        let unordered = PlanTries {
            cells: vec![cell(3, 1), cell(2, 2)],
            ..good
        };
        assert!(refusal(&unordered).contains("out of order"));
        // A count the bytes left cannot hold allocates nothing.
        let mut huge = payload(&PlanTries {
            cells: vec![],
            ..unordered
        });
        let at = huge.len() - 2;
        huge.truncate(at);
        huge.extend_from_slice(&[0xff, 0xff, 0xff, 0xff, 0x0f, 0]);
        assert!(read::<PlanTries>(&huge).is_err());
    }
}
