//! Host side of the sensor stream: [`StreamParser`] finds frames in the byte
//! stream and decodes the packets the driver uses into a [`SensorFrame`].

use heapless::Vec as HVec;

use super::packets::{group_members, packet_size, response_size};
use super::{pkt, STREAM_HEADER};

/// The sensor values a stream frame carried (only those requested are `Some`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorFrame {
    /// Packet 7: bumps and wheel drops bit field.
    pub bumps_drops: Option<u8>,
    /// Packet 22: battery voltage (mV).
    pub voltage_mv: Option<u16>,
    /// Packet 35: OI mode byte.
    pub oi_mode: Option<u8>,
    /// Packet 43: left encoder counts.
    pub left_encoder: Option<u16>,
    /// Packet 44: right encoder counts.
    pub right_encoder: Option<u16>,
}

impl SensorFrame {
    /// Bumper bits as sides (right = bit 0, left = bit 1).
    pub fn bumps(&self) -> Option<super::Sides> {
        self.bumps_drops.map(|b| super::Sides {
            right: b & 0x01 != 0,
            left: b & 0x02 != 0,
        })
    }

    /// Wheel-drop bits as sides (right = bit 2, left = bit 3).
    pub fn wheel_drops(&self) -> Option<super::Sides> {
        self.bumps_drops.map(|b| super::Sides {
            right: b & 0x04 != 0,
            left: b & 0x08 != 0,
        })
    }

    /// Takes in single packet `id`'s data `d` (of its size).
    fn apply(&mut self, id: u8, d: &[u8]) {
        let word = || u16::from_be_bytes([d[0], d[1]]);
        match id {
            pkt::BUMPS_WHEEL_DROPS => self.bumps_drops = Some(d[0]),
            pkt::VOLTAGE => self.voltage_mv = Some(word()),
            pkt::OI_MODE => self.oi_mode = Some(d[0]),
            pkt::LEFT_ENCODER => self.left_encoder = Some(word()),
            pkt::RIGHT_ENCODER => self.right_encoder = Some(word()),
            _ => {}
        }
    }
}

/// Why a stream frame was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StreamError {
    /// The byte sum of the frame is not 0 mod 256.
    #[error("sensor stream checksum mismatch (sum 0x{0:02X}, expected 0)")]
    Checksum(u8),
    /// A packet id the specification does not define.
    #[error("sensor stream frame names unknown packet id {0}")]
    UnknownPacket(u8),
    /// The packets do not fill the frame's length exactly.
    #[error("sensor stream frame length {0} does not match its packets")]
    BadLength(u8),
}

/// Longest stream payload this parser accepts (bytes between the length and
/// the checksum): the driver asks for far less, and a bound keeps a corrupted
/// length from swallowing many good frames.
pub const MAX_PAYLOAD: usize = 120;

/// Host-side streaming parser of sensor frames: finds the header, checks the
/// length and checksum, and after a bad frame re-scans the bytes it had taken
/// for the next header, so one corrupted byte costs at most one frame.
#[derive(Clone, Debug, Default)]
pub struct StreamParser {
    buf: HVec<u8, { MAX_PAYLOAD + 3 }>,
    expect: Option<u8>,
    /// Bytes skipped while looking for a header.
    pub discarded: u64,
}

impl StreamParser {
    /// A parser looking for a header, accepting any plausible length.
    pub fn new() -> Self {
        Self::default()
    }

    /// A parser for a stream whose payload is known to be `n` bytes long (the
    /// host knows what it asked for): a header followed by any other length is
    /// taken for data at once, so a corrupted length cannot swallow the
    /// frames after it.
    pub fn with_payload_len(n: u8) -> Self {
        Self {
            expect: Some(n),
            ..Self::default()
        }
    }

    /// Expected payload length of the requested packet `ids` (single or
    /// group), if every id is defined and the frame fits.
    pub fn payload_len(ids: &[u8]) -> Option<u8> {
        let mut n = 0usize;
        for &id in ids {
            n += 1 + response_size(id)?;
        }
        (n > 0 && n <= MAX_PAYLOAD).then_some(n as u8)
    }

    /// Drops a partial frame (after a stream pause or reconnect).
    pub fn reset(&mut self) {
        self.buf.clear();
    }

    /// Feeds bytes; calls `out` for every complete frame, valid or not.
    pub fn feed(&mut self, bytes: &[u8], out: &mut impl FnMut(Result<SensorFrame, StreamError>)) {
        for &b in bytes {
            self.push(b, out);
        }
    }

    fn push(&mut self, b: u8, out: &mut impl FnMut(Result<SensorFrame, StreamError>)) {
        if self.buf.is_empty() {
            if b == STREAM_HEADER {
                let _ = self.buf.push(b);
            } else {
                self.discarded += 1;
            }
            return;
        }
        if self.buf.len() == 1
            && (b == 0 || b as usize > MAX_PAYLOAD || self.expect.is_some_and(|n| n != b))
        {
            // Not a plausible length: the 19 was data, look again from here.
            self.discarded += 1;
            self.buf.clear();
            self.push(b, out);
            return;
        }
        let _ = self.buf.push(b);
        let n = self.buf[1] as usize;
        if self.buf.len() < n + 3 {
            return;
        }
        match parse_frame(&self.buf) {
            Ok(f) => {
                self.buf.clear();
                out(Ok(f));
            }
            Err(e) => {
                out(Err(e));
                // Re-scan everything after the false header.
                let mut rest: HVec<u8, { MAX_PAYLOAD + 3 }> = HVec::new();
                let _ = rest.extend_from_slice(&self.buf[1..]);
                self.buf.clear();
                self.discarded += 1;
                for &r in rest.iter() {
                    self.push(r, out);
                }
            }
        }
    }
}

/// Parses one complete frame `19, n, payload, checksum`; a group packet's
/// data is its members' data in id order.
fn parse_frame(frame: &[u8]) -> Result<SensorFrame, StreamError> {
    let sum = frame.iter().fold(0u8, |a, &b| a.wrapping_add(b));
    if sum != 0 {
        return Err(StreamError::Checksum(sum));
    }
    let n = frame[1];
    let payload = &frame[2..frame.len() - 1];
    let mut f = SensorFrame::default();
    let mut i = 0;
    while i < payload.len() {
        let id = payload[i];
        let size = response_size(id).ok_or(StreamError::UnknownPacket(id))?;
        let Some(d) = payload.get(i + 1..i + 1 + size) else {
            return Err(StreamError::BadLength(n));
        };
        match group_members(id) {
            Some(members) => {
                let mut at = 0;
                for m in members {
                    let k = packet_size(m).unwrap_or(0);
                    if let Some(md) = d.get(at..at + k) {
                        f.apply(m, md);
                    }
                    at += k;
                }
            }
            None => f.apply(id, d),
        }
        i += 1 + size;
    }
    Ok(f)
}
