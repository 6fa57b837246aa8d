//! RoboClaw packet serial, sans-IO: bytes in, typed messages out, both ways.
//!
//! As Basicmicro's RoboClaw user manual ("Packet Serial") lays it out:
//!
//! - a **write** is `[address][command][data…][CRC16 hi][CRC16 lo]`, the CRC
//!   (CRC-16/XMODEM) over address, command and data; a valid write is
//!   answered with the single byte `0xFF`, an invalid one with nothing;
//! - a **read** is `[address][command]` and nothing else; the controller
//!   answers `[data…][CRC16 hi][CRC16 lo]`, the CRC over the *sent* address
//!   and command followed by the data;
//! - a packet whose bytes arrive more than 10 ms apart is thrown away by the
//!   controller ([`PACKET_GAP`]); multi-byte values are big-endian.
//!
//! The host side is [`encode_command`] plus a [`ReplyDecoder`] per request;
//! the device side (used by the emulator) is a streaming [`CommandDecoder`]
//! plus [`encode_reply`]. Nothing here allocates or panics on any input.

use heapless::Vec as HVec;

use crate::crc16::Crc16;

/// Lowest packet-serial address (the factory default).
pub const ADDRESS_MIN: u8 = 0x80;
/// Highest packet-serial address.
pub const ADDRESS_MAX: u8 = 0x87;
/// The acknowledge byte a write command is answered with.
pub const ACK: u8 = 0xFF;
/// Longest firmware version string (bytes, terminator included): the
/// manual's "up to 48 bytes".
pub const VERSION_MAX: usize = 48;
/// Inter-byte gap (s) after which the controller discards a partial packet
/// (the manual's "Packet Timeout", 10 ms).
pub const PACKET_GAP: f64 = 0.010;
/// Largest duty magnitude the duty commands take (±100 %).
pub const DUTY_MAX: i16 = 32767;

/// Command numbers (RoboClaw user manual, packet serial chapters).
pub mod cmd {
    /// Set serial timeout, 1 data byte in 100 ms units.
    pub const SET_SERIAL_TIMEOUT: u8 = 14;
    /// Read the serial timeout (100 ms units).
    pub const READ_SERIAL_TIMEOUT: u8 = 15;
    /// Read the M1 encoder counter and its status byte.
    pub const READ_ENC_M1: u8 = 16;
    /// Read the M2 encoder counter and its status byte.
    pub const READ_ENC_M2: u8 = 17;
    /// Read the M1 encoder speed (counts/s) and its direction byte.
    pub const READ_SPEED_M1: u8 = 18;
    /// Read the M2 encoder speed (counts/s) and its direction byte.
    pub const READ_SPEED_M2: u8 = 19;
    /// Reset both quadrature encoder counters to zero.
    pub const RESET_ENCODERS: u8 = 20;
    /// Read the firmware version string.
    pub const READ_VERSION: u8 = 21;
    /// Set the M1 encoder counter.
    pub const SET_ENC_M1: u8 = 22;
    /// Set the M2 encoder counter.
    pub const SET_ENC_M2: u8 = 23;
    /// Read the main battery voltage (0.1 V units).
    pub const READ_MAIN_BATTERY: u8 = 24;
    /// Read the logic battery voltage (0.1 V units).
    pub const READ_LOGIC_BATTERY: u8 = 25;
    /// Set M1's velocity PID constants and QPPS.
    pub const SET_PID_M1: u8 = 28;
    /// Set M2's velocity PID constants and QPPS.
    pub const SET_PID_M2: u8 = 29;
    /// Read M1's instantaneous speed (counts/s over the last 1/300 s).
    pub const READ_ISPEED_M1: u8 = 30;
    /// Read M2's instantaneous speed.
    pub const READ_ISPEED_M2: u8 = 31;
    /// Drive M1 with a signed duty.
    pub const DUTY_M1: u8 = 32;
    /// Drive M2 with a signed duty.
    pub const DUTY_M2: u8 = 33;
    /// Drive M1 and M2 with signed duties.
    pub const DUTY_M1M2: u8 = 34;
    /// Drive M1 at a signed speed (counts/s).
    pub const SPEED_M1: u8 = 35;
    /// Drive M2 at a signed speed (counts/s).
    pub const SPEED_M2: u8 = 36;
    /// Drive M1 and M2 with signed speeds (encoder counts per second).
    pub const DRIVE_SPEEDS: u8 = 37;
    /// M1 speed with an acceleration.
    pub const SPEED_ACCEL_M1: u8 = 38;
    /// M2 speed with an acceleration.
    pub const SPEED_ACCEL_M2: u8 = 39;
    /// Drive M1 and M2 with signed speeds and one acceleration (counts/s²).
    pub const DRIVE_SPEEDS_ACCEL: u8 = 40;
    /// M1 speed for a distance.
    pub const SPEED_DIST_M1: u8 = 41;
    /// M2 speed for a distance.
    pub const SPEED_DIST_M2: u8 = 42;
    /// M1 and M2 speeds for distances.
    pub const SPEED_DIST_M1M2: u8 = 43;
    /// M1 speed with acceleration for a distance.
    pub const SPEED_ACCEL_DIST_M1: u8 = 44;
    /// M2 speed with acceleration for a distance.
    pub const SPEED_ACCEL_DIST_M2: u8 = 45;
    /// M1 and M2 speeds with one acceleration for distances.
    pub const SPEED_ACCEL_DIST_M1M2: u8 = 46;
    /// Read the distance-command buffer of each motor.
    pub const READ_BUFFERS: u8 = 47;
    /// Read the PWM duty of each motor.
    pub const READ_PWMS: u8 = 48;
    /// Read the current of each motor (10 mA units).
    pub const READ_CURRENTS: u8 = 49;
    /// M1 and M2 speeds with an acceleration each.
    pub const SPEED_ACCEL_M1M2_2: u8 = 50;
    /// M1 and M2 speeds with an acceleration each, for distances.
    pub const SPEED_ACCEL_DIST_M1M2_2: u8 = 51;
    /// M1 duty with an acceleration.
    pub const DUTY_ACCEL_M1: u8 = 52;
    /// M2 duty with an acceleration.
    pub const DUTY_ACCEL_M2: u8 = 53;
    /// M1 and M2 duties with an acceleration each.
    pub const DUTY_ACCEL_M1M2: u8 = 54;
    /// Read M1's velocity PID constants and QPPS.
    pub const READ_PID_M1: u8 = 55;
    /// Read M2's velocity PID constants and QPPS.
    pub const READ_PID_M2: u8 = 56;
    /// Read the whole status record (Basicmicro's `GetStatus`).
    pub const READ_STATUS_RECORD: u8 = 73;
    /// Read both encoder counters in one reply.
    pub const READ_ENCODERS: u8 = 78;
    /// Read both instantaneous speeds.
    pub const READ_ISPEEDS: u8 = 79;
    /// Read the board temperature (0.1 °C).
    pub const READ_TEMP: u8 = 82;
    /// Read the second board temperature (0.1 °C).
    pub const READ_TEMP2: u8 = 83;
    /// Read the status (error/warning) word: the manual's "Read Status".
    pub const READ_STATUS: u8 = 90;
    /// Read both encoder modes.
    pub const READ_ENCODER_MODES: u8 = 91;
    /// Read both average speeds (counts/s over the last second).
    pub const READ_SPEEDS: u8 = 108;
}

