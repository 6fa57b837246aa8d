//! The planner's tries and give-ups ([`PlanTries`]) as checkpoint section
//! `plan.tries`: a resumed run does not give floor it already failed to
//! reach all its tries again, nor a second round it already had.
//!
//! Payload, version 1 (little-endian): the grid geometry (as
//! [`super::GridHeader`]), a u64 count of listed cells, then per cell its
//! row-major index (u32, strictly increasing, inside the grid), its tries
//! (u8) and its flags (u8: bit 0 abandoned as a cover target, bit 1 given up
//! as an exploration goal, no other bit), then whether given-up floor has
//! had its second round (bool).

use super::swept::MAX_CELLS;
use super::{CheckpointError, Decoder, Encoder, Section};
use crate::plan::{PlanTries, TriedCell};

/// Flag bits of a listed cell.
const ABANDONED: u8 = 1;
const GIVEN_UP: u8 = 2;

impl Section for PlanTries {
    const NAME: &'static str = "plan.tries";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        e.grid_header(&self.frame.into());
        e.len(self.cells.len());
        for c in &self.cells {
            e.u32(c.index);
            e.u8(c.tries);
            let mut flags = 0;
            if c.abandoned {
                flags |= ABANDONED;
            }
            if c.given_up {
                flags |= GIVEN_UP;
            }
            e.u8(flags);
        }
        e.bool(self.retried);
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let g = d.grid_header(MAX_CELLS)?;
        let n = d.len(6)?;
        let mut cells = Vec::with_capacity(n);
        for _ in 0..n {
            let index = d.u32()?;
            let tries = d.u8()?;
            let flags = d.u8()?;
            if index as usize >= g.cells() {
                return Err(d.error(format!(
                    "cell {index} outside the {} x {} grid",
                    g.width, g.height
                )));
            }
            if cells.last().is_some_and(|c: &TriedCell| c.index >= index) {
                return Err(d.error(format!("cell {index} listed out of order")));
            }
            if flags & !(ABANDONED | GIVEN_UP) != 0 {
                return Err(d.error(format!("cell {index} has unknown flags {flags:#04x}")));
            }
            cells.push(TriedCell {
                index,
                tries,
                abandoned: flags & ABANDONED != 0,
                given_up: flags & GIVEN_UP != 0,
            });
        }
        let retried = d.bool()?;
        Ok(Self {
            frame: (&g).into(),
            cells,
            retried,
        })
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point2;

    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::pipeline::checkpoint::Checkpoint;
    use crate::plan::cspace::Frame;
    use crate::plan::test_support::{planner, walled_room as room};
    use crate::plan::{PlanParams, PlanStatus, Task};

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
        let good = PlanTries {
            frame,
            cells: vec![
                TriedCell {
                    index: 2,
                    tries: 1,
                    abandoned: false,
                    given_up: true,
                },
                TriedCell {
                    index: 11,
                    tries: 2,
                    abandoned: true,
                    given_up: false,
                },
            ],
            retried: false,
        };
        let mut e = Encoder::new();
        good.encode(&mut e);
        let bytes = e.into_bytes();
        assert_eq!(
            PlanTries::decode(&mut Decoder::new(PlanTries::NAME, &bytes)).unwrap(),
            good
        );
        for cut in [0, 20, 36, 44, bytes.len() - 1] {
            let mut d = Decoder::new(PlanTries::NAME, &bytes[..cut]);
            assert!(PlanTries::decode(&mut d).is_err(), "cut at {cut}");
        }
        // Header (32 bytes) and count (8): the cells (6 bytes each) start at byte 40.
        let bad = |at: usize, v: u8, what: &str| {
            let mut b = bytes.clone();
            b[at] = v;
            let err = PlanTries::decode(&mut Decoder::new(PlanTries::NAME, &b)).unwrap_err();
            assert!(err.to_string().contains(what), "{err}");
        };
        bad(40 + 6, 12, "outside");
        bad(40 + 6, 2, "out of order");
        bad(40 + 5, 0x84, "flags");
        // A count the bytes left cannot hold allocates nothing.
        let mut huge = bytes.clone();
        huge[32..40].copy_from_slice(&u64::MAX.to_le_bytes());
        let err = PlanTries::decode(&mut Decoder::new(PlanTries::NAME, &huge)).unwrap_err();
        assert!(err.to_string().contains("cannot fit"), "{err}");
    }
}
