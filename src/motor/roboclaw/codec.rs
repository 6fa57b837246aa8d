//! RoboClaw packet serial, sans-IO: bytes in, typed messages out, both ways.
//!
//! A host packet is `[address 0x80..=0x87][command][data…][CRC16 hi][CRC16 lo]`
//! with CRC-16/XMODEM over address, command and data. Write commands are
//! answered with the single byte `0xFF`; read commands with their data and a
//! CRC computed over the *sent* address and command followed by the received
//! data. Multi-byte values are big-endian.
//!
//! The host side is [`encode_command`] plus a [`ReplyDecoder`] per request;
//! the device side (used by the emulator) is a streaming [`CommandDecoder`]
//! plus [`encode_reply`]. Nothing here allocates or panics on any input.

use heapless::Vec as HVec;

use crate::motor::crc16::Crc16;

/// Lowest packet-serial address (the factory default).
pub const ADDRESS_MIN: u8 = 0x80;
/// Highest packet-serial address.
pub const ADDRESS_MAX: u8 = 0x87;
/// The acknowledge byte a write command is answered with.
pub const ACK: u8 = 0xFF;
/// Longest firmware version string (bytes, without the LF/NUL terminator).
pub const VERSION_MAX: usize = 48;

/// Command numbers used here (RoboClaw user manual, packet serial chapters).
pub mod cmd {
    /// Set serial timeout, 1 data byte in 100 ms units.
    pub const SET_SERIAL_TIMEOUT: u8 = 14;
    /// Reset both quadrature encoder counters to zero.
    pub const RESET_ENCODERS: u8 = 20;
    /// Read the firmware version string.
    pub const READ_VERSION: u8 = 21;
    /// Read the main battery voltage (0.1 V units).
    pub const READ_MAIN_BATTERY: u8 = 24;
    /// Drive M1 and M2 with signed speeds (encoder counts per second).
    pub const DRIVE_SPEEDS: u8 = 37;
    /// Drive M1 and M2 with signed speeds and one acceleration (counts/s²).
    pub const DRIVE_SPEEDS_ACCEL: u8 = 40;
    /// Read both encoder counters in one reply.
    pub const READ_ENCODERS: u8 = 78;
    /// Read the status (error/warning) word.
    pub const READ_STATUS: u8 = 90;
}

/// Status word bit: the E-Stop input is active (on this robot the bumper
/// switch is wired to it).
pub const STATUS_ESTOP: u32 = 0x0000_0001;

/// A host-to-controller command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// Stop both motors if no valid packet arrives within `tenths` × 100 ms
    /// (0 disables the timeout).
    SetSerialTimeout {
        /// Timeout in 100 ms units.
        tenths: u8,
    },
    /// Zero both encoder counters.
    ResetEncoders,
    /// Ask for the firmware version string.
    ReadVersion,
    /// Ask for the main battery voltage.
    ReadMainBattery,
    /// Velocity set-points under the onboard PID, encoder counts/s.
    DriveSpeeds {
        /// Motor 1 (left wheel here).
        m1: i32,
        /// Motor 2 (right wheel here).
        m2: i32,
    },
    /// Velocity set-points reached with a ramp of `accel` counts/s².
    DriveSpeedsAccel {
        /// Acceleration for both motors, counts/s².
        accel: u32,
        /// Motor 1 (left wheel here).
        m1: i32,
        /// Motor 2 (right wheel here).
        m2: i32,
    },
    /// Ask for both encoder counters.
    ReadEncoders,
    /// Ask for the status word.
    ReadStatus,
}

impl Command {
    /// The command number on the wire.
    pub fn code(&self) -> u8 {
        match self {
            Command::SetSerialTimeout { .. } => cmd::SET_SERIAL_TIMEOUT,
            Command::ResetEncoders => cmd::RESET_ENCODERS,
            Command::ReadVersion => cmd::READ_VERSION,
            Command::ReadMainBattery => cmd::READ_MAIN_BATTERY,
            Command::DriveSpeeds { .. } => cmd::DRIVE_SPEEDS,
            Command::DriveSpeedsAccel { .. } => cmd::DRIVE_SPEEDS_ACCEL,
            Command::ReadEncoders => cmd::READ_ENCODERS,
            Command::ReadStatus => cmd::READ_STATUS,
        }
    }

    /// Whether the controller answers with the bare ACK byte.
    pub fn is_write(&self) -> bool {
        matches!(
            self,
            Command::SetSerialTimeout { .. }
                | Command::ResetEncoders
                | Command::DriveSpeeds { .. }
                | Command::DriveSpeedsAccel { .. }
        )
    }
}