/// Status word bit: the E-Stop input is active (on this robot the bumper
/// switch is wired to it).
pub const STATUS_ESTOP: u32 = 0x0000_0001;
/// Status word bit: main battery voltage low warning.
pub const STATUS_MAIN_LOW_WARNING: u32 = 0x0008_0000;
/// Buffer status: no distance command buffered or running.
pub const BUFFER_EMPTY: u8 = 0x80;
/// Length (bytes) of the status record of command 73.
pub const STATUS_RECORD_LEN: usize = 56;

/// Which motor channel a single-motor command addresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motor {
    /// Motor 1.
    M1,
    /// Motor 2.
    M2,
}

impl Motor {
    /// 0 for M1, 1 for M2.
    pub fn index(self) -> usize {
        match self {
            Motor::M1 => 0,
            Motor::M2 => 1,
        }
    }

    fn pick(self, m1: u8, m2: u8) -> u8 {
        match self {
            Motor::M1 => m1,
            Motor::M2 => m2,
        }
    }
}

/// Velocity PID constants as the controller stores them (fixed point,
/// 65536 = 1.0) and the motor's top speed (QPPS, counts/s).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VelocityPid {
    /// Proportional constant.
    pub p: u32,
    /// Integral constant.
    pub i: u32,
    /// Derivative constant.
    pub d: u32,
    /// Counts per second at full duty.
    pub qpps: u32,
}

/// A distance move: how far (encoder counts) and whether it waits in the
/// motor's buffer behind earlier moves (`buffered`) or replaces them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Distance {
    /// Counts to travel.
    pub counts: u32,
    /// The manual's buffer argument: 0 queues the move behind earlier ones
    /// (`true` here); 1 stops the running move and clears the buffer.
    pub buffered: bool,
}

/// The acceleration of a two-motor speed command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accel {
    /// None given: the PID's full authority.
    None,
    /// One acceleration for both motors (counts/s²).
    Both(u32),
    /// One acceleration per motor (M1, M2).
    Each(u32, u32),
}

/// A query: a read command, sent as `[address, command]` alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// 15: the serial timeout.
    SerialTimeout,
    /// 16/17: one encoder counter and its status byte.
    Encoder(Motor),
    /// 18/19: one encoder speed and its direction byte.
    Speed(Motor),
    /// 21: the firmware version string.
    Version,
    /// 24: main battery voltage.
    MainBattery,
    /// 25: logic battery voltage.
    LogicBattery,
    /// 30/31: one instantaneous speed and its direction byte.
    InstSpeed(Motor),
    /// 47: both distance buffers.
    Buffers,
    /// 48: both PWM duties.
    Pwms,
    /// 49: both motor currents.
    Currents,
    /// 55/56: one motor's velocity PID.
    VelocityPid(Motor),
    /// 73: the whole status record.
    StatusRecord,
    /// 78: both encoder counters.
    Encoders,
    /// 79: both instantaneous speeds.
    InstSpeeds,
    /// 82: board temperature.
    Temperature,
    /// 83: second board temperature.
    Temperature2,
    /// 90: the status word.
    Status,
    /// 91: both encoder modes.
    EncoderModes,
    /// 108: both average speeds.
    Speeds,
}

