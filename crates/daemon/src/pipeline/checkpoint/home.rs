//! Where the robot started ([`HomePlace`]) as checkpoint section
//! `plan.home`, so that after a restart the robot drives back to where it
//! was put down (`plan.return_home`), not to where it was resumed.
//!
//! Payload, version 1 (little-endian): x (f64, m), y (f64, m), heading
//! (f64, rad), all finite.

use super::{CheckpointError, Decoder, Encoder, Section};
use crate::plan::HomePlace;

impl Section for HomePlace {
    const NAME: &'static str = "plan.home";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        e.f64(self.x);
        e.f64(self.y);
        e.f64(self.heading);
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let x = d.finite("start x")?;
        let y = d.finite("start y")?;
        let heading = d.finite("start heading")?;
        Ok(Self { x, y, heading })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
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
        let good = HomePlace {
            x: 1.0,
            y: 2.0,
            heading: 0.5,
        };
        let mut e = Encoder::new();
        good.encode(&mut e);
        let bytes = e.into_bytes();
        let mut d = Decoder::new(HomePlace::NAME, &bytes);
        assert_eq!(HomePlace::decode(&mut d).unwrap(), good);
        for cut in 0..bytes.len() {
            let mut d = Decoder::new(HomePlace::NAME, &bytes[..cut]);
            assert!(HomePlace::decode(&mut d).is_err(), "cut at {cut}");
        }
        for (k, what) in ["start x", "start y", "start heading"].iter().enumerate() {
            let mut e = Encoder::new();
            for j in 0..3 {
                e.f64(if j == k { f64::INFINITY } else { 0.5 });
            }
            let bytes = e.into_bytes();
            let err = HomePlace::decode(&mut Decoder::new(HomePlace::NAME, &bytes)).unwrap_err();
            assert!(err.to_string().contains(what), "{err}");
        }
    }
}
