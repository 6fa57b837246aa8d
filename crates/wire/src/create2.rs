//! iRobot Create 2 / Roomba 600 Open Interface (OI), sans-IO.
//!
//! Host → robot: one opcode byte and exactly the data bytes the OI
//! specification gives it ([`OiCommand`], [`encode`]); the robot has no
//! framing, so a command with the wrong number of data bytes makes it read
//! data as opcodes. Robot → host: replies to Sensors / Query List (the packets'
//! data only) and the sensor stream, a frame every 15 ms:
//! `19, n, (packet id, packet data)…, checksum`, where `n` counts the bytes
//! between itself and the checksum, and the 8-bit sum of every frame byte,
//! checksum included, is 0. Multi-byte values are big-endian.
//!
//! The host side is [`encode`] plus the streaming [`StreamParser`]; the device
//! side (emulator) is [`OiDecoder`] plus [`encode_stream_frame`] and
//! `packet_bytes`. [`OiCommand::check`] tells whether a command's values lie
//! in the ranges the specification allows. Nothing here allocates or panics on
//! any input.

use heapless::Vec as HVec;

mod decoder;
mod packets;
mod stream;

pub use decoder::{DecodeError, OiDecoder};
pub use packets::{encode_stream_frame, packet_size, response_size, FrameBytes, SensorState};
pub use packets::{packet_bytes, reads, PacketBytes};
pub use stream::{SensorFrame, StreamError, StreamParser, MAX_PAYLOAD};

/// Opcodes of the Create 2 OI specification.
pub mod op {
    /// Reset the robot (as if the battery were removed and reinserted): Off.
    pub const RESET: u8 = 7;
    /// Start the OI (enters Passive mode).
    pub const START: u8 = 128;
    /// Set the baud rate (1 data byte, code 11 = 115200).
    pub const BAUD: u8 = 129;
    /// Same as Safe.
    pub const CONTROL: u8 = 130;
    /// Enter Safe mode.
    pub const SAFE: u8 = 131;
    /// Enter Full mode.
    pub const FULL: u8 = 132;
    /// Power the robot down (mode becomes Passive).
    pub const POWER: u8 = 133;
    /// Start a spot clean (mode becomes Passive).
    pub const SPOT: u8 = 134;
    /// Start a default clean (mode becomes Passive).
    pub const CLEAN: u8 = 135;
    /// Start a max clean (mode becomes Passive).
    pub const MAX: u8 = 136;
    /// Drive with velocity and turn radius (4 data bytes).
    pub const DRIVE: u8 = 137;
    /// Cleaning motors on/off (1 data byte).
    pub const MOTORS: u8 = 138;
    /// LEDs: bits, power colour, power intensity (3 data bytes).
    pub const LEDS: u8 = 139;
    /// Define a song: number, length N, N (note, duration) pairs (2 + 2N).
    pub const SONG: u8 = 140;
    /// Play a song (1 data byte).
    pub const PLAY: u8 = 141;
    /// Query one sensor packet (1 data byte).
    pub const SENSORS: u8 = 142;
    /// Seek the dock (mode becomes Passive).
    pub const SEEK_DOCK: u8 = 143;
    /// Cleaning motors by PWM: main brush, side brush, vacuum (3 data bytes).
    pub const PWM_MOTORS: u8 = 144;
    /// Drive each wheel: right velocity then left velocity, mm/s (4 data bytes).
    pub const DRIVE_DIRECT: u8 = 145;
    /// Drive each wheel by PWM, ±255, right first (4 data bytes).
    pub const DRIVE_PWM: u8 = 146;
    /// Start a sensor stream: count, then that many packet ids.
    pub const STREAM: u8 = 148;
    /// Query a list of packets once: count, then ids.
    pub const QUERY_LIST: u8 = 149;
    /// Pause (0) or resume (1) the stream.
    pub const PAUSE_RESUME: u8 = 150;
    /// Scheduling LEDs: weekday bits, scheduling bits (2 data bytes).
    pub const SCHEDULING_LEDS: u8 = 162;
    /// Digit LEDs by segments, digit 3 first (4 data bytes).
    pub const DIGIT_LEDS_RAW: u8 = 163;
    /// Digit LEDs by ASCII codes 32-126 (4 data bytes).
    pub const DIGIT_LEDS_ASCII: u8 = 164;
    /// Push the robot's buttons (1 data byte).
    pub const BUTTONS: u8 = 165;
    /// Cleaning schedule: days, then hour and minute for each day (15 data bytes).
    pub const SCHEDULE: u8 = 167;
    /// Set the clock: day, hour, minute (3 data bytes).
    pub const SET_DAY_TIME: u8 = 168;
    /// Stop the OI (mode becomes Off; the robot stops responding).
    pub const STOP: u8 = 173;
}

