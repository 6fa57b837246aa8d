//! Scan replies (GD/GS/GE, MD/MS/ME scans): the 4-character timestamp line,
//! then the values as one character stream cut into 64-character lines, so a
//! value may straddle two lines. The decoder has already concatenated the
//! verified payloads; here the character count is checked against the echoed
//! start/end/cluster before the scan is accepted, and values are decoded lazily
//! from the borrowed buffer (no allocation).
//!
//! URG-04LX `FF` cluster mode (**experimental**: undocumented, from Hokuyo's
//! old liburg, not yet tried on hardware): each step sends one 3-character
//! value, alternating distance and intensity over pairs of steps (even step
//! first, in absolute step numbers); both steps of a pair get the pair's
//! distance and intensity, halving the angular resolution. With an odd start
//! step the first value is the intensity of a pair whose distance was not
//! requested: that step is skipped.

use super::capacity::MAX_BEAMS;

use super::command::{Cluster, DataKind, ScanRequest};
use super::decoder::RawReply;
use super::encoding::{self, Width};
use super::error_codes::Reading;
use super::params::SensorParams;
use super::reply::DataLineWriter;
use super::sink::{ByteSink, EncodeError};

/// Why scan data were rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ScanError {
    /// No timestamp line.
    #[error("scan reply has no timestamp line")]
    MissingTimestamp,
    /// The timestamp line is not 4 encoded characters.
    #[error("scan timestamp line is malformed")]
    BadTimestamp,
    /// The data do not carry the number of characters the echoed request needs.
    #[error("scan carries {got} characters, the echoed request needs {expected}")]
    CountMismatch {
        /// Characters the echoed start/end/cluster require.
        expected: usize,
        /// Characters received.
        got: usize,
    },
    /// A byte outside the encoding alphabet.
    #[error("scan byte 0x{byte:02x} at offset {offset} is not an encoded character")]
    BadChar {
        /// The byte.
        byte: u8,
        /// Its offset in the concatenated data.
        offset: usize,
    },
    /// More beams than [`MAX_BEAMS`].
    #[error("scan has more than {MAX_BEAMS} beams")]
    TooManyBeams,
}

/// One decoded value of a scan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScanValue {
    /// First step covered by the value.
    pub step: u16,
    /// Steps covered (the cluster size; 1 in FF mode).
    pub steps: u16,
    /// Raw distance (mm, or an error code below DMIN).
    pub distance: u32,
    /// Raw intensity, for GE/ME and FF mode.
    pub intensity: Option<u32>,
}

/// A verified scan, borrowing the decoder's buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScanData<'a> {
    /// The echoed range, cluster and data kind.
    pub request: ScanRequest,
    /// For MD/MS/ME: scans remaining after this one, from the echo.
    pub remaining: Option<u8>,
    /// The sensor clock at the scan (ms, 24 bits).
    pub timestamp: u32,
    data: &'a [u8],
}

impl<'a> ScanData<'a> {
    /// Checks and wraps the data lines of a scan reply.
    pub fn from_reply(
        raw: &RawReply<'a>,
        request: ScanRequest,
        remaining: Option<u8>,
    ) -> Result<Self, ScanError> {
        let ts = raw.line(0).ok_or(ScanError::MissingTimestamp)?;
        if ts.len() != 4 {
            return Err(ScanError::BadTimestamp);
        }
        let timestamp = encoding::decode_value(ts).map_err(|_| ScanError::BadTimestamp)?;
        Self::new(request, remaining, timestamp, raw.joined_from(1))
    }

    /// Checks and wraps concatenated scan characters.
    pub fn new(
        request: ScanRequest,
        remaining: Option<u8>,
        timestamp: u32,
        data: &'a [u8],
    ) -> Result<Self, ScanError> {
        let expected = request.payload_chars();
        if data.len() != expected {
            return Err(ScanError::CountMismatch {
                expected,
                got: data.len(),
            });
        }
        if let Some(offset) = data.iter().position(|&b| !(0x30..=0x6f).contains(&b)) {
            return Err(ScanError::BadChar {
                byte: data[offset],
                offset,
            });
        }
        Ok(ScanData {
            request,
            remaining,
            timestamp,
            data,
        })
    }