/// The data layout of a reply, before its CRC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// One byte.
    U8,
    /// One 16-bit word.
    U16,
    /// One 32-bit word.
    U32,
    /// A 32-bit value and a status byte.
    CountStatus,
    /// Two bytes, M1 then M2.
    Pair8,
    /// Two 16-bit words, M1 then M2.
    Pair16,
    /// Two 32-bit words, M1 then M2.
    Pair32,
    /// Four 32-bit words.
    Quad32,
    /// The 56-byte status record of command 73.
    Record,
    /// Text ending in NUL (the version).
    Text,
}

impl Layout {
    /// Data bytes before the CRC (`None` for text, whose end is its NUL).
    pub fn data_len(self) -> Option<usize> {
        Some(match self {
            Layout::U8 => 1,
            Layout::U16 | Layout::Pair8 => 2,
            Layout::U32 | Layout::Pair16 => 4,
            Layout::CountStatus => 5,
            Layout::Pair32 => 8,
            Layout::Quad32 => 16,
            Layout::Record => STATUS_RECORD_LEN,
            Layout::Text => return None,
        })
    }
}

/// Every query with its command number and reply layout.
const QUERIES: [(Query, u8, Layout); 23] = [
    (Query::SerialTimeout, cmd::READ_SERIAL_TIMEOUT, Layout::U8),
    (
        Query::Encoder(Motor::M1),
        cmd::READ_ENC_M1,
        Layout::CountStatus,
    ),
    (
        Query::Encoder(Motor::M2),
        cmd::READ_ENC_M2,
        Layout::CountStatus,
    ),
    (
        Query::Speed(Motor::M1),
        cmd::READ_SPEED_M1,
        Layout::CountStatus,
    ),
    (
        Query::Speed(Motor::M2),
        cmd::READ_SPEED_M2,
        Layout::CountStatus,
    ),
    (Query::Version, cmd::READ_VERSION, Layout::Text),
    (Query::MainBattery, cmd::READ_MAIN_BATTERY, Layout::U16),
    (Query::LogicBattery, cmd::READ_LOGIC_BATTERY, Layout::U16),
    (
        Query::InstSpeed(Motor::M1),
        cmd::READ_ISPEED_M1,
        Layout::CountStatus,
    ),
    (
        Query::InstSpeed(Motor::M2),
        cmd::READ_ISPEED_M2,
        Layout::CountStatus,
    ),
    (Query::Buffers, cmd::READ_BUFFERS, Layout::Pair8),
    (Query::Pwms, cmd::READ_PWMS, Layout::Pair16),
    (Query::Currents, cmd::READ_CURRENTS, Layout::Pair16),
    (
        Query::VelocityPid(Motor::M1),
        cmd::READ_PID_M1,
        Layout::Quad32,
    ),
    (
        Query::VelocityPid(Motor::M2),
        cmd::READ_PID_M2,
        Layout::Quad32,
    ),
    (Query::StatusRecord, cmd::READ_STATUS_RECORD, Layout::Record),
    (Query::Encoders, cmd::READ_ENCODERS, Layout::Pair32),
    (Query::InstSpeeds, cmd::READ_ISPEEDS, Layout::Pair32),
    (Query::Temperature, cmd::READ_TEMP, Layout::U16),
    (Query::Temperature2, cmd::READ_TEMP2, Layout::U16),
    (Query::Status, cmd::READ_STATUS, Layout::U32),
    (Query::EncoderModes, cmd::READ_ENCODER_MODES, Layout::Pair8),
    (Query::Speeds, cmd::READ_SPEEDS, Layout::Pair32),
];

impl Query {
    /// The command number on the wire.
    pub fn code(self) -> u8 {
        QUERIES.iter().find(|q| q.0 == self).map_or(0, |q| q.1)
    }

    /// The query with command number `code`, if it is one.
    pub fn from_code(code: u8) -> Option<Query> {
        QUERIES.iter().find(|q| q.1 == code).map(|q| q.0)
    }

    /// The layout of the reply.
    pub fn layout(self) -> Layout {
        QUERIES
            .iter()
            .find(|q| q.0 == self)
            .map_or(Layout::U8, |q| q.2)
    }
}

/// A host-to-controller command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// 14: stop both motors if no valid packet arrives within `tenths` ×
    /// 100 ms (0 disables the timeout).
    SetSerialTimeout {
        /// Timeout in 100 ms units.
        tenths: u8,
    },
    /// 20: zero both encoder counters.
    ResetEncoders,
    /// 22/23: set one encoder counter.
    SetEncoder {
        /// Which counter.
        motor: Motor,
        /// The new count.
        count: u32,
    },
    /// 28/29: set one motor's velocity PID and QPPS.
    SetVelocityPid {
        /// Which motor.
        motor: Motor,
        /// Constants and top speed.
        pid: VelocityPid,
    },
    /// 32/33 (no acceleration) and 52/53: one motor's signed duty.
    Duty {
        /// Which motor.
        motor: Motor,
        /// −32767..=32767 for −100..=100 %.
        duty: i16,
        /// Duty units per second (52/53), or none (32/33).
        accel: Option<u32>,
    },
    /// 34 (no acceleration) and 54: both motors' duties.
    Duties {
        /// Motor 1 duty.
        m1: i16,
        /// Motor 2 duty.
        m2: i16,
        /// Accelerations (M1, M2) for 54, none for 34.
        accel: Option<(u32, u32)>,
    },
    /// 35/36, 38/39, 41/42 and 44/45: one motor's signed speed
    /// (counts/s), with an acceleration and/or a distance.
    Speed {
        /// Which motor.
        motor: Motor,
        /// Counts per second.
        speed: i32,
        /// Counts/s² (38/39, 44/45).
        accel: Option<u32>,
        /// A distance move (41/42, 44/45).
        distance: Option<Distance>,
    },
    /// 37, 40, 50 (no distance) and 43, 46, 51 (with distances): both
    /// motors' signed speeds.
    Speeds {
        /// Motor 1 counts/s (motor 1 is the left wheel here by default).
        m1: i32,
        /// Motor 2 counts/s.
        m2: i32,
        /// The acceleration(s).
        accel: Accel,
        /// Distances (M1, M2 counts) and the buffer flag.
        distance: Option<(u32, u32, bool)>,
    },
    /// A read command.
    Query(Query),
}