/// Sensor packet ids the driver uses.
pub mod pkt {
    /// Bumps (bits 0 right, 1 left) and wheel drops (bits 2 right, 3 left).
    pub const BUMPS_WHEEL_DROPS: u8 = 7;
    /// Distance travelled since last read (mm, i16).
    pub const DISTANCE: u8 = 19;
    /// Angle turned since last read (degrees, i16, counter-clockwise positive).
    pub const ANGLE: u8 = 20;
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
/// Fastest wheel speed Drive and Drive Direct accept (mm/s).
pub const MAX_WHEEL_MM_S: i16 = 500;
/// Largest turn radius Drive accepts besides the special values (mm).
pub const MAX_RADIUS_MM: i16 = 2000;
/// Drive's radius meaning "straight" (the specification gives 0x8000 and 0x7FFF).
pub const RADIUS_STRAIGHT: i16 = i16::MAX;
/// Largest PWM magnitude Drive PWM accepts.
pub const MAX_WHEEL_PWM: i16 = 255;
/// Most packet ids in one Stream or Query List this codec carries; a longer
/// list is consumed and reported as [`DecodeError::TooLong`].
pub const MAX_STREAM_IDS: usize = 64;
/// Songs the robot stores (numbers 0-4).
pub const SONGS: u8 = 5;
/// Most notes in one song.
pub const MAX_NOTES: usize = 16;

/// The OI's operating mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OiMode {
    /// OI not started: only Start (and Reset) are obeyed.
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

    /// Whether actuator commands are obeyed (Safe and Full).
    pub fn drives(self) -> bool {
        matches!(self, OiMode::Safe | OiMode::Full)
    }
}

/// A song's notes: (MIDI note, duration in 1/64 s) pairs, flattened.
pub type Notes = HVec<u8, { 2 * MAX_NOTES }>;
/// A list of packet ids.
pub type PacketIds = HVec<u8, MAX_STREAM_IDS>;

/// A host-to-robot command: every opcode of the specification.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OiCommand {
    /// Opcode 128.
    Start,
    /// Opcode 129 with its baud code.
    Baud(u8),
    /// Opcode 130 (the specification: same as Safe).
    Control,
    /// Opcode 131.
    Safe,
    /// Opcode 132.
    Full,
    /// Opcode 133.
    Power,
    /// Opcode 134.
    Spot,
    /// Opcode 135.
    Clean,
    /// Opcode 136.
    Max,
    /// Opcode 143.
    SeekDock,
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
    /// Opcode 138: cleaning motor bits.
    Motors(u8),
    /// Opcode 144: cleaning motors by PWM.
    PwmMotors {
        /// Main brush, -127..=127.
        main: i8,
        /// Side brush, -127..=127.
        side: i8,
        /// Vacuum, 0..=127.
        vacuum: i8,
    },
    /// Opcode 139.
    Leds {
        /// LED bits (debris, spot, dock, check robot).
        bits: u8,
        /// Power LED colour, 0 green to 255 red.
        color: u8,
        /// Power LED intensity.
        intensity: u8,
    },
    /// Opcode 162: weekday and scheduling LED bits.
    SchedulingLeds {
        /// Weekday LED bits.
        weekdays: u8,
        /// Scheduling LED bits.
        scheduling: u8,
    },
    /// Opcode 163: segment bits of digits 3, 2, 1, 0.
    DigitLedsRaw([u8; 4]),
    /// Opcode 164: ASCII codes of the four digits, left first.
    DigitLedsAscii([u8; 4]),
    /// Opcode 165: button bits.
    Buttons(u8),
    /// Opcode 167: day bits, then (hour, minute) Sunday to Saturday.
    Schedule([u8; 15]),
    /// Opcode 168.
    SetDayTime {
        /// Day, 0 Sunday to 6 Saturday.
        day: u8,
        /// Hour, 0-23.
        hour: u8,
        /// Minute, 0-59.
        minute: u8,
    },
    /// Opcode 140: song `number`, its notes (the length is `notes.len() / 2`).
    Song {
        /// Song number, 0-4.
        number: u8,
        /// (note, duration) pairs.
        notes: Notes,
    },
    /// Opcode 141.
    Play(u8),
    /// Opcode 148: stream these packet ids every 15 ms.
    Stream(PacketIds),
    /// Opcode 149: send these packets once.
    QueryList(PacketIds),
    /// Opcode 142: send one packet once.
    Sensors(u8),
    /// Opcode 150: `false` pauses the stream, `true` resumes it.
    StreamEnable(bool),
}

