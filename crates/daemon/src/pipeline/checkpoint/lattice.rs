//! The phase of the planner's lane lattice ([`LatticePhase`]) as checkpoint
//! section `plan.lattice`, so that lanes planned after a restart line up
//! with the lanes driven before it.
//!
//! Payload, version 1: [`LatticePhase`] in postcard: for lanes along x, then
//! along y, an optional phase (f64, m; finite).

use super::checks::finite;
use super::Section;
use crate::plan::LatticePhase;

impl Section for LatticePhase {
    const NAME: &'static str = "plan.lattice";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        if let Some(v) = self.x {
            finite("phase of lanes along x", v)?;
        }
        if let Some(v) = self.y {
            finite("phase of lanes along y", v)?;
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::pipeline::checkpoint::testing::{read, refusal, round_trips};
    use crate::pipeline::checkpoint::Checkpoint;
    use crate::plan::test_support::{planner, walled_room as room};
    use crate::plan::{CoveragePlanner, PlanParams, Task};
    use crate::robot::RobotParams;

    /// Positions across the lanes (y: the room is wider than deep, so lanes
    /// run along x) of the planned lanes' waypoints.
    fn lane_rows(p: &CoveragePlanner) -> Vec<f64> {
        let (path, _) = p.path();
        path.windows(2)
            .filter(|w| (w[1].y - w[0].y).abs() < 1e-9 && (w[1].x - w[0].x).abs() > 0.5)
            .map(|w| w[0].y)
            .collect()
    }

    #[test]
    fn a_restored_lattice_places_the_lanes() {
        let grid = room();
        let empty = Decomposition::default();
        let start = pose(1.5, 1.0, 0.0);
        let mut a = planner();
        assert_eq!(
            a.lattice(),
            LatticePhase::default(),
            "not fixed before a lane"
        );
        a.update(&grid, &empty, &start, None).unwrap();
        assert_eq!(a.task(), Task::Cover(None));
        let saved = a.lattice();
        let phase = saved.x.expect("lanes along x fix the x phase");
        assert_eq!(saved.y, None);
        let rows = lane_rows(&a);
        assert!(rows.len() >= 3, "{rows:?}");

        let mut cp = Checkpoint::new();
        cp.put(&saved).unwrap();
        let back: LatticePhase = Checkpoint::from_bytes(&cp.to_bytes())
            .unwrap()
            .require()
            .unwrap();
        assert_eq!(back, saved);

        // A restart with the lattice shifted by a third of the spacing: the
        // new lanes lie on the restored lattice, not on a recomputed one.
        let spacing = RobotParams::default().tool_width - PlanParams::default().lane_overlap;
        let shifted = phase + spacing / 3.0;
        let mut b = planner();
        b.restore_lattice(LatticePhase {
            x: Some(shifted),
            y: Some(f64::NAN),
        });
        b.update(&grid, &empty, &start, None).unwrap();
        assert_eq!(b.lattice().x, Some(shifted));
        assert_eq!(b.lattice().y, None, "non-finite phase ignored");
        let on_lattice = |rows: &[f64], ph: f64| {
            rows.iter().all(|r| {
                let k = (r - ph) / spacing;
                (k - k.round()).abs() < 1e-6
            })
        };
        let rows_b = lane_rows(&b);
        assert!(!rows_b.is_empty());
        // Hugging lanes along a wall may lie off the lattice; most do not.
        let inner: Vec<f64> = rows_b
            .iter()
            .copied()
            .filter(|r| *r > 0.35 && *r < 1.6)
            .collect();
        assert!(!inner.is_empty(), "{rows_b:?}");
        assert!(on_lattice(&inner, shifted), "{inner:?} on {shifted}");
        assert!(!on_lattice(&inner, phase), "{inner:?} not on {phase}");
    }

    #[test]
    fn bad_records_are_clear_errors() {
        round_trips(&LatticePhase {
            x: Some(0.335),
            y: None,
        });
        let nan = LatticePhase {
            x: None,
            y: Some(f64::NAN),
        };
        assert!(refusal(&nan).contains("phase of lanes along y is not a finite number"));
        // An option tag that is neither 0 nor 1.
        assert!(read::<LatticePhase>(&[2, 0]).is_err());
    }
}
