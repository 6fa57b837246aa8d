//! iRobot Create 2 / Roomba Open Interface (OI), sans-IO.
//!
//! Host → robot: one opcode byte and its fixed data ([`OiCommand`],
//! [`encode`]). Robot → host: the sensor stream, a frame every 15 ms:
//! `19, n, (packet id, packet data)…, checksum`, where `n` counts the bytes
//! between itself and the checksum, and the 8-bit sum of every frame byte,
//! checksum included, is 0. Multi-byte values are big-endian.
//!
//! The host side is [`encode`] plus the streaming [`StreamParser`]; the device
//! side (emulator) is [`OiDecoder`] plus [`encode_stream_frame`]. Nothing here
//! allocates or panics on any input.

use heapless::Vec as HVec;

/// Opcodes used here (Create 2 OI specification).
pub mod op {
    /// Reset the robot (as if the battery were removed and reinserted).
    pub const RESET: u8 = 7;
    /// Start the OI (enters Passive mode).
    pub const START: u8 = 128;
    /// Set the baud rate (1 data byte, code 11 = 115200).
    pub const BAUD: u8 = 129;
    /// Enter Safe mode.
    pub const SAFE: u8 = 131;
    /// Enter Full mode.
    pub const FULL: u8 = 132;
    /// Drive with velocity and turn radius (4 data bytes).
    pub const DRIVE: u8 = 137;
    /// Query one sensor packet (1 data byte).
    pub const SENSORS: u8 = 142;
    /// Drive each wheel: right velocity then left velocity, mm/s (4 data bytes).
    pub const DRIVE_DIRECT: u8 = 145;
    /// Drive each wheel by PWM, ±255 (4 data bytes).
    pub const DRIVE_PWM: u8 = 146;
    /// Start a sensor stream: count, then that many packet ids.
    pub const STREAM: u8 = 148;
    /// Query a list of packets once: count, then ids.
    pub const QUERY_LIST: u8 = 149;
    /// Pause (0) or resume (1) the stream.
    pub const PAUSE_RESUME: u8 = 150;
    /// Stop the OI (robot stops responding to commands).
    pub const STOP: u8 = 173;
}

/// Sensor packet ids used here.
pub mod pkt {
    /// Bumps (bits 0 right, 1 left) and wheel drops (bits 2 right, 3 left).
    pub const BUMPS_WHEEL_DROPS: u8 = 7;
    /// Battery voltage (mV, u16).
    pub const VOLTAGE: u8 = 22;
    /// OI mode: 0 Off, 1 Passive, 2 Safe, 3 Full.
    pub const OI_MODE: u8 = 35;
    /// Left wheel encoder counts (u16, wrapping).
    pub const LEFT_ENCODER: u8 = 43;
    /// Right wheel encoder counts (u16, wrapping).
    pub const RIGHT_ENCODER: u8 = 44;
}

/// The stream frame header byte.
pub const STREAM_HEADER: u8 = 19;
/// Fastest wheel speed Drive Direct accepts (mm/s).
pub const MAX_WHEEL_MM_S: i16 = 500;
/// Most packet ids in one stream request this codec sends or accepts.
pub const MAX_STREAM_IDS: usize = 16;

/// Data size in bytes of single sensor packet `id` (7..=58), `None` for group
/// packets and unknown ids.
pub fn packet_size(id: u8) -> Option<usize> {
    match id {
        7..=18 | 21 | 24 | 32 | 34..=38 | 45 | 52 | 53 | 58 => Some(1),
        19 | 20 | 22 | 23 | 25..=31 | 33 | 39..=44 | 46..=51 | 54..=57 => Some(2),
        _ => None,
    }
}

/// The OI's operating mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OiMode {
    /// OI not started: only Start is obeyed.
    Off,
    /// Sensors only; actuator commands are ignored.
    Passive,
    /// Actuators obeyed; the robot stops itself on cliffs and wheel drops.
    Safe,
    /// Actuators obeyed, no safety reflexes.
    Full,
}

