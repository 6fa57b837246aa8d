//! Device side of the command link: [`OiDecoder`] turns host bytes into
//! commands, consuming exactly the data bytes the specification gives each
//! opcode, so data bytes (a note of 145, an LED colour of 128) are never read
//! as opcodes.

use heapless::Vec as HVec;

use super::{op, Notes, OiCommand, PacketIds, MAX_NOTES, MAX_STREAM_IDS};

/// Why host bytes yielded no command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// A byte that is no opcode of the specification; the robot cannot know
    /// how many data bytes follow it, so only this byte is skipped.
    #[error("unknown OI opcode {0}")]
    UnknownOpcode(u8),
    /// A Song of more than 16 notes or a packet list longer than this codec
    /// carries: all its bytes were consumed, the command dropped.
    #[error("OI opcode {opcode} announces {count} items, more than are carried")]
    TooLong {
        /// The command's opcode.
        opcode: u8,
        /// The count it announced.
        count: u8,
    },
}

/// Data bytes of `opc` known from the opcode alone (for Song and the packet
/// lists: the bytes up to and including the count); `None` for bytes that
/// are no opcode.
fn data_len(opc: u8) -> Option<usize> {
    Some(match opc {
        op::START | op::CONTROL | op::SAFE | op::FULL | op::POWER | op::SPOT | op::CLEAN => 0,
        op::MAX | op::SEEK_DOCK | op::STOP | op::RESET => 0,
        op::BAUD | op::MOTORS | op::PLAY | op::SENSORS | op::PAUSE_RESUME | op::BUTTONS => 1,
        op::STREAM | op::QUERY_LIST => 1,
        op::SONG | op::SCHEDULING_LEDS => 2,
        op::LEDS | op::PWM_MOTORS | op::SET_DAY_TIME => 3,
        op::DRIVE | op::DRIVE_DIRECT | op::DRIVE_PWM => 4,
        op::DIGIT_LEDS_RAW | op::DIGIT_LEDS_ASCII => 4,
        op::SCHEDULE => 15,
        _ => return None,
    })
}

/// The full data length once `got` data bytes are in and the last was `b`:
/// Song is 2 + 2N with N its second byte, the lists 1 + their count.
fn full_len(opc: u8, got: usize, b: u8, need: usize) -> usize {
    match (opc, got) {
        (op::SONG, 2) => 2 + 2 * usize::from(b),
        (op::STREAM | op::QUERY_LIST, 1) => 1 + usize::from(b),
        _ => need,
    }
}

/// Longest data kept: a Stream or Query List of [`MAX_STREAM_IDS`] ids (a
/// longer one is counted through, not kept).
const KEPT: usize = MAX_STREAM_IDS + 1;

/// Device-side parser of host commands.
#[derive(Clone, Debug, Default)]
pub struct OiDecoder {
    opcode: Option<u8>,
    data: HVec<u8, KEPT>,
    got: usize,
    need: usize,
    /// Bytes skipped because they were no opcode.
    pub skipped: u64,
}

impl OiDecoder {
    /// A decoder waiting for an opcode.
    pub fn new() -> Self {
        Self::default()
    }

    /// Whether a command has begun and awaits data bytes.
    pub fn mid_command(&self) -> bool {
        self.opcode.is_some()
    }

    /// Feeds one byte; returns a command (or why the bytes were dropped) when
    /// one is complete.
    pub fn push(&mut self, b: u8) -> Option<Result<OiCommand, DecodeError>> {
        let Some(opc) = self.opcode else {
            return self.begin(b);
        };
        // Past KEPT the bytes are only counted (TooLong below).
        let _ = self.data.push(b);
        self.got += 1;
        self.need = full_len(opc, self.got, b, self.need);
        if self.got < self.need {
            return None;
        }
        self.opcode = None;
        let r = build(opc, &self.data, self.got);
        self.data.clear();
        Some(r)
    }

    fn begin(&mut self, b: u8) -> Option<Result<OiCommand, DecodeError>> {
        match data_len(b) {
            None => {
                self.skipped += 1;
                Some(Err(DecodeError::UnknownOpcode(b)))
            }
            Some(0) => Some(build(b, &[], 0)),
            Some(n) => {
                self.opcode = Some(b);
                self.need = n;
                self.got = 0;
                self.data.clear();
                None
            }
        }
    }
}

/// The command `opc` with all its data `d` (`got` bytes were received).
fn build(opc: u8, d: &[u8], got: usize) -> Result<OiCommand, DecodeError> {
    use OiCommand as C;
    let too_long = |count: u8| DecodeError::TooLong { opcode: opc, count };
    if d.len() < got {
        return Err(too_long(
            d.get(usize::from(opc == op::SONG)).copied().unwrap_or(0),
        ));
    }
    let byte = |i: usize| d.get(i).copied().unwrap_or(0);
    let word = |i: usize| i16::from_be_bytes([byte(i), byte(i + 1)]);
    let four = || [byte(0), byte(1), byte(2), byte(3)];
    Ok(match opc {
        op::START => C::Start,
        op::CONTROL => C::Control,
        op::SAFE => C::Safe,
        op::FULL => C::Full,
        op::POWER => C::Power,
        op::SPOT => C::Spot,
        op::CLEAN => C::Clean,
        op::MAX => C::Max,
        op::SEEK_DOCK => C::SeekDock,
        op::STOP => C::Stop,
        op::RESET => C::Reset,
        op::BAUD => C::Baud(byte(0)),
        op::MOTORS => C::Motors(byte(0)),
        op::PLAY => C::Play(byte(0)),
        op::SENSORS => C::Sensors(byte(0)),
        op::BUTTONS => C::Buttons(byte(0)),
        op::PAUSE_RESUME => C::StreamEnable(byte(0) != 0),
        op::DRIVE => C::Drive {
            velocity: word(0),
            radius: word(2),
        },
        op::DRIVE_DIRECT => C::DriveDirect {
            right: word(0),
            left: word(2),
        },
        op::DRIVE_PWM => C::DrivePwm {
            right: word(0),
            left: word(2),
        },
        op::PWM_MOTORS => C::PwmMotors {
            main: byte(0) as i8,
            side: byte(1) as i8,
            vacuum: byte(2) as i8,
        },
        op::LEDS => C::Leds {
            bits: byte(0),
            color: byte(1),
            intensity: byte(2),
        },
        op::SCHEDULING_LEDS => C::SchedulingLeds {
            weekdays: byte(0),
            scheduling: byte(1),
        },
        op::DIGIT_LEDS_RAW => C::DigitLedsRaw(four()),
        op::DIGIT_LEDS_ASCII => C::DigitLedsAscii(four()),
        op::SET_DAY_TIME => C::SetDayTime {
            day: byte(0),
            hour: byte(1),
            minute: byte(2),
        },
        op::SCHEDULE => {
            let mut s = [0u8; 15];
            s.iter_mut().enumerate().for_each(|(i, v)| *v = byte(i));
            C::Schedule(s)
        }
        op::SONG => {
            if usize::from(byte(1)) > MAX_NOTES {
                return Err(too_long(byte(1)));
            }
            let mut notes = Notes::new();
            let _ = notes.extend_from_slice(d.get(2..).unwrap_or_default());
            C::Song {
                number: byte(0),
                notes,
            }
        }
        _ => {
            // Stream or Query List: count, then the ids.
            let mut ids = PacketIds::new();
            let _ = ids.extend_from_slice(d.get(1..).unwrap_or_default());
            if opc == op::STREAM {
                C::Stream(ids)
            } else {
                C::QueryList(ids)
            }
        }
    })
}