impl Command {
    /// Velocity set-points under the onboard PID (command 37).
    pub const fn speeds(m1: i32, m2: i32) -> Self {
        Command::Speeds {
            m1,
            m2,
            accel: Accel::None,
            distance: None,
        }
    }

    /// Velocity set-points reached with one ramp (command 40).
    pub const fn speeds_accel(accel: u32, m1: i32, m2: i32) -> Self {
        Command::Speeds {
            m1,
            m2,
            accel: Accel::Both(accel),
            distance: None,
        }
    }

    /// The command number on the wire.
    pub fn code(&self) -> u8 {
        match *self {
            Command::SetSerialTimeout { .. } => cmd::SET_SERIAL_TIMEOUT,
            Command::ResetEncoders => cmd::RESET_ENCODERS,
            Command::SetEncoder { motor, .. } => motor.pick(cmd::SET_ENC_M1, cmd::SET_ENC_M2),
            Command::SetVelocityPid { motor, .. } => motor.pick(cmd::SET_PID_M1, cmd::SET_PID_M2),
            Command::Duty { motor, accel, .. } => match accel {
                None => motor.pick(cmd::DUTY_M1, cmd::DUTY_M2),
                Some(_) => motor.pick(cmd::DUTY_ACCEL_M1, cmd::DUTY_ACCEL_M2),
            },
            Command::Duties { accel: None, .. } => cmd::DUTY_M1M2,
            Command::Duties { accel: Some(_), .. } => cmd::DUTY_ACCEL_M1M2,
            Command::Speed {
                motor,
                accel,
                distance,
                ..
            } => match (accel, distance) {
                (None, None) => motor.pick(cmd::SPEED_M1, cmd::SPEED_M2),
                (Some(_), None) => motor.pick(cmd::SPEED_ACCEL_M1, cmd::SPEED_ACCEL_M2),
                (None, Some(_)) => motor.pick(cmd::SPEED_DIST_M1, cmd::SPEED_DIST_M2),
                (Some(_), Some(_)) => {
                    motor.pick(cmd::SPEED_ACCEL_DIST_M1, cmd::SPEED_ACCEL_DIST_M2)
                }
            },
            Command::Speeds {
                accel, distance, ..
            } => match (accel, distance.is_some()) {
                (Accel::None, false) => cmd::DRIVE_SPEEDS,
                (Accel::Both(_), false) => cmd::DRIVE_SPEEDS_ACCEL,
                (Accel::Each(..), false) => cmd::SPEED_ACCEL_M1M2_2,
                (Accel::None, true) => cmd::SPEED_DIST_M1M2,
                (Accel::Both(_), true) => cmd::SPEED_ACCEL_DIST_M1M2,
                (Accel::Each(..), true) => cmd::SPEED_ACCEL_DIST_M1M2_2,
            },
            Command::Query(q) => q.code(),
        }
    }

    /// Whether the controller answers with the bare ACK byte.
    pub fn is_write(&self) -> bool {
        !matches!(self, Command::Query(_))
    }
}

/// Number of data bytes that follow write command `code` in a host packet
/// (before its CRC), or `None` for a read or an unknown command.
pub fn write_len(code: u8) -> Option<usize> {
    Some(match code {
        cmd::RESET_ENCODERS => 0,
        cmd::SET_SERIAL_TIMEOUT => 1,
        cmd::DUTY_M1 | cmd::DUTY_M2 => 2,
        cmd::SET_ENC_M1 | cmd::SET_ENC_M2 | cmd::SPEED_M1 | cmd::SPEED_M2 | cmd::DUTY_M1M2 => 4,
        cmd::DUTY_ACCEL_M1 | cmd::DUTY_ACCEL_M2 => 6,
        cmd::DRIVE_SPEEDS | cmd::SPEED_ACCEL_M1 | cmd::SPEED_ACCEL_M2 => 8,
        cmd::SPEED_DIST_M1 | cmd::SPEED_DIST_M2 => 9,
        cmd::DRIVE_SPEEDS_ACCEL | cmd::DUTY_ACCEL_M1M2 => 12,
        cmd::SPEED_ACCEL_DIST_M1 | cmd::SPEED_ACCEL_DIST_M2 => 13,
        cmd::SET_PID_M1 | cmd::SET_PID_M2 | cmd::SPEED_ACCEL_M1M2_2 => 16,
        cmd::SPEED_DIST_M1M2 => 17,
        cmd::SPEED_ACCEL_DIST_M1M2 => 21,
        cmd::SPEED_ACCEL_DIST_M1M2_2 => 25,
        _ => return None,
    })
}

/// A host packet: at most address, command, 25 data bytes and the CRC.
pub type Packet = HVec<u8, 32>;