impl OiMode {
    /// Mode from packet 35's value.
    pub fn from_byte(b: u8) -> Option<OiMode> {
        match b {
            0 => Some(OiMode::Off),
            1 => Some(OiMode::Passive),
            2 => Some(OiMode::Safe),
            3 => Some(OiMode::Full),
            _ => None,
        }
    }

    /// Packet 35's value for this mode.
    pub fn to_byte(self) -> u8 {
        match self {
            OiMode::Off => 0,
            OiMode::Passive => 1,
            OiMode::Safe => 2,
            OiMode::Full => 3,
        }
    }
}

/// A host-to-robot command.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OiCommand {
    /// Opcode 128.
    Start,
    /// Opcode 129 with its baud code.
    Baud(u8),
    /// Opcode 131.
    Safe,
    /// Opcode 132.
    Full,
    /// Opcode 173.
    Stop,
    /// Opcode 7.
    Reset,
    /// Opcode 137: velocity (mm/s) and radius (mm).
    Drive {
        /// Velocity, mm/s.
        velocity: i16,
        /// Radius, mm (special values for straight and spin).
        radius: i16,
    },
    /// Opcode 145: per-wheel velocities in mm/s; right goes first on the wire.
    DriveDirect {
        /// Right wheel, mm/s.
        right: i16,
        /// Left wheel, mm/s.
        left: i16,
    },
    /// Opcode 146: per-wheel PWM, right first.
    DrivePwm {
        /// Right wheel PWM.
        right: i16,
        /// Left wheel PWM.
        left: i16,
    },
    /// Opcode 148: stream these packet ids every 15 ms.
    Stream(HVec<u8, MAX_STREAM_IDS>),
    /// Opcode 149: send these packets once.
    QueryList(HVec<u8, MAX_STREAM_IDS>),
    /// Opcode 142: send one packet once.
    Sensors(u8),
    /// Opcode 150: `false` pauses the stream, `true` resumes it.
    StreamEnable(bool),
}

impl OiCommand {
    /// Drive Direct from wheel speeds in m/s, rounded to mm/s and clamped to
    /// ±500 mm/s (NaN becomes 0).
    pub fn drive_direct(left_mps: f64, right_mps: f64) -> OiCommand {
        OiCommand::DriveDirect {
            right: mm_s(right_mps),
            left: mm_s(left_mps),
        }
    }
}

fn mm_s(v: f64) -> i16 {
    let mm = (v * 1000.0).round();
    if mm.is_nan() {
        0
    } else {
        mm.clamp(-(MAX_WHEEL_MM_S as f64), MAX_WHEEL_MM_S as f64) as i16
    }
}

/// Encoded command bytes.
pub type OiBytes = HVec<u8, 24>;

