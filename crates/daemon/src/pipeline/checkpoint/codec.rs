//! The small binary encoding of checkpoint sections: little-endian fixed-width
//! integers and IEEE floats, length-prefixed byte strings and sequences, and
//! CRC-32 (IEEE 802.3, the zlib/PNG polynomial) for integrity.
//!
//! Why our own instead of a serde format crate: the reader must survive
//! hostile files without panicking or allocating what a length field claims,
//! and every length here is checked against the bytes actually left before
//! anything is allocated. The format is a page of documentation
//! (`docs/checkpoints.md`), stable, and readable from any language.

use super::CheckpointError;
use crate::geom::IPoint;

/// CRC-32 lookup tables for slicing-by-8: `T[0]` is the classic byte table,
/// `T[k][b]` is the CRC of byte `b` followed by `k` zero bytes.
const fn crc_tables() -> [[u32; 256]; 8] {
    let mut t = [[0u32; 256]; 8];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[0][i] = c;
        i += 1;
    }
    let mut i = 0;
    while i < 256 {
        let mut k = 1;
        while k < 8 {
            let prev = t[k - 1][i];
            t[k][i] = (prev >> 8) ^ t[0][(prev & 0xFF) as usize];
            k += 1;
        }
        i += 1;
    }
    t
}

static CRC_TABLES: [[u32; 256]; 8] = crc_tables();