/// Appends big-endian values to a packet (capacity is checked by the
/// longest layout: pushes never fail).
struct Put<'a>(&'a mut Packet);

impl Put<'_> {
    fn u8(&mut self, v: u8) -> &mut Self {
        let _ = self.0.push(v);
        self
    }
    fn u16(&mut self, v: u16) -> &mut Self {
        let _ = self.0.extend_from_slice(&v.to_be_bytes());
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        let _ = self.0.extend_from_slice(&v.to_be_bytes());
        self
    }
}

/// Encodes `command` for the controller at `address`: a write with its CRC,
/// a read as address and command alone.
pub fn encode_command(address: u8, command: &Command) -> Packet {
    let mut p = Packet::new();
    let _ = p.push(address);
    let _ = p.push(command.code());
    let mut w = Put(&mut p);
    match *command {
        Command::Query(_) => return p,
        Command::ResetEncoders => {}
        Command::SetSerialTimeout { tenths } => {
            w.u8(tenths);
        }
        Command::SetEncoder { count, .. } => {
            w.u32(count);
        }
        Command::SetVelocityPid { pid, .. } => {
            // The manual's order for 28/29: D, P, I, QPPS.
            w.u32(pid.d).u32(pid.p).u32(pid.i).u32(pid.qpps);
        }
        Command::Duty { duty, accel, .. } => {
            w.u16(duty as u16);
            if let Some(a) = accel {
                w.u32(a);
            }
        }
        Command::Duties { m1, m2, accel } => match accel {
            None => {
                w.u16(m1 as u16).u16(m2 as u16);
            }
            Some((a1, a2)) => {
                w.u16(m1 as u16).u32(a1).u16(m2 as u16).u32(a2);
            }
        },
        Command::Speed {
            speed,
            accel,
            distance,
            ..
        } => {
            if let Some(a) = accel {
                w.u32(a);
            }
            w.u32(speed as u32);
            if let Some(d) = distance {
                w.u32(d.counts).u8(u8::from(!d.buffered));
            }
        }
        Command::Speeds {
            m1,
            m2,
            accel,
            distance,
        } => put_speeds(&mut w, m1, m2, accel, distance),
    }
    let mut c = Crc16::new();
    c.extend(&p);
    let _ = p.extend_from_slice(&c.value().to_be_bytes());
    p
}

/// The data of the two-motor speed commands, in the manual's order.
fn put_speeds(w: &mut Put<'_>, m1: i32, m2: i32, accel: Accel, distance: Option<(u32, u32, bool)>) {
    let (s1, s2) = (m1 as u32, m2 as u32);
    match (accel, distance) {
        (Accel::None, None) => {
            w.u32(s1).u32(s2);
        }
        (Accel::Both(a), None) => {
            w.u32(a).u32(s1).u32(s2);
        }
        (Accel::Each(a1, a2), None) => {
            w.u32(a1).u32(s1).u32(a2).u32(s2);
        }
        (Accel::None, Some((d1, d2, b))) => {
            w.u32(s1).u32(d1).u32(s2).u32(d2).u8(u8::from(!b));
        }
        (Accel::Both(a), Some((d1, d2, b))) => {
            w.u32(a).u32(s1).u32(d1).u32(s2).u32(d2).u8(u8::from(!b));
        }
        (Accel::Each(a1, a2), Some((d1, d2, b))) => {
            w.u32(a1)
                .u32(s1)
                .u32(d1)
                .u32(a2)
                .u32(s2)
                .u32(d2)
                .u8(u8::from(!b));
        }
    }
}

/// A controller-to-host reply, by layout (see [`Query::layout`] for which
/// query gets which).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// The write command was accepted.
    Ack,
    /// Firmware version text (without its LF and NUL).
    Version(HVec<u8, VERSION_MAX>),
    /// One byte (15: timeout in 100 ms units).
    U8(u8),
    /// One word (24/25: volts × 10; 82/83: °C × 10).
    U16(u16),
    /// One 32-bit word (90: the status word, see [`STATUS_ESTOP`]).
    U32(u32),
    /// A 32-bit value and a status byte (16/17: counter and its status;
    /// 18/19, 30/31: speed and direction, 1 = backwards).
    CountStatus {
        /// The counter or speed (speeds are two's complement).
        value: u32,
        /// The status or direction byte.
        status: u8,
    },
    /// Two bytes (47: buffers; 91: encoder modes).
    Pair8(u8, u8),
    /// Two words (48: PWMs; 49: currents in 10 mA, both signed).
    Pair16(u16, u16),
    /// Two 32-bit words (78: counters; 79, 108: speeds, signed).
    Pair32(u32, u32),
    /// Four 32-bit words (55/56: P, I, D, QPPS: the manual's read order).
    Quad32([u32; 4]),
    /// The 56-byte status record of command 73, as sent.
    Record([u8; STATUS_RECORD_LEN]),
}

/// Why a reply was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// A write command was answered with something other than 0xFF.
    #[error("expected the ACK byte 0xFF, got 0x{0:02X}")]
    NotAck(u8),
    /// The reply's CRC does not match its contents.
    #[error("reply CRC mismatch: computed 0x{computed:04X}, received 0x{received:04X}")]
    Crc {
        /// CRC computed over address, command and data.
        computed: u16,
        /// CRC in the reply.
        received: u16,
    },
    /// The version string has no terminator within its maximum length.
    #[error("version reply longer than {VERSION_MAX} bytes without a terminator")]
    TooLong,
}