/// Encodes one command.
pub fn encode(c: &OiCommand) -> OiBytes {
    let mut o = OiBytes::new();
    // Capacity 24 exceeds the longest command (2 + 16 ids): pushes cannot fail.
    let two = |o: &mut OiBytes, opc: u8, a: i16, b: i16| {
        let _ = o.push(opc);
        let _ = o.extend_from_slice(&a.to_be_bytes());
        let _ = o.extend_from_slice(&b.to_be_bytes());
    };
    match c {
        OiCommand::Start => {
            let _ = o.push(op::START);
        }
        OiCommand::Baud(code) => {
            let _ = o.extend_from_slice(&[op::BAUD, *code]);
        }
        OiCommand::Safe => {
            let _ = o.push(op::SAFE);
        }
        OiCommand::Full => {
            let _ = o.push(op::FULL);
        }
        OiCommand::Stop => {
            let _ = o.push(op::STOP);
        }
        OiCommand::Reset => {
            let _ = o.push(op::RESET);
        }
        OiCommand::Drive { velocity, radius } => two(&mut o, op::DRIVE, *velocity, *radius),
        OiCommand::DriveDirect { right, left } => two(&mut o, op::DRIVE_DIRECT, *right, *left),
        OiCommand::DrivePwm { right, left } => two(&mut o, op::DRIVE_PWM, *right, *left),
        OiCommand::Stream(ids) | OiCommand::QueryList(ids) => {
            let opc = if matches!(c, OiCommand::Stream(_)) {
                op::STREAM
            } else {
                op::QUERY_LIST
            };
            let _ = o.push(opc);
            let _ = o.push(ids.len() as u8);
            let _ = o.extend_from_slice(ids);
        }
        OiCommand::Sensors(id) => {
            let _ = o.extend_from_slice(&[op::SENSORS, *id]);
        }
        OiCommand::StreamEnable(on) => {
            let _ = o.extend_from_slice(&[op::PAUSE_RESUME, u8::from(*on)]);
        }
    }
    o
}

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
    pub fn bumps(&self) -> Option<crate::motor::Sides> {
        self.bumps_drops.map(|b| crate::motor::Sides {
            right: b & 0x01 != 0,
            left: b & 0x02 != 0,
        })
    }

    /// Wheel-drop bits as sides (right = bit 2, left = bit 3).
    pub fn wheel_drops(&self) -> Option<crate::motor::Sides> {
        self.bumps_drops.map(|b| crate::motor::Sides {
            right: b & 0x04 != 0,
            left: b & 0x08 != 0,
        })
    }
}

/// Why a stream frame was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StreamError {
    /// The byte sum of the frame is not 0 mod 256.
    #[error("sensor stream checksum mismatch (sum 0x{0:02X}, expected 0)")]
    Checksum(u8),
    /// A packet id that is unknown or a group id.
    #[error("sensor stream frame names unknown packet id {0}")]
    UnknownPacket(u8),
    /// The packets do not fill the frame's length exactly.
    #[error("sensor stream frame length {0} does not match its packets")]
    BadLength(u8),
}

/// Longest stream payload accepted (bytes between the length and the checksum).
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

    /// Expected payload length of the requested packet `ids`, if every id is a
    /// known single packet and the frame fits.
    pub fn payload_len(ids: &[u8]) -> Option<u8> {
        let mut n = 0usize;
        for &id in ids {
            n += 1 + packet_size(id)?;
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

/// Parses one complete frame `19, n, payload, checksum`.
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
        let size = packet_size(id).ok_or(StreamError::UnknownPacket(id))?;
        let Some(d) = payload.get(i + 1..i + 1 + size) else {
            return Err(StreamError::BadLength(n));
        };
        let word = || u16::from_be_bytes([d[0], d[1]]);
        match id {
            pkt::BUMPS_WHEEL_DROPS => f.bumps_drops = Some(d[0]),
            pkt::VOLTAGE => f.voltage_mv = Some(word()),
            pkt::OI_MODE => f.oi_mode = Some(d[0]),
            pkt::LEFT_ENCODER => f.left_encoder = Some(word()),
            pkt::RIGHT_ENCODER => f.right_encoder = Some(word()),
            _ => {}
        }
        i += 1 + size;
    }
    Ok(f)
}

/// The robot-side values a stream frame reports (device side).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorState {
    /// Packet 7 bit field.
    pub bumps_drops: u8,
    /// Packet 22 (mV).
    pub voltage_mv: u16,
    /// Packet 35 mode byte.
    pub oi_mode: u8,
    /// Packet 43.
    pub left_encoder: u16,
    /// Packet 44.
    pub right_encoder: u16,
}

/// A stream frame on the wire.
pub type FrameBytes = HVec<u8, { MAX_PAYLOAD + 3 }>;

