//! An emulated Create 2, sans-IO: Open Interface commands in, replies and the
//! sensor stream out, wheel set-points to the kinematics. It follows the
//! Create 2 OI specification: every opcode consumes exactly its data bytes;
//! the modes Off, Passive, Safe and Full with the specification's
//! transitions (Start → Passive; Safe and Full need the OI started; Power,
//! Spot, Clean, Max and Seek Dock → Passive; Stop and Reset → Off);
//! actuator commands obeyed only in Safe and Full; Safe mode's reflex (wheel
//! drop, or a cliff while driving forward, stops the motors and drops to
//! Passive); every packet 7-58 and group 0-6, 100, 101, 106, 107 answered to
//! Sensors, Query List and Stream (a frame every 15 ms); no command timeout.
//!
//! Anything the specification does not allow (an unknown opcode, a command
//! the current mode does not take, a value out of its range, an undefined
//! packet id) is counted in [`DeviceStats::packets_rejected`]. In strict
//! mode an out-of-range command is also refused; otherwise it is obeyed
//! with its values clamped, as a lenient robot would.
//!
//! Assumed where the specification is silent (each at its item): the
//! emulator stays awake after Power so its mode can be read; Spot, Clean,
//! Max and Seek Dock do not run the cleaning behaviours; full PWM reaches
//! 500 mm/s; packets 39 and 40 after Drive Direct report the equivalent
//! Drive request; the battery's capacity and currents; the reset message's
//! text. Wall, virtual wall, light bumper, IR, buttons, dirt and overcurrents
//! read 0: the body state carries nothing they could sense.

mod body;
#[cfg(test)]
mod tests;

use crate::base_emu::{BaseDevice, BodyState, DeviceStats};
use crate::motor::create2::codec::{
    encode_stream_frame, packet_bytes, pkt, reads, OiCommand, OiDecoder, OiMode, PacketIds,
    SensorState, MAX_RADIUS_MM, MAX_WHEEL_MM_S, MAX_WHEEL_PWM, SONGS,
};
use crate::motor::WheelSpeeds;
use body::{Battery, WheelTrack, CAPACITY_MAH};

/// Stream period (s).
pub const STREAM_PERIOD: f64 = 0.015;

/// What the robot prints when reset: modelled on the boot text real robots
/// send (bootloader lines, a greeting, the battery current offset); the
/// exact content varies with the firmware and is illustrative here.
pub(crate) const RESET_MESSAGE: &[u8] = b"bl-start\r\nSTR730\r\nbootloader id: #x47186549 82ECCFFF\r\nbootloader info rev: #xF000\r\nbootloader rev: #x0001\r\n2007-05-14-1715-L   \r\nRoomba by iRobot!\r\nstr730\r\n2015-05-07-1646-L   \r\nbattery-current-zero 257\r\n";

/// Robot radius (m) below which a backwards turn counts as "small" for the
/// cliff reflex (the specification: one robot radius; Create 2 is 348 mm wide).
const ROBOT_RADIUS: f64 = 0.174;

/// The drive request packets 39-42 report (mm/s and mm).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Requested {
    velocity: i16,
    radius: i16,
    right: i16,
    left: i16,
}

/// The sensor stream's request.
#[derive(Clone, Debug, Default)]
struct Stream {
    ids: PacketIds,
    on: bool,
    next: f64,
}

/// Cleaning motors' duty (0..1): main brush, side brush, vacuum.
#[derive(Clone, Copy, Debug, Default)]
struct Brushes {
    main: f64,
    side: f64,
    vacuum: f64,
}

impl Brushes {
    /// Currents (mA) of main and side brush and in total: assumed figures.
    fn currents(&self) -> (f64, f64, f64) {
        let (m, s) = (400.0 * self.main, 100.0 * self.side);
        (m, s, m + s + 500.0 * self.vacuum)
    }
}

/// An emulated Create 2.
#[derive(Clone, Debug)]
pub(crate) struct Create2Device {
    counts_per_metre: f64,
    wheel_base: f64,
    strict: bool,
    decoder: OiDecoder,
    mode: OiMode,
    speeds: WheelSpeeds,
    requested: Requested,
    brushes: Brushes,
    stream: Stream,
    track: WheelTrack,
    battery: Battery,
    /// Length (s) of each defined song.
    songs: [Option<f64>; SONGS as usize],
    song_number: u8,
    song_until: f64,
    now: f64,
    stats: DeviceStats,
}