/// Decodes the reply to one request, byte by byte. Create one per request
/// (or [`ReplyDecoder::restart`]); the CRC is seeded with the request's
/// address and command, as the controller computes it.
#[derive(Clone, Debug)]
pub struct ReplyDecoder {
    address: u8,
    code: u8,
    layout: Option<Layout>,
    buf: HVec<u8, 64>,
}

impl ReplyDecoder {
    /// A decoder for the reply to `command` sent to `address`.
    pub fn new(address: u8, command: &Command) -> Self {
        let layout = match command {
            Command::Query(q) => Some(q.layout()),
            _ => None,
        };
        Self {
            address,
            code: command.code(),
            layout,
            buf: HVec::new(),
        }
    }

    /// Forgets bytes received so far (after a timeout).
    pub fn restart(&mut self) {
        self.buf.clear();
    }

    /// Feeds one byte: `Ok(None)` while the reply is incomplete, `Ok(Some)` when
    /// it is complete and valid, `Err` when it is invalid (the decoder then
    /// starts over).
    pub fn push(&mut self, b: u8) -> Result<Option<Reply>, ReplyError> {
        let Some(layout) = self.layout else {
            return if b == ACK {
                Ok(Some(Reply::Ack))
            } else {
                Err(ReplyError::NotAck(b))
            };
        };
        if self.buf.push(b).is_err() {
            self.buf.clear();
            return Err(ReplyError::TooLong);
        }
        let data_len = match layout.data_len() {
            Some(n) => n,
            // Text ends with NUL (after an LF), followed by the CRC.
            None => match self.buf.iter().position(|&c| c == 0) {
                Some(nul) => nul + 1,
                None if self.buf.len() >= VERSION_MAX => {
                    self.buf.clear();
                    return Err(ReplyError::TooLong);
                }
                None => return Ok(None),
            },
        };
        if self.buf.len() < data_len + 2 {
            return Ok(None);
        }
        let r = self.finish(layout, data_len);
        self.buf.clear();
        r.map(Some)
    }

    /// Checks the CRC over the first `n` data bytes and builds the reply.
    fn finish(&self, layout: Layout, n: usize) -> Result<Reply, ReplyError> {
        let data = &self.buf[..n];
        let received = u16::from_be_bytes([self.buf[n], self.buf[n + 1]]);
        let mut c = Crc16::new();
        c.push(self.address);
        c.push(self.code);
        c.extend(data);
        if c.value() != received {
            return Err(ReplyError::Crc {
                computed: c.value(),
                received,
            });
        }
        Ok(parse_reply(layout, data))
    }
}

/// Reads big-endian values from a slice whose length was checked.
struct Get<'a>(&'a [u8]);

impl Get<'_> {
    fn u8(&mut self) -> u8 {
        let v = self.0.first().copied().unwrap_or(0);
        self.0 = self.0.get(1..).unwrap_or(&[]);
        v
    }
    fn u16(&mut self) -> u16 {
        u16::from_be_bytes([self.u8(), self.u8()])
    }
    fn u32(&mut self) -> u32 {
        u32::from_be_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
    fn i16(&mut self) -> i16 {
        self.u16() as i16
    }
    fn i32(&mut self) -> i32 {
        self.u32() as i32
    }
}

/// Builds a reply from its data bytes (length already checked).
fn parse_reply(layout: Layout, data: &[u8]) -> Reply {
    let mut g = Get(data);
    match layout {
        Layout::U8 => Reply::U8(g.u8()),
        Layout::U16 => Reply::U16(g.u16()),
        Layout::U32 => Reply::U32(g.u32()),
        Layout::CountStatus => Reply::CountStatus {
            value: g.u32(),
            status: g.u8(),
        },
        Layout::Pair8 => Reply::Pair8(g.u8(), g.u8()),
        Layout::Pair16 => Reply::Pair16(g.u16(), g.u16()),
        Layout::Pair32 => Reply::Pair32(g.u32(), g.u32()),
        Layout::Quad32 => Reply::Quad32([g.u32(), g.u32(), g.u32(), g.u32()]),
        Layout::Record => {
            let mut r = [0u8; STATUS_RECORD_LEN];
            let n = data.len().min(STATUS_RECORD_LEN);
            r[..n].copy_from_slice(&data[..n]);
            Reply::Record(r)
        }
        Layout::Text => {
            let end = data
                .iter()
                .position(|&c| c == b'\n' || c == 0)
                .unwrap_or(data.len());
            let mut v = HVec::new();
            let _ = v.extend_from_slice(&data[..end.min(VERSION_MAX)]);
            Reply::Version(v)
        }
    }
}

/// A reply as it goes on the wire: at most the status record and the CRC.
pub type ReplyBytes = HVec<u8, 64>;