    /// The concatenated encoded characters.
    pub fn chars(&self) -> &'a [u8] {
        self.data
    }

    /// Number of encoded fields (values; twice as many for GE/ME).
    pub fn field_count(&self) -> usize {
        self.data.len() / self.width().chars()
    }

    fn width(&self) -> Width {
        match self.request.kind {
            DataKind::ShortDistance => Width::Two,
            _ => Width::Three,
        }
    }

    /// Raw field `i` (0 when out of range; the alphabet was checked up front).
    pub fn field(&self, i: usize) -> u32 {
        let w = self.width().chars();
        match self.data.get(i * w..i * w + w) {
            Some(f) => f.iter().fold(0u32, |v, &c| {
                (v << 6) | u32::from(c.wrapping_sub(0x30) & 0x3f)
            }),
            None => 0,
        }
    }

    /// True when the request used the URG-04LX `FF` intensity mode.
    pub fn is_ff_intensity(&self) -> bool {
        self.request.cluster == Cluster::UrgIntensity
    }

    /// The decoded values in scanning order.
    pub fn values(&self) -> impl Iterator<Item = ScanValue> + '_ {
        let req = self.request;
        let group = req.cluster.group();
        let n = req.value_count();
        let ff = self.is_ff_intensity();
        let odd_start = usize::from(req.start & 1);
        (0..n).filter_map(move |i| {
            let step = req.start.saturating_add((i as u16).saturating_mul(group));
            if ff {
                let base = if (i + odd_start) % 2 == 0 {
                    i
                } else {
                    i.checked_sub(1)?
                };
                let intensity = (base + 1 < n).then(|| self.field(base + 1));
                return Some(ScanValue {
                    step,
                    steps: 1,
                    distance: self.field(base),
                    intensity,
                });
            }
            let steps = group.min(req.end.saturating_sub(step).saturating_add(1));
            match req.kind {
                DataKind::DistanceIntensity => Some(ScanValue {
                    step,
                    steps,
                    distance: self.field(2 * i),
                    intensity: Some(self.field(2 * i + 1)),
                }),
                _ => Some(ScanValue {
                    step,
                    steps,
                    distance: self.field(i),
                    intensity: None,
                }),
            }
        })
    }

    /// The readings (valid range, typed error code, or beyond DMAX) with the
    /// sensor's own DMIN/DMAX and model table.
    pub fn readings<'p>(
        &'p self,
        params: &'p SensorParams,
    ) -> impl Iterator<Item = (ScanValue, Reading)> + 'p {
        let family = params.family();
        self.values().map(move |v| {
            (
                v,
                Reading::classify(v.distance, params.dmin, params.dmax, family),
            )
        })
    }

    /// Writes the timestamp line and the data lines (64 characters each) as
    /// the sensor sends them.
    pub fn encode_lines(&self, out: &mut impl ByteSink) -> Result<(), EncodeError> {
        write_scan_lines(self.timestamp, self.data, out)
    }
}

/// Writes a scan body: the 4-character timestamp line, then `chars` (already
/// encoded values) cut into 64-character lines, each with its checksum.
pub fn write_scan_lines(
    timestamp: u32,
    chars: &[u8],
    out: &mut impl ByteSink,
) -> Result<(), EncodeError> {
    let mut w = DataLineWriter::new(&mut *out);
    w.put_value(timestamp & 0x00ff_ffff, Width::Four)?;
    w.finish()?;
    let mut w = DataLineWriter::new(out);
    w.put(chars)?;
    w.finish()
}

/// Encodes raw field values (distances, or distance/intensity pairs, or the
/// FF stream) at `width` into `out` as characters (no line cutting).
pub fn encode_fields(
    fields: impl IntoIterator<Item = u32>,
    width: Width,
    out: &mut impl ByteSink,
) -> Result<(), EncodeError> {
    for f in fields {
        encoding::encode_value(f, width, out)?;
    }
    Ok(())
}

/// The FF-mode field stream for steps `start..start + distances.len()`: for
/// each (even, odd) step pair, the pair's distance on the even step and its
/// intensity on the odd one (the inverse of what [`ScanData::values`] reads).
/// `distances[i]`/`intensities[i]` belong to step `start + i`.
pub fn ff_fields<'v>(
    start: u16,
    distances: &'v [u32],
    intensities: &'v [u32],
) -> impl Iterator<Item = u32> + 'v {
    (0..distances.len()).map(move |i| {
        let step = usize::from(start) + i;
        if step % 2 == 0 {
            distances[i]
        } else {
            intensities.get(i).copied().unwrap_or(0)
        }
    })
}