/// Encodes a stream frame with packets `ids` from `s` (device side). Ids this
/// codec does not know are sent as zeros of their size; unknown or group ids
/// are left out.
pub fn encode_stream_frame(ids: &[u8], s: &SensorState) -> FrameBytes {
    let mut o = FrameBytes::new();
    let _ = o.push(STREAM_HEADER);
    let _ = o.push(0);
    for &id in ids {
        let Some(size) = packet_size(id) else {
            continue;
        };
        if o.len() + 1 + size + 1 > o.capacity() {
            break;
        }
        let _ = o.push(id);
        match id {
            pkt::BUMPS_WHEEL_DROPS => {
                let _ = o.push(s.bumps_drops);
            }
            pkt::VOLTAGE => {
                let _ = o.extend_from_slice(&s.voltage_mv.to_be_bytes());
            }
            pkt::OI_MODE => {
                let _ = o.push(s.oi_mode);
            }
            pkt::LEFT_ENCODER => {
                let _ = o.extend_from_slice(&s.left_encoder.to_be_bytes());
            }
            pkt::RIGHT_ENCODER => {
                let _ = o.extend_from_slice(&s.right_encoder.to_be_bytes());
            }
            _ => {
                for _ in 0..size {
                    let _ = o.push(0);
                }
            }
        }
    }
    o[1] = (o.len() - 2) as u8;
    let sum = o.iter().fold(0u8, |a, &b| a.wrapping_add(b));
    let _ = o.push(0u8.wrapping_sub(sum));
    o
}

/// Device-side parser of host commands. Opcodes it does not know are skipped
/// (a real robot ignores them too) and counted.
#[derive(Clone, Debug, Default)]
pub struct OiDecoder {
    buf: HVec<u8, 24>,
    need: usize,
    /// Bytes skipped because they were no known opcode.
    pub skipped: u64,
}

fn fixed_len(opc: u8) -> Option<usize> {
    match opc {
        op::START | op::SAFE | op::FULL | op::STOP | op::RESET => Some(0),
        op::BAUD | op::SENSORS | op::PAUSE_RESUME => Some(1),
        op::DRIVE | op::DRIVE_DIRECT | op::DRIVE_PWM => Some(4),
        _ => None,
    }
}

impl OiDecoder {
    /// A decoder waiting for an opcode.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds one byte; returns a command when one is complete.
    pub fn push(&mut self, b: u8) -> Option<OiCommand> {
        if self.buf.is_empty() {
            if let Some(n) = fixed_len(b) {
                self.need = 1 + n;
            } else if b == op::STREAM || b == op::QUERY_LIST {
                self.need = 2;
            } else {
                self.skipped += 1;
                return None;
            }
        }
        let _ = self.buf.push(b);
        let opc = self.buf[0];
        if (opc == op::STREAM || opc == op::QUERY_LIST) && self.buf.len() == 2 {
            let n = b as usize;
            if n > MAX_STREAM_IDS {
                self.skipped += 2;
                self.buf.clear();
                return None;
            }
            self.need = 2 + n;
        }
        if self.buf.len() < self.need {
            return None;
        }
        let d = &self.buf[1..];
        let w = |i: usize| i16::from_be_bytes([d[i], d[i + 1]]);
        let c = match opc {
            op::START => OiCommand::Start,
            op::SAFE => OiCommand::Safe,
            op::FULL => OiCommand::Full,
            op::STOP => OiCommand::Stop,
            op::RESET => OiCommand::Reset,
            op::BAUD => OiCommand::Baud(d[0]),
            op::SENSORS => OiCommand::Sensors(d[0]),
            op::PAUSE_RESUME => OiCommand::StreamEnable(d[0] != 0),
            op::DRIVE => OiCommand::Drive {
                velocity: w(0),
                radius: w(2),
            },
            op::DRIVE_DIRECT => OiCommand::DriveDirect {
                right: w(0),
                left: w(2),
            },
            op::DRIVE_PWM => OiCommand::DrivePwm {
                right: w(0),
                left: w(2),
            },
            _ => {
                let mut ids = HVec::new();
                let _ = ids.extend_from_slice(&d[1..]);
                if opc == op::STREAM {
                    OiCommand::Stream(ids)
                } else {
                    OiCommand::QueryList(ids)
                }
            }
        };
        self.buf.clear();
        Some(c)
    }
}

#[cfg(test)]
mod tests;