/// Encodes the controller's answer `reply` to command `code` from `address`
/// (device side; the CRC covers address, command and data).
pub fn encode_reply(address: u8, code: u8, reply: &Reply) -> ReplyBytes {
    let mut out = ReplyBytes::new();
    let mut put = |b: &[u8]| {
        let _ = out.extend_from_slice(b);
    };
    match reply {
        Reply::Ack => {
            put(&[ACK]);
            return out;
        }
        Reply::Version(text) => {
            put(&text[..text.len().min(VERSION_MAX - 2)]);
            put(b"\n\0");
        }
        Reply::U8(v) => put(&[*v]),
        Reply::U16(v) => put(&v.to_be_bytes()),
        Reply::U32(v) => put(&v.to_be_bytes()),
        Reply::CountStatus { value, status } => {
            put(&value.to_be_bytes());
            put(&[*status]);
        }
        Reply::Pair8(a, b) => put(&[*a, *b]),
        Reply::Pair16(a, b) => {
            put(&a.to_be_bytes());
            put(&b.to_be_bytes());
        }
        Reply::Pair32(a, b) => {
            put(&a.to_be_bytes());
            put(&b.to_be_bytes());
        }
        Reply::Quad32(q) => q.iter().for_each(|v| put(&v.to_be_bytes())),
        Reply::Record(r) => put(r),
    }
    let mut c = Crc16::new();
    c.push(address);
    c.push(code);
    c.extend(&out);
    let _ = out.extend_from_slice(&c.value().to_be_bytes());
    out
}

/// Why the device side threw a packet away (a real controller stays silent).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The packet's CRC does not match.
    #[error("packet CRC mismatch: computed 0x{computed:04X}, received 0x{received:04X}")]
    Crc {
        /// CRC computed over the packet.
        computed: u16,
        /// CRC in the packet.
        received: u16,
    },
    /// A command number this controller does not implement.
    #[error("unknown command {0}")]
    UnknownCommand(u8),
    /// A valid packet whose values the manual does not allow (refused by a
    /// strict decoder only; see [`within_manual`]).
    #[error("command {0} with values outside the manual's ranges")]
    OutsideManual(u8),
}

/// Device-side streaming parser of host packets. Bytes that cannot start a
/// packet (not an address) are skipped and counted. A read completes with
/// its command byte; a write with its CRC.
#[derive(Clone, Debug, Default)]
pub struct CommandDecoder {
    buf: HVec<u8, 32>,
    need: usize,
    strict: bool,
    /// Bytes skipped while waiting for an address byte.
    pub skipped: u64,
}

impl CommandDecoder {
    /// A decoder waiting for an address byte.
    pub fn new() -> Self {
        Self::default()
    }

    /// A decoder that also refuses packets with values the manual does not
    /// allow ([`FrameError::OutsideManual`]).
    pub fn strict() -> Self {
        Self {
            strict: true,
            ..Self::default()
        }
    }

    /// Drops a partial packet (the controller does this after an inter-byte
    /// gap of [`PACKET_GAP`]); returns how many bytes it held.
    pub fn reset(&mut self) -> usize {
        let n = self.buf.len();
        self.buf.clear();
        self.need = 0;
        n
    }

    /// Feeds one byte; returns a complete packet's `(address, command)` or
    /// why it was rejected.
    pub fn push(&mut self, b: u8) -> Option<Result<(u8, Command), FrameError>> {
        if self.buf.is_empty() {
            if (ADDRESS_MIN..=ADDRESS_MAX).contains(&b) {
                let _ = self.buf.push(b);
            } else {
                self.skipped += 1;
            }
            return None;
        }
        if self.buf.len() == 1 {
            let addr = self.buf[0];
            if let Some(q) = Query::from_code(b) {
                self.reset();
                return Some(Ok((addr, Command::Query(q))));
            }
            let Some(n) = write_len(b) else {
                self.reset();
                return Some(Err(FrameError::UnknownCommand(b)));
            };
            let _ = self.buf.push(b);
            self.need = 2 + n + 2;
            return None;
        }
        let _ = self.buf.push(b);
        if self.buf.len() < self.need {
            return None;
        }
        let n = self.need;
        let received = u16::from_be_bytes([self.buf[n - 2], self.buf[n - 1]]);
        let mut c = Crc16::new();
        c.extend(&self.buf[..n - 2]);
        let result = if c.value() != received {
            Err(FrameError::Crc {
                computed: c.value(),
                received,
            })
        } else if self.strict && !within_manual(self.buf[1], &self.buf[2..n - 2]) {
            Err(FrameError::OutsideManual(self.buf[1]))
        } else {
            parse_write(self.buf[1], &self.buf[2..n - 2])
                .map(|c| (self.buf[0], c))
                .ok_or(FrameError::UnknownCommand(self.buf[1]))
        };
        self.reset();
        Some(result)
    }
}

