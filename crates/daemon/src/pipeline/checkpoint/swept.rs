//! The planner's record of swept floor ([`SweptFloor`]) as checkpoint
//! section `plan.swept` (here, in the pipeline layer, so the planner knows
//! nothing of checkpoints).
//!
//! Payload, version 1: [`SweptFloor`] in postcard: the grid geometry
//! ([`Frame`]: origin x, y and cell size as f64, columns and rows as
//! varints), then the flags of [`sweepline_core::stored::bits`] (one bit per
//! cell, row-major).
//!
//! [`Frame`]: crate::plan::cspace::Frame

use super::checks::check_frame;
use super::Section;
use crate::plan::SweptFloor;

impl Section for SweptFloor {
    const NAME: &'static str = "plan.swept";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        check_frame(&self.frame, Some(("swept", self.covered.len())))?;
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point2;

    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::pipeline::checkpoint::testing::{refusal, round_trips};
    use crate::pipeline::checkpoint::Checkpoint;
    use crate::plan::cspace::Frame;
    use crate::plan::test_support::{planner, walled_room as room};

    #[test]
    fn swept_floor_survives_save_and_load() {
        let grid = room();
        let empty = Decomposition::default();
        let start = pose(0.6, 0.6, 0.0);
        let mut a = planner();
        a.update(&grid, &empty, &start, None).unwrap();
        for k in 0..100 {
            a.record_pose(&pose(0.6 + 0.02 * f64::from(k), 0.6, 0.0));
        }
        let saved = a.swept().unwrap();
        assert!(saved.area() > 0.5, "{} m² swept", saved.area());

        let mut cp = Checkpoint::new();
        cp.put(&saved).unwrap();
        let back = Checkpoint::from_bytes(&cp.to_bytes()).unwrap();
        let loaded: SweptFloor = back.require().unwrap();
        assert_eq!(loaded, saved);

        let mut fresh = planner();
        fresh.update(&grid, &empty, &start, None).unwrap();
        assert!(fresh.swept().unwrap().area() < saved.area() / 2.0);

        let mut b = planner();
        b.restore_swept(loaded);
        assert!(b.swept().is_none(), "no grid yet");
        b.update(&grid, &empty, &start, None).unwrap();
        assert_eq!(b.swept().unwrap(), saved);
        assert_eq!(b.covered(), a.covered());
    }

    #[test]
    fn bad_records_are_clear_errors() {
        let frame = Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.05,
            w: 9,
            h: 3,
        };
        let good = SweptFloor {
            frame,
            covered: (0..27).map(|i| i % 3 == 0).collect(),
        };
        round_trips(&good);
        let short = SweptFloor {
            covered: vec![true; 24],
            ..good.clone()
        };
        assert!(refusal(&short).contains("24 swept flags"));
        let bad_res = SweptFloor {
            frame: Frame { res: -1.0, ..frame },
            ..good
        };
        assert!(refusal(&bad_res).contains("cell size -1"));
    }
}
