//! The planner's record of swept floor ([`SweptFloor`]) as checkpoint
//! section `plan.swept` (here, in the pipeline layer, so the planner knows
//! nothing of checkpoints).
//!
//! Payload, version 1 (little-endian): the grid geometry (origin x, origin y,
//! cell size: f64; columns, rows: u32, as [`super::GridHeader`]), then a byte
//! string (u64 length) of one bit per cell, row-major, least significant bit
//! first.

use nalgebra::Point2;

use super::{CheckpointError, Decoder, Encoder, GridHeader, Section};
use crate::plan::cspace::Frame;
use crate::plan::SweptFloor;

/// Largest record a checkpoint may restore (cells), as for the map grid.
pub(super) const MAX_CELLS: u64 = 8192 * 8192;

/// The planner grid's geometry as it is written (shared by the planner's
/// sections).
impl From<Frame> for GridHeader {
    fn from(f: Frame) -> Self {
        GridHeader {
            origin_x: f.origin.x,
            origin_y: f.origin.y,
            resolution: f.res,
            width: f.w as u32,
            height: f.h as u32,
        }
    }
}

/// The planner grid's geometry as it is read back.
impl From<&GridHeader> for Frame {
    fn from(g: &GridHeader) -> Self {
        Frame {
            origin: Point2::new(g.origin_x, g.origin_y),
            res: g.resolution,
            w: g.width as usize,
            h: g.height as usize,
        }
    }
}

impl Section for SweptFloor {
    const NAME: &'static str = "plan.swept";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        e.grid_header(&self.frame.into());
        put_flags(e, &self.covered);
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let g = d.grid_header(MAX_CELLS)?;
        let covered = take_flags(d, &g, "swept")?;
        Ok(Self {
            frame: (&g).into(),
            covered,
        })
    }
}

/// Writes one flag per cell as a byte string (u64 length) of one bit per
/// cell, row-major, least significant bit first.
pub(super) fn put_flags(e: &mut Encoder, flags: &[bool]) {
    let mut bits = vec![0u8; flags.len().div_ceil(8)];
    for (i, _) in flags.iter().enumerate().filter(|(_, c)| **c) {
        bits[i / 8] |= 1 << (i % 8);
    }
    e.bytes(&bits);
}

/// Reads the flags [`put_flags`] wrote for every cell of grid `g`; `what`
/// names them in the error.
pub(super) fn take_flags(
    d: &mut Decoder<'_>,
    g: &GridHeader,
    what: &str,
) -> Result<Vec<bool>, CheckpointError> {
    let bits = d.bytes()?;
    let (w, h, n) = (g.width, g.height, g.cells());
    if bits.len() != n.div_ceil(8) {
        return Err(d.error(format!(
            "{} bytes of {what} flags for a {w} x {h} grid",
            bits.len()
        )));
    }
    Ok((0..n).map(|i| bits[i / 8] & (1 << (i % 8)) != 0).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decomp::Decomposition;
    use crate::geom::pose;
    use crate::pipeline::checkpoint::Checkpoint;
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
        let good = SweptFloor {
            frame: Frame {
                origin: Point2::new(0.0, 0.0),
                res: 0.05,
                w: 9,
                h: 3,
            },
            covered: (0..27).map(|i| i % 3 == 0).collect(),
        };
        let mut e = Encoder::new();
        good.encode(&mut e);
        let bytes = e.into_bytes();
        let mut d = Decoder::new(SweptFloor::NAME, &bytes);
        assert_eq!(SweptFloor::decode(&mut d).unwrap(), good);
        for cut in [0, 10, 30, bytes.len() - 1] {
            let mut d = Decoder::new(SweptFloor::NAME, &bytes[..cut]);
            assert!(SweptFloor::decode(&mut d).is_err(), "cut at {cut}");
        }
        let mut e = Encoder::new();
        e.f64(0.0);
        e.f64(0.0);
        e.f64(0.05);
        e.u32(9);
        e.u32(3);
        e.bytes(&[0xff; 3]);
        let bytes = e.into_bytes();
        let err = SweptFloor::decode(&mut Decoder::new(SweptFloor::NAME, &bytes)).unwrap_err();
        assert!(err.to_string().contains("swept flags"), "{err}");
        let mut e = Encoder::new();
        e.f64(0.0);
        e.f64(0.0);
        e.f64(-1.0);
        let bytes = e.into_bytes();
        let err = SweptFloor::decode(&mut Decoder::new(SweptFloor::NAME, &bytes)).unwrap_err();
        assert!(err.to_string().contains("resolution"), "{err}");
    }
}