/// Number of data bytes that follow command `code` in a host packet, or `None`
/// for a command this codec does not know.
pub fn data_len(code: u8) -> Option<usize> {
    match code {
        cmd::SET_SERIAL_TIMEOUT => Some(1),
        cmd::RESET_ENCODERS
        | cmd::READ_VERSION
        | cmd::READ_MAIN_BATTERY
        | cmd::READ_ENCODERS
        | cmd::READ_STATUS => Some(0),
        cmd::DRIVE_SPEEDS => Some(8),
        cmd::DRIVE_SPEEDS_ACCEL => Some(12),
        _ => None,
    }
}

/// A host packet: at most address, command, 12 data bytes and the CRC.
pub type Packet = HVec<u8, 16>;

/// Encodes `command` for the controller at `address`, CRC included.
pub fn encode_command(address: u8, command: &Command) -> Packet {
    let mut p = Packet::new();
    // Capacity 16 is the longest packet (command 40): pushes cannot fail.
    let _ = p.push(address);
    let _ = p.push(command.code());
    match *command {
        Command::SetSerialTimeout { tenths } => {
            let _ = p.push(tenths);
        }
        Command::DriveSpeeds { m1, m2 } => {
            let _ = p.extend_from_slice(&m1.to_be_bytes());
            let _ = p.extend_from_slice(&m2.to_be_bytes());
        }
        Command::DriveSpeedsAccel { accel, m1, m2 } => {
            let _ = p.extend_from_slice(&accel.to_be_bytes());
            let _ = p.extend_from_slice(&m1.to_be_bytes());
            let _ = p.extend_from_slice(&m2.to_be_bytes());
        }
        _ => {}
    }
    let mut c = Crc16::new();
    c.extend(&p);
    let _ = p.extend_from_slice(&c.value().to_be_bytes());
    p
}

/// A controller-to-host reply.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// The write command was accepted.
    Ack,
    /// Firmware version text (without the terminator).
    Version(HVec<u8, VERSION_MAX>),
    /// Main battery voltage in 0.1 V units.
    MainBattery(u16),
    /// Encoder counters of M1 and M2 (32-bit, wrapping).
    Encoders {
        /// Motor 1 counter.
        m1: u32,
        /// Motor 2 counter.
        m2: u32,
    },
    /// Status word (see [`STATUS_ESTOP`]).
    Status(u32),
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

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Shape {
    Ack,
    Fixed(usize),
    Text,
}

fn shape(code: u8) -> Shape {
    match code {
        cmd::READ_VERSION => Shape::Text,
        cmd::READ_MAIN_BATTERY => Shape::Fixed(2),
        cmd::READ_ENCODERS => Shape::Fixed(8),
        cmd::READ_STATUS => Shape::Fixed(4),
        _ => Shape::Ack,
    }
}

/// Decodes the reply to one request, byte by byte. Create one per request
/// (or [`ReplyDecoder::restart`]); the CRC is seeded with the request's
/// address and command, as the controller computes it.
#[derive(Clone, Debug)]
pub struct ReplyDecoder {
    address: u8,
    code: u8,
    shape: Shape,
    buf: HVec<u8, 64>,
}