impl Create2Device {
    /// A robot with its OI off; `counts_per_metre` converts wheel travel to
    /// encoder counts; `wheel_base` (m) serves the radius-based Drive command
    /// and the angle; `strict` refuses out-of-range commands (see the module
    /// docs).
    pub fn new(counts_per_metre: f64, wheel_base: f64, strict: bool) -> Self {
        Self {
            counts_per_metre,
            wheel_base,
            strict,
            decoder: OiDecoder::new(),
            mode: OiMode::Off,
            speeds: WheelSpeeds::STOP,
            requested: Requested::default(),
            brushes: Brushes::default(),
            stream: Stream::default(),
            track: WheelTrack::default(),
            battery: Battery::default(),
            songs: [None; SONGS as usize],
            song_number: 0,
            song_until: f64::NEG_INFINITY,
            now: 0.0,
            stats: DeviceStats::default(),
        }
    }

    /// The current OI mode.
    #[cfg(test)]
    pub(crate) fn mode(&self) -> OiMode {
        self.mode
    }

    /// The sensor values now; distance and angle as a read would give them.
    fn sensors(&self, body: &BodyState) -> SensorState {
        let mut bits = 0u8;
        bits |= u8::from(body.bumper.right);
        bits |= u8::from(body.bumper.left) << 1;
        bits |= u8::from(body.wheel_drop.right) << 2;
        bits |= u8::from(body.wheel_drop.left) << 3;
        let (left_encoder, right_encoder) = self.track.counts(self.counts_per_metre);
        let (distance_mm, angle_deg) = self.track.peek();
        let (lw, rw) = self.battery.wheel_currents();
        let (main, side, _) = self.brushes.currents();
        let forward = body.wheels.left + body.wheels.right > 0.02;
        // Floor under a cliff sensor reflects strongly; a drop does not
        // (assumed signal levels within the specification's 0-4095).
        let cliff_signal = body.cliff.map(|c| if c { 20 } else { 2600 });
        SensorState {
            bumps_drops: bits,
            cliff: body.cliff.map(u8::from),
            distance_mm,
            angle_deg,
            voltage_mv: self.battery.voltage(),
            current_ma: self.battery.current(),
            temperature_c: 25,
            charge_mah: self.battery.charge(),
            capacity_mah: CAPACITY_MAH as u16,
            cliff_signal,
            oi_mode: self.mode.to_byte(),
            song_number: self.song_number,
            song_playing: u8::from(self.now < self.song_until),
            stream_packets: self.stream.ids.len() as u8,
            velocity: self.requested.velocity,
            radius: self.requested.radius,
            right_velocity: self.requested.right,
            left_velocity: self.requested.left,
            left_encoder,
            right_encoder,
            motor_current: [lw, rw, main.round() as i16, side.round() as i16],
            stasis: u8::from(forward),
            ..SensorState::default()
        }
    }

    /// The values for a read of packets `ids`: distance and angle, when read,
    /// restart from zero.
    fn read(&mut self, ids: &[u8], body: &BodyState) -> SensorState {
        let mut s = self.sensors(body);
        if ids.iter().any(|&id| reads(id, pkt::DISTANCE)) {
            s.distance_mm = self.track.read_distance();
        }
        if ids.iter().any(|&id| reads(id, pkt::ANGLE)) {
            s.angle_deg = self.track.read_angle();
        }
        s
    }

    /// Whether the specification lets mode `self.mode` take `c`.
    fn allowed(&self, c: &OiCommand) -> bool {
        use OiCommand as C;
        match c {
            C::Start | C::Reset => true,
            C::Drive { .. }
            | C::DriveDirect { .. }
            | C::DrivePwm { .. }
            | C::Motors(_)
            | C::PwmMotors { .. }
            | C::Leds { .. }
            | C::SchedulingLeds { .. }
            | C::DigitLedsRaw(_)
            | C::DigitLedsAscii(_)
            | C::Play(_) => self.mode.drives(),
            _ => self.mode != OiMode::Off,
        }
    }

    /// Stops the motors and leaves Safe/Full for `mode`.
    fn halt(&mut self, mode: OiMode) {
        self.mode = mode;
        self.speeds = WheelSpeeds::STOP;
        self.requested = Requested::default();
        self.brushes = Brushes::default();
    }

    fn handle(&mut self, c: OiCommand, body: &BodyState, out: &mut Vec<u8>) {
        if !self.allowed(&c) {
            self.stats.packets_rejected += 1;
            self.stats.refused_in_mode += 1;
            return;
        }
        if c.check().is_err() {
            self.stats.packets_rejected += 1;
            if self.strict {
                return;
            }
        }
        self.stats.packets_ok += 1;
        self.obey(c, body, out);
    }