/// A command value outside the range the specification allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("OI opcode {opcode}: {field} = {value} is outside the specification's range")]
pub struct RangeError {
    /// The command's opcode.
    pub opcode: u8,
    /// Which data field.
    pub field: &'static str,
    /// Its value.
    pub value: i32,
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

    /// The command's opcode.
    pub fn opcode(&self) -> u8 {
        use OiCommand as C;
        match self {
            C::Start => op::START,
            C::Baud(_) => op::BAUD,
            C::Control => op::CONTROL,
            C::Safe => op::SAFE,
            C::Full => op::FULL,
            C::Power => op::POWER,
            C::Spot => op::SPOT,
            C::Clean => op::CLEAN,
            C::Max => op::MAX,
            C::SeekDock => op::SEEK_DOCK,
            C::Stop => op::STOP,
            C::Reset => op::RESET,
            C::Drive { .. } => op::DRIVE,
            C::DriveDirect { .. } => op::DRIVE_DIRECT,
            C::DrivePwm { .. } => op::DRIVE_PWM,
            C::Motors(_) => op::MOTORS,
            C::PwmMotors { .. } => op::PWM_MOTORS,
            C::Leds { .. } => op::LEDS,
            C::SchedulingLeds { .. } => op::SCHEDULING_LEDS,
            C::DigitLedsRaw(_) => op::DIGIT_LEDS_RAW,
            C::DigitLedsAscii(_) => op::DIGIT_LEDS_ASCII,
            C::Buttons(_) => op::BUTTONS,
            C::Schedule(_) => op::SCHEDULE,
            C::SetDayTime { .. } => op::SET_DAY_TIME,
            C::Song { .. } => op::SONG,
            C::Play(_) => op::PLAY,
            C::Stream(_) => op::STREAM,
            C::QueryList(_) => op::QUERY_LIST,
            C::Sensors(_) => op::SENSORS,
            C::StreamEnable(_) => op::PAUSE_RESUME,
        }
    }

    /// Checks every value against the range the specification gives it.
    /// Bit-field bytes (LEDs, motors, buttons) accept any value: the robot
    /// ignores unused bits. Notes outside 31-127 are rests, not errors.
    pub fn check(&self) -> Result<(), RangeError> {
        use OiCommand as C;
        let opcode = self.opcode();
        let within = |field: &'static str, v: i32, lo: i32, hi: i32| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(RangeError {
                    opcode,
                    field,
                    value: v,
                })
            }
        };
        let wheel = i32::from(MAX_WHEEL_MM_S);
        match self {
            C::Baud(code) => within("baud code", (*code).into(), 0, 11),
            C::Drive { velocity, radius } => {
                within("velocity", (*velocity).into(), -wheel, wheel)?;
                let r = i32::from(*radius);
                let special = *radius == i16::MIN || *radius == i16::MAX;
                if special {
                    Ok(())
                } else {
                    within("radius", r, -i32::from(MAX_RADIUS_MM), MAX_RADIUS_MM.into())
                }
            }
            C::DriveDirect { right, left } => {
                within("right velocity", (*right).into(), -wheel, wheel)?;
                within("left velocity", (*left).into(), -wheel, wheel)
            }
            C::DrivePwm { right, left } => {
                let m = i32::from(MAX_WHEEL_PWM);
                within("right PWM", (*right).into(), -m, m)?;
                within("left PWM", (*left).into(), -m, m)
            }
            C::PwmMotors { main, side, vacuum } => {
                within("main brush PWM", (*main).into(), -127, 127)?;
                within("side brush PWM", (*side).into(), -127, 127)?;
                within("vacuum PWM", (*vacuum).into(), 0, 127)
            }
            C::DigitLedsRaw(d) => d
                .iter()
                .try_for_each(|&b| within("digit segments", b.into(), 0, 127)),
            C::DigitLedsAscii(d) => d
                .iter()
                .try_for_each(|&b| within("digit ASCII", b.into(), 32, 126)),
            C::Schedule(s) => check_schedule(s, &within),
            C::SetDayTime { day, hour, minute } => {
                within("day", (*day).into(), 0, 6)?;
                within("hour", (*hour).into(), 0, 23)?;
                within("minute", (*minute).into(), 0, 59)
            }
            C::Song { number, notes } => {
                within("song number", (*number).into(), 0, i32::from(SONGS) - 1)?;
                within("song length", (notes.len() / 2) as i32, 1, MAX_NOTES as i32)
            }
            C::Play(n) => within("song number", (*n).into(), 0, i32::from(SONGS) - 1),
            C::Sensors(id) => check_id(*id, &within),
            C::Stream(ids) | C::QueryList(ids) => {
                ids.iter().try_for_each(|&id| check_id(id, &within))
            }
            _ => Ok(()),
        }
    }
}