/// CRC-32 (IEEE, reflected, init and xor-out 0xFFFFFFFF) of `bytes`: the
/// checksum zlib, PNG and gzip use. `crc32(b"123456789") == 0xCBF43926`.
/// Slicing-by-8: eight bytes per step.
pub fn crc32(bytes: &[u8]) -> u32 {
    let t = &CRC_TABLES;
    let mut c = 0xFFFF_FFFFu32;
    let mut chunks = bytes.chunks_exact(8);
    for ch in &mut chunks {
        let lo = c ^ u32::from_le_bytes([ch[0], ch[1], ch[2], ch[3]]);
        let hi = u32::from_le_bytes([ch[4], ch[5], ch[6], ch[7]]);
        c = t[7][(lo & 0xFF) as usize]
            ^ t[6][((lo >> 8) & 0xFF) as usize]
            ^ t[5][((lo >> 16) & 0xFF) as usize]
            ^ t[4][(lo >> 24) as usize]
            ^ t[3][(hi & 0xFF) as usize]
            ^ t[2][((hi >> 8) & 0xFF) as usize]
            ^ t[1][((hi >> 16) & 0xFF) as usize]
            ^ t[0][(hi >> 24) as usize];
    }
    for &b in chunks.remainder() {
        c = t[0][((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8);
    }
    c ^ 0xFFFF_FFFF
}

/// Writes a section payload.
#[derive(Debug, Default)]
pub struct Encoder {
    buf: Vec<u8>,
}

impl Encoder {
    /// An empty payload.
    pub fn new() -> Self {
        Self::default()
    }

    /// The bytes written so far.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    /// One byte.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A little-endian u16.
    pub fn u16(&mut self, v: u16) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A little-endian u32.
    pub fn u32(&mut self, v: u32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// The geometry of a raster (origin, cell size, columns, rows), as
    /// [`Decoder::grid_header`] reads it back.
    pub fn grid_header(&mut self, h: &GridHeader) {
        self.f64(h.origin_x);
        self.f64(h.origin_y);
        self.f64(h.resolution);
        self.u32(h.width);
        self.u32(h.height);
    }

    /// A little-endian u64.
    pub fn u64(&mut self, v: u64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A little-endian i64.
    pub fn i64(&mut self, v: i64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A little-endian IEEE-754 single (rounded from `v`).
    pub fn f32(&mut self, v: f64) {
        self.buf.extend_from_slice(&(v as f32).to_le_bytes());
    }

    /// A little-endian IEEE-754 double.
    pub fn f64(&mut self, v: f64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A bool as one byte (0 or 1).
    pub fn bool(&mut self, v: bool) {
        self.u8(u8::from(v));
    }

    /// A byte string: u64 length, then the bytes.
    pub fn bytes(&mut self, v: &[u8]) {
        self.u64(v.len() as u64);
        self.buf.extend_from_slice(v);
    }

    /// A UTF-8 string, as [`Encoder::bytes`].
    pub fn str(&mut self, v: &str) {
        self.bytes(v.as_bytes());
    }

    /// A sequence length prefix (u64); follow it with the elements.
    pub fn len(&mut self, n: usize) {
        self.u64(n as u64);
    }

    /// Points with intensity: length, then x, y, intensity of each.
    pub fn points(&mut self, pts: &[IPoint]) {
        self.len(pts.len());
        for p in pts {
            self.f64(p.x);
            self.f64(p.y);
            self.f64(p.intensity);
        }
    }
}

/// The geometry of a raster stored in a checkpoint section (the explored
/// grid, the planner's swept floor): one encoding and one validation for all.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridHeader {
    /// World x of the lower-left corner (m).
    pub origin_x: f64,
    /// World y of the lower-left corner (m).
    pub origin_y: f64,
    /// Cell size (m), > 0.
    pub resolution: f64,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

impl GridHeader {
    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// Reads a section payload; every read is bounds-checked and returns a
/// [`CheckpointError`] naming the section instead of panicking.
#[derive(Debug)]
pub struct Decoder<'a> {
    section: &'a str,
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Decoder<'a> {
    /// A decoder over `buf`, the payload of section `section`.
    pub fn new(section: &'a str, buf: &'a [u8]) -> Self {
        Self {
            section,
            buf,
            pos: 0,
        }
    }

    /// Reads a [`GridHeader`]: finite origin, positive cell size, and at
    /// most `max_cells` cells, else an error naming what is wrong.
    pub fn grid_header(&mut self, max_cells: u64) -> Result<GridHeader, CheckpointError> {
        let origin_x = self.finite("origin x")?;
        let origin_y = self.finite("origin y")?;
        let resolution = self.finite("resolution")?;
        if resolution <= 0.0 {
            return Err(self.error(format!("resolution {resolution} is not > 0")));
        }
        let width = self.u32()?;
        let height = self.u32()?;
        if u64::from(width) * u64::from(height) > max_cells {
            return Err(self.error(format!(
                "{width} x {height} cells, more than the {max_cells} allowed"
            )));
        }
        Ok(GridHeader {
            origin_x,
            origin_y,
            resolution,
            width,
            height,
        })
    }

    /// The error "section is malformed: `message`" for this section.
    pub fn error(&self, message: impl Into<String>) -> CheckpointError {
        CheckpointError::BadSection {
            name: self.section.to_string(),
            message: message.into(),
        }
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }

    /// The next `n` bytes as they are (no length prefix).
    pub fn raw(&mut self, n: usize) -> Result<&'a [u8], CheckpointError> {
        self.take(n)
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], CheckpointError> {
        if n > self.remaining() {
            return Err(self.error(format!(
                "ends early: needs {n} more bytes at offset {}, has {}",
                self.pos,
                self.remaining()
            )));
        }
        let s = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], CheckpointError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }

    /// One byte.
    pub fn u8(&mut self) -> Result<u8, CheckpointError> {
        Ok(self.array::<1>()?[0])
    }

    /// A little-endian u16.
    pub fn u16(&mut self) -> Result<u16, CheckpointError> {
        Ok(u16::from_le_bytes(self.array()?))
    }

    /// A little-endian u32.
    pub fn u32(&mut self) -> Result<u32, CheckpointError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// A little-endian u64.
    pub fn u64(&mut self) -> Result<u64, CheckpointError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    /// A little-endian i64.
    pub fn i64(&mut self) -> Result<i64, CheckpointError> {
        Ok(i64::from_le_bytes(self.array()?))
    }

    /// A little-endian double (any bit pattern, NaN included).
    pub fn f64(&mut self) -> Result<f64, CheckpointError> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    /// A little-endian single widened to a double, which must be finite;
    /// `what` names it in the error.
    pub fn finite_f32(&mut self, what: &str) -> Result<f64, CheckpointError> {
        let v = f64::from(f32::from_le_bytes(self.array()?));
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(format!("{what} is not a finite number ({v})")))
        }
    }

    /// A double that must be finite; `what` names it in the error.
    pub fn finite(&mut self, what: &str) -> Result<f64, CheckpointError> {
        let v = self.f64()?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(format!("{what} is not a finite number ({v})")))
        }
    }

    /// A bool (0 or 1; anything else is an error).
    pub fn bool(&mut self) -> Result<bool, CheckpointError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(self.error(format!("bool byte is {b}, not 0 or 1"))),
        }
    }

    /// A byte string written by [`Encoder::bytes`]; the length is checked
    /// against the bytes left before anything is copied.
    pub fn bytes(&mut self) -> Result<&'a [u8], CheckpointError> {
        let n = self.u64()?;
        let n = usize::try_from(n)
            .ok()
            .filter(|&n| n <= self.remaining())
            .ok_or_else(|| {
                self.error(format!(
                    "byte string of {n} bytes but only {} left",
                    self.remaining()
                ))
            })?;
        self.take(n)
    }

    /// A UTF-8 string written by [`Encoder::str`].
    pub fn str(&mut self) -> Result<&'a str, CheckpointError> {
        let b = self.bytes()?;
        std::str::from_utf8(b).map_err(|_| self.error("string is not UTF-8"))
    }

    /// A sequence length whose elements take at least `min_elem_bytes` each:
    /// rejected when the bytes left cannot hold that many (so a hostile length
    /// never causes a huge allocation).
    pub fn len(&mut self, min_elem_bytes: usize) -> Result<usize, CheckpointError> {
        let n = self.u64()?;
        let fits = usize::try_from(n).ok().filter(|&n| {
            n.checked_mul(min_elem_bytes.max(1))
                .is_some_and(|b| b <= self.remaining())
        });
        fits.ok_or_else(|| {
            self.error(format!(
                "sequence of {n} elements cannot fit in the {} bytes left",
                self.remaining()
            ))
        })
    }

    /// Points written by [`Encoder::points`]; every coordinate must be finite.
    pub fn points(&mut self) -> Result<Vec<IPoint>, CheckpointError> {
        let n = self.len(24)?;
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            let x = self.finite("point x")?;
            let y = self.finite("point y")?;
            let i = self.finite("point intensity")?;
            v.push(IPoint::new(x, y, i));
        }
        Ok(v)
    }

    /// Fails unless every byte was read (a longer payload means a different
    /// layout than this reader expects).
    pub fn finish(self) -> Result<(), CheckpointError> {
        if self.remaining() == 0 {
            Ok(())
        } else {
            Err(self.error(format!("{} unexpected trailing bytes", self.remaining())))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
        // Every length around the 8-byte stride against the bytewise definition.
        let data: Vec<u8> = (0..100u32).map(|i| (i * 37 + 11) as u8).collect();
        for n in 0..data.len() {
            let mut c = 0xFFFF_FFFFu32;
            for &b in &data[..n] {
                c ^= u32::from(b);
                for _ in 0..8 {
                    c = if c & 1 != 0 {
                        0xEDB8_8320 ^ (c >> 1)
                    } else {
                        c >> 1
                    };
                }
            }
            assert_eq!(crc32(&data[..n]), c ^ 0xFFFF_FFFF, "length {n}");
        }
    }

    #[test]
    fn round_trip_and_bounds() {
        let mut e = Encoder::new();
        e.u8(7);
        e.u16(0xBEEF);
        e.u32(123_456);
        e.u64(u64::MAX);
        e.i64(-5);
        e.f64(1.5);
        e.bool(true);
        e.str("pose");
        e.points(&[IPoint::new(1.0, 2.0, 0.5)]);
        let b = e.into_bytes();
        let mut d = Decoder::new("t", &b);
        assert_eq!(d.u8().unwrap(), 7);
        assert_eq!(d.u16().unwrap(), 0xBEEF);
        assert_eq!(d.u32().unwrap(), 123_456);
        assert_eq!(d.u64().unwrap(), u64::MAX);
        assert_eq!(d.i64().unwrap(), -5);
        assert_eq!(d.finite("x").unwrap(), 1.5);
        assert!(d.bool().unwrap());
        assert_eq!(d.str().unwrap(), "pose");
        assert_eq!(d.points().unwrap(), vec![IPoint::new(1.0, 2.0, 0.5)]);
        d.finish().unwrap();

        let mut d = Decoder::new("t", &[1, 2]);
        let e = d.u32().unwrap_err();
        assert!(e.to_string().contains("section `t`"), "{e}");
        let huge = u64::MAX.to_le_bytes();
        assert!(Decoder::new("t", &huge).bytes().is_err());
        assert!(Decoder::new("t", &huge).len(1).is_err());
        assert!(Decoder::new("t", &[2]).bool().is_err());
        let nan = f64::NAN.to_le_bytes();
        assert!(Decoder::new("t", &nan).finite("x").is_err());
        assert!(Decoder::new("t", &[0]).finish().is_err());
    }
}