    fn obey(&mut self, c: OiCommand, body: &BodyState, out: &mut Vec<u8>) {
        use OiCommand as C;
        match c {
            C::Start => self.halt(OiMode::Passive),
            C::Control | C::Safe => self.mode = OiMode::Safe,
            C::Full => self.mode = OiMode::Full,
            // Power puts a real robot to sleep; the emulator stays awake so
            // its mode can still be read (an assumption for testing).
            C::Power => {
                self.halt(OiMode::Passive);
                self.stream.on = false;
            }
            // The cleaning behaviours themselves are not emulated: the robot
            // enters Passive and stands still.
            C::Spot | C::Clean | C::Max | C::SeekDock => self.halt(OiMode::Passive),
            C::Stop => {
                self.halt(OiMode::Off);
                self.stream.on = false;
            }
            C::Reset => self.reset(out),
            C::Drive { velocity, radius } => self.drive(velocity, radius),
            C::DriveDirect { right, left } => self.drive_direct(right, left),
            C::DrivePwm { right, left } => {
                // Full PWM assumed to reach the top speed.
                let mm = |p: i16| {
                    let p = i32::from(p.clamp(-MAX_WHEEL_PWM, MAX_WHEEL_PWM));
                    (p * i32::from(MAX_WHEEL_MM_S) / i32::from(MAX_WHEEL_PWM)) as i16
                };
                self.drive_direct(mm(right), mm(left));
            }
            C::Motors(bits) => {
                let on = |b: u8| f64::from(u8::from(bits & b != 0));
                self.brushes = Brushes {
                    side: on(0x01),
                    vacuum: on(0x02),
                    main: on(0x04),
                };
            }
            C::PwmMotors { main, side, vacuum } => {
                let duty = |v: i8| (f64::from(v).abs() / 127.0).min(1.0);
                self.brushes = Brushes {
                    main: duty(main),
                    side: duty(side),
                    vacuum: duty(vacuum),
                };
            }
            C::Song { number, notes } => {
                let ticks: u32 = notes.chunks_exact(2).map(|n| u32::from(n[1])).sum();
                if let Some(s) = self.songs.get_mut(usize::from(number)) {
                    *s = Some(f64::from(ticks) / 64.0);
                }
            }
            C::Play(n) => self.play(n),
            C::Sensors(id) => self.query(&[id], body, out),
            C::QueryList(ids) => self.query(&ids, body, out),
            C::Stream(ids) => {
                self.stream.on = !ids.is_empty();
                self.stream.ids = ids;
                self.stream.next = self.now;
            }
            C::StreamEnable(on) => {
                self.stream.on = on && !self.stream.ids.is_empty();
                self.stream.next = self.now;
            }
            // Accepted; nothing the emulated robot senses depends on them.
            C::Baud(_)
            | C::Leds { .. }
            | C::SchedulingLeds { .. }
            | C::DigitLedsRaw(_)
            | C::DigitLedsAscii(_)
            | C::Buttons(_)
            | C::Schedule(_)
            | C::SetDayTime { .. } => {}
        }
    }

    /// Reset: as if the battery were reinserted. Off mode, songs and stream
    /// forgotten, counters from zero, and the boot text on the link.
    fn reset(&mut self, out: &mut Vec<u8>) {
        self.halt(OiMode::Off);
        self.stream = Stream::default();
        self.songs = [None; SONGS as usize];
        self.song_number = 0;
        self.song_until = f64::NEG_INFINITY;
        self.track.reset();
        self.decoder = OiDecoder::new();
        out.extend_from_slice(RESET_MESSAGE);
    }

    /// Play: a defined song starts unless one is playing (the specification:
    /// the command then does nothing).
    fn play(&mut self, n: u8) {
        let Some(Some(len)) = self.songs.get(usize::from(n)).copied() else {
            return;
        };
        if self.now >= self.song_until {
            self.song_number = n;
            self.song_until = self.now + len;
        }
    }

    /// Drive Direct (mm/s, clamped to ±500). Packets 39 and 40 then report
    /// the equivalent Drive request: the mean velocity and the radius the
    /// wheel speeds turn on (an assumption: the specification only says they
    /// are the last requested).
    fn drive_direct(&mut self, right: i16, left: i16) {
        let c = |v: i16| v.clamp(-MAX_WHEEL_MM_S, MAX_WHEEL_MM_S);
        let (r, l) = (c(right), c(left));
        self.speeds = WheelSpeeds {
            left: f64::from(l) / 1000.0,
            right: f64::from(r) / 1000.0,
        };
        self.requested = Requested {
            velocity: ((i32::from(r) + i32::from(l)) / 2) as i16,
            radius: self.radius_of(r, l),
            right: r,
            left: l,
        };
    }