fn check_id(
    id: u8,
    within: &impl Fn(&'static str, i32, i32, i32) -> Result<(), RangeError>,
) -> Result<(), RangeError> {
    match response_size(id) {
        Some(_) => Ok(()),
        // An id with no packet: report it against an empty range.
        None => within("packet id", id.into(), 1, 0),
    }
}

fn check_schedule(
    s: &[u8; 15],
    within: &impl Fn(&'static str, i32, i32, i32) -> Result<(), RangeError>,
) -> Result<(), RangeError> {
    within("schedule days", s[0].into(), 0, 127)?;
    for hm in s[1..].chunks_exact(2) {
        within("schedule hour", hm[0].into(), 0, 23)?;
        within("schedule minute", hm[1].into(), 0, 59)?;
    }
    Ok(())
}

fn mm_s(v: f64) -> i16 {
    let mm = crate::float::round(v * 1000.0);
    if mm.is_nan() {
        0
    } else {
        mm.clamp(-(MAX_WHEEL_MM_S as f64), MAX_WHEEL_MM_S as f64) as i16
    }
}

/// Encoded command bytes (the longest command, a Stream or Query List of
/// [`MAX_STREAM_IDS`] ids, fits).
pub type OiBytes = HVec<u8, { MAX_STREAM_IDS + 2 }>;

/// Encodes one command: its opcode and exactly its data bytes.
pub fn encode(c: &OiCommand) -> OiBytes {
    use OiCommand as C;
    let mut o = OiBytes::new();
    let _ = o.push(c.opcode());
    // Capacity exceeds the longest command: extending cannot fail.
    let mut put = |b: &[u8]| {
        let _ = o.extend_from_slice(b);
    };
    let pair = |a: i16, b: i16| {
        let (a, b) = (a.to_be_bytes(), b.to_be_bytes());
        [a[0], a[1], b[0], b[1]]
    };
    match c {
        C::Start
        | C::Control
        | C::Safe
        | C::Full
        | C::Power
        | C::Spot
        | C::Clean
        | C::Max
        | C::SeekDock
        | C::Stop
        | C::Reset => {}
        C::Baud(b) | C::Motors(b) | C::Buttons(b) | C::Play(b) | C::Sensors(b) => put(&[*b]),
        C::StreamEnable(on) => put(&[u8::from(*on)]),
        C::Drive { velocity, radius } => put(&pair(*velocity, *radius)),
        C::DriveDirect { right, left } | C::DrivePwm { right, left } => put(&pair(*right, *left)),
        C::PwmMotors { main, side, vacuum } => {
            put(&[*main as u8, *side as u8, *vacuum as u8]);
        }
        C::Leds {
            bits,
            color,
            intensity,
        } => put(&[*bits, *color, *intensity]),
        C::SchedulingLeds {
            weekdays,
            scheduling,
        } => put(&[*weekdays, *scheduling]),
        C::DigitLedsRaw(d) | C::DigitLedsAscii(d) => put(d),
        C::Schedule(s) => put(s),
        C::SetDayTime { day, hour, minute } => put(&[*day, *hour, *minute]),
        C::Song { number, notes } => {
            put(&[*number, (notes.len() / 2) as u8]);
            put(&notes[..notes.len() & !1]);
        }
        C::Stream(ids) | C::QueryList(ids) => {
            put(&[ids.len() as u8]);
            put(ids);
        }
    }
    o
}

/// Which side of the robot a contact or drop is on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sides {
    /// Left side.
    pub left: bool,
    /// Right side.
    pub right: bool,
}

impl Sides {
    /// Whether either side is active.
    pub fn any(&self) -> bool {
        self.left || self.right
    }
}

#[cfg(test)]
mod tests;