impl ReplyDecoder {
    /// A decoder for the reply to `command` sent to `address`.
    pub fn new(address: u8, command: &Command) -> Self {
        let code = command.code();
        Self {
            address,
            code,
            shape: shape(code),
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
        match self.shape {
            Shape::Ack => {
                if b == ACK {
                    Ok(Some(Reply::Ack))
                } else {
                    Err(ReplyError::NotAck(b))
                }
            }
            Shape::Fixed(n) => {
                if self.buf.push(b).is_err() {
                    self.buf.clear();
                    return Err(ReplyError::TooLong);
                }
                if self.buf.len() < n + 2 {
                    return Ok(None);
                }
                let r = self.finish(n);
                self.buf.clear();
                r.map(Some)
            }
            Shape::Text => {
                if self.buf.push(b).is_err() {
                    self.buf.clear();
                    return Err(ReplyError::TooLong);
                }
                // Text is terminated by LF then NUL, followed by the CRC.
                let len = self.buf.len();
                let Some(nul) = self.buf.iter().position(|&c| c == 0) else {
                    if len > VERSION_MAX + 1 {
                        self.buf.clear();
                        return Err(ReplyError::TooLong);
                    }
                    return Ok(None);
                };
                if len < nul + 3 {
                    return Ok(None);
                }
                let r = self.finish(nul + 1);
                self.buf.clear();
                r.map(Some)
            }
        }
    }

    /// Checks the CRC over the first `n` data bytes and builds the reply.
    fn finish(&self, n: usize) -> Result<Reply, ReplyError> {
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
        Ok(match self.code {
            cmd::READ_MAIN_BATTERY => Reply::MainBattery(u16::from_be_bytes([data[0], data[1]])),
            cmd::READ_ENCODERS => Reply::Encoders {
                m1: u32::from_be_bytes([data[0], data[1], data[2], data[3]]),
                m2: u32::from_be_bytes([data[4], data[5], data[6], data[7]]),
            },
            cmd::READ_STATUS => {
                Reply::Status(u32::from_be_bytes([data[0], data[1], data[2], data[3]]))
            }
            _ => {
                let text_end = data
                    .iter()
                    .position(|&c| c == b'\n' || c == 0)
                    .unwrap_or(data.len());
                let mut v = HVec::new();
                let _ = v.extend_from_slice(&data[..text_end.min(VERSION_MAX)]);
                Reply::Version(v)
            }
        })
    }
}

/// A reply as it goes on the wire: at most the version text, its terminator
/// and the CRC.
pub type ReplyBytes = HVec<u8, 64>;

/// Encodes the controller's answer `reply` to command `code` from `address`
/// (device side; the CRC covers address, command and data).
pub fn encode_reply(address: u8, code: u8, reply: &Reply) -> ReplyBytes {
    let mut out = ReplyBytes::new();
    match reply {
        Reply::Ack => {
            let _ = out.push(ACK);
            return out;
        }
        Reply::Version(text) => {
            let _ = out.extend_from_slice(text);
            let _ = out.push(b'\n');
            let _ = out.push(0);
        }
        Reply::MainBattery(v) => {
            let _ = out.extend_from_slice(&v.to_be_bytes());
        }
        Reply::Encoders { m1, m2 } => {
            let _ = out.extend_from_slice(&m1.to_be_bytes());
            let _ = out.extend_from_slice(&m2.to_be_bytes());
        }
        Reply::Status(s) => {
            let _ = out.extend_from_slice(&s.to_be_bytes());
        }
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
}

/// Device-side streaming parser of host packets. Bytes that cannot start a
/// packet (not an address) are skipped and counted.
#[derive(Clone, Debug, Default)]
pub struct CommandDecoder {
    buf: HVec<u8, 16>,
    need: usize,
    /// Bytes skipped while waiting for an address byte.
    pub skipped: u64,
}

impl CommandDecoder {
    /// A decoder waiting for an address byte.
    pub fn new() -> Self {
        Self::default()
    }

    /// Drops a partial packet (the controller does this after an inter-byte gap).
    pub fn reset(&mut self) {
        self.buf.clear();
        self.need = 0;
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
            let Some(n) = data_len(b) else {
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
        let addr = self.buf[0];
        let code = self.buf[1];
        let d = &self.buf[2..n - 2];
        let result = if c.value() != received {
            Err(FrameError::Crc {
                computed: c.value(),
                received,
            })
        } else {
            Ok((
                addr,
                match code {
                    cmd::SET_SERIAL_TIMEOUT => Command::SetSerialTimeout { tenths: d[0] },
                    cmd::RESET_ENCODERS => Command::ResetEncoders,
                    cmd::READ_VERSION => Command::ReadVersion,
                    cmd::READ_MAIN_BATTERY => Command::ReadMainBattery,
                    cmd::DRIVE_SPEEDS => Command::DriveSpeeds {
                        m1: i32::from_be_bytes([d[0], d[1], d[2], d[3]]),
                        m2: i32::from_be_bytes([d[4], d[5], d[6], d[7]]),
                    },
                    cmd::DRIVE_SPEEDS_ACCEL => Command::DriveSpeedsAccel {
                        accel: u32::from_be_bytes([d[0], d[1], d[2], d[3]]),
                        m1: i32::from_be_bytes([d[4], d[5], d[6], d[7]]),
                        m2: i32::from_be_bytes([d[8], d[9], d[10], d[11]]),
                    },
                    cmd::READ_ENCODERS => Command::ReadEncoders,
                    _ => Command::ReadStatus,
                },
            ))
        };
        self.reset();
        Some(result)
    }
}

#[cfg(test)]
mod tests;
