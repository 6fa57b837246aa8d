//! What the sections share: a bounds-checked reader of the container's
//! fixed-width fields, and the checks of values serde cannot make (finite
//! numbers, poses, grid geometry).

use crate::geom::{pose, Pose};
use crate::plan::cspace::Frame;

/// Largest grid a checkpoint may restore (cells): 8192 × 8192 at 5 cm is a
/// 400 m square, far more than any room.
pub(super) const MAX_CELLS: usize = 8192 * 8192;

/// Little-endian fixed-width fields off a byte slice; `None` when the slice
/// ends first.
pub(super) struct Bytes<'a> {
    buf: &'a [u8],
}

impl<'a> Bytes<'a> {
    pub(super) fn new(buf: &'a [u8]) -> Self {
        Self { buf }
    }

    /// Bytes not read yet.
    pub(super) fn remaining(&self) -> usize {
        self.buf.len()
    }

    /// The next `n` bytes.
    pub(super) fn raw(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.buf.len() {
            return None;
        }
        let (head, tail) = self.buf.split_at(n);
        self.buf = tail;
        Some(head)
    }

    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        self.raw(N)?.try_into().ok()
    }

    pub(super) fn u8(&mut self) -> Option<u8> {
        self.array::<1>().map(|[b]| b)
    }

    pub(super) fn u16(&mut self) -> Option<u16> {
        self.array().map(u16::from_le_bytes)
    }

    pub(super) fn u32(&mut self) -> Option<u32> {
        self.array().map(u32::from_le_bytes)
    }

    pub(super) fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }
}

/// `v`, or an error naming it when it is NaN or infinite.
pub(super) fn finite(what: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{what} is not a finite number ({v})"))
    }
}

/// A stored pose checked and made exact again: finite, and its rotation a
/// unit complex number (within 1e-6; renormalised).
pub(super) fn checked_pose(what: &str, p: &Pose) -> Result<Pose, String> {
    let x = finite(&format!("{what} x"), p.translation.x)?;
    let y = finite(&format!("{what} y"), p.translation.y)?;
    let (re, im) = (p.rotation.re, p.rotation.im);
    let norm = finite(&format!("{what} rotation"), re.hypot(im))?;
    if (norm - 1.0).abs() > 1e-6 {
        return Err(format!(
            "{what} rotation ({re}, {im}) is not a unit complex number"
        ));
    }
    Ok(pose(x, y, im.atan2(re)))
}

/// A planner grid's geometry checked: finite origin, a positive cell size,
/// at most [`MAX_CELLS`] cells; `cells` flags given per cell must number
/// exactly its cells. Returns the cell count.
pub(super) fn check_frame(f: &Frame, flags: Option<(&str, usize)>) -> Result<usize, String> {
    finite("grid origin x", f.origin.x)?;
    finite("grid origin y", f.origin.y)?;
    let res = finite("cell size", f.res)?;
    if res <= 0.0 {
        return Err(format!("cell size {res} is not > 0"));
    }
    let n =
        f.w.checked_mul(f.h)
            .filter(|&n| n <= MAX_CELLS)
            .ok_or_else(|| {
                format!(
                    "a {} x {} grid, more than the {MAX_CELLS} cells allowed",
                    f.w, f.h
                )
            })?;
    if let Some((what, got)) = flags {
        if got != n {
            return Err(format!("{got} {what} flags for a {} x {} grid", f.w, f.h));
        }
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use nalgebra::Point2;

    use super::*;

    #[test]
    fn the_reader_stops_at_the_end() {
        let mut b = Bytes::new(&[1, 2, 0, 3, 0, 0, 0]);
        assert_eq!(b.u8(), Some(1));
        assert_eq!(b.u16(), Some(2));
        assert_eq!(b.u32(), Some(3));
        assert_eq!(b.u8(), None);
        assert_eq!(b.remaining(), 0);
        assert_eq!(Bytes::new(&[1, 2, 3]).u64(), None);
    }

    #[test]
    fn bad_values_are_named() {
        assert!(finite("x", f64::NAN)
            .unwrap_err()
            .contains("x is not a finite"));
        let mut p = pose(1.0, 2.0, 0.3);
        assert!(checked_pose("start", &p).is_ok());
        p.rotation = nalgebra::UnitComplex::new_unchecked(nalgebra::Complex::new(2.0, 0.0));
        assert!(checked_pose("start", &p)
            .unwrap_err()
            .contains("unit complex"));
        let f = Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.05,
            w: 4,
            h: 3,
        };
        assert_eq!(check_frame(&f, Some(("swept", 12))), Ok(12));
        assert!(check_frame(&f, Some(("swept", 11)))
            .unwrap_err()
            .contains("11 swept"));
        let huge = Frame {
            w: 1 << 40,
            h: 1 << 40,
            ..f
        };
        assert!(check_frame(&huge, None).unwrap_err().contains("more than"));
        let neg = Frame { res: -0.1, ..f };
        assert!(check_frame(&neg, None).unwrap_err().contains("not > 0"));
    }
}