/// Builds a write command from its number and data (length already checked
/// against [`write_len`]).
fn parse_write(code: u8, d: &[u8]) -> Option<Command> {
    let mut g = Get(d);
    let m = |c1: u8| if code == c1 { Motor::M1 } else { Motor::M2 };
    let dist = |counts: u32, flag: u8| Distance {
        counts,
        buffered: flag == 0,
    };
    Some(match code {
        cmd::SET_SERIAL_TIMEOUT => Command::SetSerialTimeout { tenths: g.u8() },
        cmd::RESET_ENCODERS => Command::ResetEncoders,
        cmd::SET_ENC_M1 | cmd::SET_ENC_M2 => Command::SetEncoder {
            motor: m(cmd::SET_ENC_M1),
            count: g.u32(),
        },
        cmd::SET_PID_M1 | cmd::SET_PID_M2 => {
            let (d, p, i, qpps) = (g.u32(), g.u32(), g.u32(), g.u32());
            Command::SetVelocityPid {
                motor: m(cmd::SET_PID_M1),
                pid: VelocityPid { p, i, d, qpps },
            }
        }
        cmd::DUTY_M1 | cmd::DUTY_M2 => Command::Duty {
            motor: m(cmd::DUTY_M1),
            duty: g.i16(),
            accel: None,
        },
        cmd::DUTY_ACCEL_M1 | cmd::DUTY_ACCEL_M2 => Command::Duty {
            motor: m(cmd::DUTY_ACCEL_M1),
            duty: g.i16(),
            accel: Some(g.u32()),
        },
        cmd::DUTY_M1M2 => Command::Duties {
            m1: g.i16(),
            m2: g.i16(),
            accel: None,
        },
        cmd::DUTY_ACCEL_M1M2 => {
            let (m1, a1, m2, a2) = (g.i16(), g.u32(), g.i16(), g.u32());
            Command::Duties {
                m1,
                m2,
                accel: Some((a1, a2)),
            }
        }
        cmd::SPEED_M1 | cmd::SPEED_M2 => Command::Speed {
            motor: m(cmd::SPEED_M1),
            speed: g.i32(),
            accel: None,
            distance: None,
        },
        cmd::SPEED_ACCEL_M1 | cmd::SPEED_ACCEL_M2 => {
            let (a, s) = (g.u32(), g.i32());
            Command::Speed {
                motor: m(cmd::SPEED_ACCEL_M1),
                speed: s,
                accel: Some(a),
                distance: None,
            }
        }
        cmd::SPEED_DIST_M1 | cmd::SPEED_DIST_M2 => {
            let (s, d, b) = (g.i32(), g.u32(), g.u8());
            Command::Speed {
                motor: m(cmd::SPEED_DIST_M1),
                speed: s,
                accel: None,
                distance: Some(dist(d, b)),
            }
        }
        cmd::SPEED_ACCEL_DIST_M1 | cmd::SPEED_ACCEL_DIST_M2 => {
            let (a, s, d, b) = (g.u32(), g.i32(), g.u32(), g.u8());
            Command::Speed {
                motor: m(cmd::SPEED_ACCEL_DIST_M1),
                speed: s,
                accel: Some(a),
                distance: Some(dist(d, b)),
            }
        }
        _ => return parse_speeds(code, &mut g),
    })
}

/// The two-motor speed commands (37, 40, 43, 46, 50, 51).
fn parse_speeds(code: u8, g: &mut Get<'_>) -> Option<Command> {
    let (m1, m2, accel, distance) = match code {
        cmd::DRIVE_SPEEDS => (g.i32(), g.i32(), Accel::None, None),
        cmd::DRIVE_SPEEDS_ACCEL => {
            let a = g.u32();
            (g.i32(), g.i32(), Accel::Both(a), None)
        }
        cmd::SPEED_ACCEL_M1M2_2 => {
            let (a1, s1, a2, s2) = (g.u32(), g.i32(), g.u32(), g.i32());
            (s1, s2, Accel::Each(a1, a2), None)
        }
        cmd::SPEED_DIST_M1M2 => {
            let (s1, d1, s2, d2, b) = (g.i32(), g.u32(), g.i32(), g.u32(), g.u8());
            (s1, s2, Accel::None, Some((d1, d2, b == 0)))
        }
        cmd::SPEED_ACCEL_DIST_M1M2 => {
            let a = g.u32();
            let (s1, d1, s2, d2, b) = (g.i32(), g.u32(), g.i32(), g.u32(), g.u8());
            (s1, s2, Accel::Both(a), Some((d1, d2, b == 0)))
        }
        cmd::SPEED_ACCEL_DIST_M1M2_2 => {
            let (a1, s1, d1) = (g.u32(), g.i32(), g.u32());
            let (a2, s2, d2, b) = (g.u32(), g.i32(), g.u32(), g.u8());
            (s1, s2, Accel::Each(a1, a2), Some((d1, d2, b == 0)))
        }
        _ => return None,
    };
    Some(Command::Speeds {
        m1,
        m2,
        accel,
        distance,
    })
}

/// Whether a write's raw data keeps to what the manual allows: duties within
/// ±32767 and the buffer argument 0 or 1. The controller's behaviour outside
/// these is not documented; a strict emulator refuses such packets.
pub fn within_manual(code: u8, data: &[u8]) -> bool {
    let duty_ok = |hi: u8, lo: u8| i16::from_be_bytes([hi, lo]) >= -DUTY_MAX;
    let last_is_flag = || data.last().is_some_and(|&b| b <= 1);
    match code {
        cmd::DUTY_M1 | cmd::DUTY_M2 | cmd::DUTY_ACCEL_M1 | cmd::DUTY_ACCEL_M2 => {
            data.len() >= 2 && duty_ok(data[0], data[1])
        }
        cmd::DUTY_M1M2 => data.len() >= 4 && duty_ok(data[0], data[1]) && duty_ok(data[2], data[3]),
        cmd::DUTY_ACCEL_M1M2 => {
            data.len() >= 8 && duty_ok(data[0], data[1]) && duty_ok(data[6], data[7])
        }
        cmd::SPEED_DIST_M1
        | cmd::SPEED_DIST_M2
        | cmd::SPEED_ACCEL_DIST_M1
        | cmd::SPEED_ACCEL_DIST_M2
        | cmd::SPEED_DIST_M1M2
        | cmd::SPEED_ACCEL_DIST_M1M2
        | cmd::SPEED_ACCEL_DIST_M1M2_2 => last_is_flag(),
        _ => true,
    }
}

#[cfg(test)]
mod tests;