    /// The Drive radius (mm) wheel speeds `r`, `l` (mm/s) turn on.
    fn radius_of(&self, r: i16, l: i16) -> i16 {
        let (r, l) = (f64::from(r), f64::from(l));
        if r == l {
            return crate::motor::create2::codec::RADIUS_STRAIGHT;
        }
        if r == -l {
            return if r > 0.0 { 1 } else { -1 };
        }
        let radius = self.wheel_base * 1000.0 / 2.0 * (r + l) / (r - l);
        radius
            .round()
            .clamp(-f64::from(MAX_RADIUS_MM), f64::from(MAX_RADIUS_MM)) as i16
    }

    /// Drive: velocity (mm/s) on a radius (mm), positive radius turning left.
    fn drive(&mut self, velocity: i16, radius: i16) {
        let v = f64::from(velocity.clamp(-MAX_WHEEL_MM_S, MAX_WHEEL_MM_S));
        let half = self.wheel_base * 1000.0 / 2.0;
        let (l, r) = match radius {
            i16::MAX | i16::MIN => (v, v),
            1 => (-v, v),
            -1 => (v, -v),
            r => {
                let r = f64::from(r.clamp(-MAX_RADIUS_MM, MAX_RADIUS_MM));
                if r == 0.0 {
                    (v, v)
                } else {
                    (v * (r - half) / r, v * (r + half) / r)
                }
            }
        };
        let mm = |x: f64| x.round().clamp(-500.0, 500.0) as i16;
        self.speeds = WheelSpeeds {
            left: f64::from(mm(l)) / 1000.0,
            right: f64::from(mm(r)) / 1000.0,
        };
        self.requested = Requested {
            velocity: v as i16,
            radius,
            right: mm(r),
            left: mm(l),
        };
    }

    /// Query replies carry the packets' data only: no header, ids or checksum.
    fn query(&mut self, ids: &[u8], body: &BodyState, out: &mut Vec<u8>) {
        let s = self.read(ids, body);
        for &id in ids {
            out.extend_from_slice(&packet_bytes(id, &s));
        }
    }

    /// Safe mode's reflex: a wheel drop, or a cliff while driving forward
    /// (or backwards on a turn tighter than the robot's radius).
    fn safety_condition(&self, body: &BodyState) -> bool {
        let cliff = body.cliff.iter().any(|&c| c);
        let w = self.speeds;
        let forward = w.left + w.right > 0.0;
        let tight_back = w.left + w.right < 0.0 && {
            let r = f64::from(self.radius_of(
                (w.right * 1000.0).round() as i16,
                (w.left * 1000.0).round() as i16,
            ));
            r.abs() / 1000.0 < ROBOT_RADIUS
        };
        body.wheel_drop.any() || (cliff && (forward || tight_back))
    }

    /// Time passes: odometry and battery follow the body.
    fn observe(&mut self, now: f64, body: &BodyState) {
        self.now = now;
        self.track.observe(body, self.wheel_base);
        self.battery
            .run(now, body.wheels, self.brushes.currents().2);
    }
}

impl BaseDevice for Create2Device {
    fn on_bytes(&mut self, bytes: &[u8], now: f64, body: &BodyState, out: &mut Vec<u8>) {
        self.observe(now, body);
        self.stats.bytes_in += bytes.len() as u64;
        for &b in bytes {
            match self.decoder.push(b) {
                Some(Ok(c)) => self.handle(c, body, out),
                Some(Err(_)) => self.stats.packets_rejected += 1,
                None => {}
            }
        }
        self.stats.bytes_skipped = self.decoder.skipped;
    }

    fn tick(&mut self, now: f64, body: &BodyState, out: &mut Vec<u8>) -> WheelSpeeds {
        self.observe(now, body);
        if self.mode == OiMode::Safe && self.safety_condition(body) {
            self.halt(OiMode::Passive);
        }
        if !self.mode.drives() {
            self.speeds = WheelSpeeds::STOP;
        }
        if self.stream.on && now >= self.stream.next {
            let ids = self.stream.ids.clone();
            let s = self.read(&ids, body);
            out.extend_from_slice(&encode_stream_frame(&ids, &s));
            self.stats.frames_out += 1;
            self.stream.next += STREAM_PERIOD;
            if self.stream.next < now {
                self.stream.next = now + STREAM_PERIOD;
            }
        }
        self.speeds
    }

    fn stats(&self) -> DeviceStats {
        self.stats
    }
}
