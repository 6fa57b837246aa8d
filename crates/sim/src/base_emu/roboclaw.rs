//! An emulated RoboClaw, sans-IO: host packets in, replies out, wheel
//! set-points to the kinematics.
//!
//! It follows Basicmicro's RoboClaw user manual: reads are `[address,
//! command]` and answered with data and a CRC over address, command and
//! data; writes carry a CRC and are answered `0xFF`; a packet with a bad CRC,
//! an unknown command or bytes more than 10 ms apart gets no answer. It
//! answers the reads and writes that Basicmicro's own libraries and the
//! common ROS drivers use (see [`Query`] and [`Command`]), with values from
//! the simulated base: encoder counters that move only when a wheel turns,
//! speeds measured from them, duty, currents from a simple DC-motor model,
//! temperatures that follow the current, and a main battery that drains
//! with use. Its serial timeout stops both motors when armed and no valid
//! packet arrived within it.
//!
//! In **strict** mode it also refuses packets the manual does not allow
//! ([`within_manual`](crate::motor::roboclaw::codec::within_manual)), so a
//! host that drifts from the manual shows in
//! [`DeviceStats::packets_rejected`] and [`DeviceStats::bytes_skipped`].
//! In either mode a partial packet dropped after an inter-byte gap counts
//! in [`DeviceStats::packets_cut`]: a stray byte from the host, or a host
//! that paused inside a packet.

use heapless::Deque;

use crate::base_emu::{BaseDevice, BodyState, DeviceStats};
use crate::motor::roboclaw::codec::{
    encode_reply, Accel, Command, CommandDecoder, Distance, FrameError, Query, Reply, VelocityPid,
    BUFFER_EMPTY, DUTY_MAX, PACKET_GAP, STATUS_ESTOP, STATUS_MAIN_LOW_WARNING, STATUS_RECORD_LEN,
};
use crate::motor::WheelSpeeds;

/// The firmware version string the emulator reports.
pub const VERSION: &[u8] = b"sweepline emulated RoboClaw 2x7A v4.1.34";

/// Distance moves one motor's buffer holds (an assumption: the manual says
/// commands are buffered, not how many).
const BUFFER_LEN: usize = 32;
/// Stall current of one emulated motor (A): the current at full duty with
/// the wheel held still.
const STALL_CURRENT: f64 = 5.0;
/// Current (A) a turning motor draws beyond its load (friction).
const FRICTION_CURRENT: f64 = 0.15;
/// Capacity of the emulated main battery (Ah; a small 3-cell pack).
const CAPACITY_AH: f64 = 2.0;
/// Time constant (s) of the board temperature.
const THERMAL_TAU: f64 = 60.0;
/// Ambient temperature (°C).
const AMBIENT: f64 = 25.0;

/// A buffered or running distance move of one motor.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Move {
    speed: f64,
    accel: Option<f64>,
    remaining: f64,
}

/// One motor channel: what it is told, where its ramp is, what its
/// encoder counted.
#[derive(Clone, Debug)]
struct Channel {
    /// The speed set-point the ramp heads for (counts/s).
    target: f64,
    /// Ramp (counts/s²); `None` for the PID's full authority.
    accel: Option<f64>,
    /// The ramped set-point (counts/s).
    cur: f64,
    /// The running distance move, and those waiting behind it.
    running: Option<Move>,
    queue: Deque<Move, BUFFER_LEN>,
    pid: VelocityPid,
    /// Raw count (whole counts of wheel travel) at the last reset/set.
    offset: i64,
    /// Raw count at the last tick.
    raw: i64,
    /// Latched under/overflow bits of the encoder status byte.
    flags: u8,
    /// Measured speeds (counts/s): instantaneous, averaged, last second.
    inst: f64,
    avg: f64,
    second: f64,
    /// Motor current (A, signed).
    current: f64,
    temp: f64,
}

impl Channel {
    fn new(qpps: u32) -> Self {
        Self {
            target: 0.0,
            accel: None,
            cur: 0.0,
            running: None,
            queue: Deque::new(),
            pid: VelocityPid {
                p: 0x0001_0000,
                i: 0x0000_8000,
                d: 0x0000_4000,
                qpps,
            },
            offset: 0,
            raw: 0,
            flags: 0,
            inst: 0.0,
            avg: 0.0,
            second: 0.0,
            current: 0.0,
            temp: AMBIENT,
        }
    }

    /// A plain speed (or duty) command: any distance move is dropped.
    fn drive(&mut self, speed: f64, accel: Option<u32>) {
        self.running = None;
        self.queue.clear();
        self.target = speed;
        self.accel = accel.filter(|&a| a > 0).map(f64::from);
    }

    /// A distance move: replaces the running one, or waits behind it.
    /// False when the buffer is full (the packet is then refused).
    fn distance(&mut self, speed: f64, accel: Option<u32>, d: Distance) -> bool {
        let m = Move {
            speed,
            accel: accel.filter(|&a| a > 0).map(f64::from),
            remaining: f64::from(d.counts),
        };
        if !d.buffered || self.running.is_none() {
            self.queue.clear();
            self.start(m);
            return true;
        }
        self.queue.push_back(m).is_ok()
    }

    fn start(&mut self, m: Move) {
        self.target = m.speed;
        self.accel = m.accel;
        self.running = Some(m);
    }

    /// Moves the distance moves and the ramp on by `dt`. A distance move
    /// slows down ahead of its end so that it stops there: its speed is held
    /// to what braking at `decel` (counts/s², the move's own acceleration
    /// when lower) can still stop within the counts left.
    fn step(&mut self, dt: f64, decel: f64) {
        if let Some(m) = self.running {
            if m.remaining < 0.5 {
                match self.queue.pop_front() {
                    Some(next) => self.start(next),
                    None => {
                        self.running = None;
                        self.target = 0.0;
                    }
                }
            }
        }
        if let Some(m) = self.running {
            let a = m.accel.map_or(decel, |a| a.min(decel));
            let brake = (2.0 * a * m.remaining).sqrt();
            self.target = m.speed.signum() * m.speed.abs().min(brake);
        }
        self.cur = match self.accel {
            Some(a) => self.cur + (self.target - self.cur).clamp(-a * dt, a * dt),
            None => self.target,
        };
    }

    /// Takes the raw counter to `raw` over `dt`: speeds, wrap flags, the
    /// motor current and the board temperature.
    fn sense(&mut self, raw: i64, dt: f64, top: f64) {
        let before = self.raw - self.offset;
        let after = raw - self.offset;
        let wraps = |c: i64| c.div_euclid(1 << 32);
        match wraps(after).cmp(&wraps(before)) {
            std::cmp::Ordering::Greater => self.flags |= 0b100,
            std::cmp::Ordering::Less => self.flags |= 0b001,
            std::cmp::Ordering::Equal => {}
        }
        if let Some(m) = self.running.as_mut() {
            m.remaining -= (raw - self.raw).abs() as f64;
        }
        if dt > 0.0 {
            // Counts arrive whole and ticks come at uneven times: speeds are
            // the counts' rate through first-order filters (10 ms for the
            // instantaneous speed, 50 ms for the encoder speed, 1 s for the
            // average of the last second).
            let v = (raw - self.raw) as f64 / dt;
            let k = |tau: f64| 1.0 - (-dt / tau).exp();
            self.inst += (v - self.inst) * k(0.01);
            self.avg += (v - self.avg) * k(0.05);
            self.second += (v - self.second) * k(1.0);
        }
        self.raw = raw;
        // A DC motor: the PWM drives the current, back-EMF (the measured
        // speed) opposes it; friction adds a little while it turns.
        let pwm = self.pwm_fraction(top);
        let emf = if top > 0.0 { self.avg / top } else { 0.0 };
        let friction = FRICTION_CURRENT * pwm.signum() * f64::from(u8::from(pwm != 0.0));
        self.current =
            (STALL_CURRENT * (pwm - emf) + friction).clamp(-STALL_CURRENT, STALL_CURRENT);
        let hot = AMBIENT + 4.0 * self.current * self.current;
        if dt > 0.0 {
            self.temp += (hot - self.temp) * (1.0 - (-dt / THERMAL_TAU).exp());
        }
    }

    /// The duty the controller applies, as a fraction of full.
    fn pwm_fraction(&self, top: f64) -> f64 {
        if top > 0.0 {
            (self.cur / top).clamp(-1.0, 1.0)
        } else {
            0.0
        }
    }

    /// The counter, for the raw count `raw` the wheel is at now.
    fn count(&self, raw: i64) -> u32 {
        (raw - self.offset) as u32
    }

    /// The encoder status byte; reading it clears the wrap flags.
    fn take_status(&mut self) -> u8 {
        let dir = if self.avg < 0.0 { 0b010 } else { 0 };
        let s = self.flags | dir;
        self.flags = 0;
        s
    }

    /// 0x80 when nothing is buffered or running, else the moves waiting.
    fn buffer(&self) -> u8 {
        if self.running.is_none() {
            BUFFER_EMPTY
        } else {
            self.queue.len() as u8
        }
    }

    fn stop(&mut self) {
        self.drive(0.0, None);
    }
}

/// An emulated RoboClaw with quadrature encoders on both motors.
#[derive(Clone, Debug)]
pub struct RoboClawDevice {
    address: u8,
    counts_per_metre: f64,
    m1_is_left: bool,
    strict: bool,
    decoder: CommandDecoder,
    ch: [Channel; 2],
    /// Counts/s at full duty (the emulated motors' top speed).
    top: f64,
    /// Counts/s² the motors can brake at (a distance move's end).
    decel: f64,
    last_tick: Option<f64>,
    start: Option<f64>,
    timeout_tenths: u8,
    last_valid: f64,
    last_byte: f64,
    timed_out: bool,
    /// Charge used (Ah).
    used_ah: f64,
    /// Raw counts (M1, M2) of the wheels when the packet being handled
    /// arrived: the counters a read latches.
    latched: [i64; 2],
    stats: DeviceStats,
}

impl RoboClawDevice {
    /// A controller at `address`; `counts_per_metre` converts wheel travel to
    /// encoder counts; `m1_is_left` says which wheel motor 1 drives.
    pub fn new(address: u8, counts_per_metre: f64, m1_is_left: bool) -> Self {
        Self {
            address,
            counts_per_metre,
            m1_is_left,
            strict: false,
            decoder: CommandDecoder::new(),
            ch: [Channel::new(0), Channel::new(0)],
            top: 0.0,
            decel: 1.0,
            last_tick: None,
            start: None,
            timeout_tenths: 0,
            last_valid: 0.0,
            last_byte: f64::NEG_INFINITY,
            timed_out: false,
            used_ah: 0.0,
            latched: [0; 2],
            stats: DeviceStats::default(),
        }
        // Until told otherwise: motors of 1 m/s top speed braking at 1 m/s².
        .with_motors(1.0, 1.0)
    }

    /// The same controller refusing (and counting) packets the manual does
    /// not allow, and counting partial packets lost to the inter-byte gap.
    pub fn strict(mut self, strict: bool) -> Self {
        self.strict = strict;
        self.decoder = if strict {
            CommandDecoder::strict()
        } else {
            CommandDecoder::new()
        };
        self
    }

    /// The same controller driving motors whose top speed (full duty) is
    /// `top_speed` m/s and that brake at `max_accel` m/s²: what the duty
    /// commands scale to, the QPPS it reports and how early a distance move
    /// slows down.
    pub(crate) fn with_motors(mut self, top_speed: f64, max_accel: f64) -> Self {
        self.top = (top_speed * self.counts_per_metre).max(0.0);
        self.decel = (max_accel * self.counts_per_metre).max(1.0);
        let qpps = self.top.round().clamp(0.0, u32::MAX as f64) as u32;
        self.ch.iter_mut().for_each(|c| c.pid.qpps = qpps);
        self
    }

    /// Raw whole counts of the wheels' travel, (M1, M2).
    fn raw_counts(&self, body: &BodyState) -> (i64, i64) {
        let c = |m: f64| (m * self.counts_per_metre).round() as i64;
        let (l, r) = (c(body.encoder.0), c(body.encoder.1));
        if self.m1_is_left {
            (l, r)
        } else {
            (r, l)
        }
    }

    /// Main battery voltage (V): a 3-cell pack from 12.6 V full to 9.9 V
    /// empty, sagging 0.05 V per ampere drawn.
    fn main_volts(&self) -> f64 {
        let soc = (1.0 - self.used_ah / CAPACITY_AH).clamp(0.0, 1.0);
        let amps = self.ch[0].current.abs() + self.ch[1].current.abs();
        9.9 + 2.7 * (0.15 + 0.85 * soc) - 0.05 * amps
    }

    /// Logic battery voltage (V). Assumed: no separate logic battery, the
    /// logic fed from the main battery through a diode (0.7 V drop).
    fn logic_volts(&self) -> f64 {
        self.main_volts() - 0.7
    }

    fn status_word(&self, body: &BodyState) -> u32 {
        let mut s = 0;
        if body.bumper.any() {
            s |= STATUS_ESTOP;
        }
        if self.main_volts() < 10.5 {
            s |= STATUS_MAIN_LOW_WARNING;
        }
        for (i, c) in self.ch.iter().enumerate() {
            // The over-current warnings, M1 0x010000 and M2 0x020000.
            if c.current.abs() > 0.8 * STALL_CURRENT {
                s |= 0x0001_0000 << i;
            }
        }
        s
    }

    fn tenths(v: f64) -> u16 {
        (v * 10.0).round().clamp(0.0, f64::from(u16::MAX)) as u16
    }

    fn pwm(&self, m: usize) -> u16 {
        (self.ch[m].pwm_fraction(self.top) * f64::from(DUTY_MAX)).round() as i16 as u16
    }

    fn centiamps(&self, m: usize) -> u16 {
        (self.ch[m].current * 100.0).round() as i16 as u16
    }

    fn speed_status(v: f64) -> Reply {
        let s = v.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32;
        Reply::CountStatus {
            value: s as u32,
            status: u8::from(s < 0),
        }
    }

    /// The 56-byte record of command 73, in the layout of Basicmicro's
    /// `GetStatus` (tick, state, temperatures, batteries, PWMs, currents,
    /// counters, set and measured speeds, speed and position errors).
    fn record(&self, now: f64, body: &BodyState) -> [u8; STATUS_RECORD_LEN] {
        let mut r = [0u8; STATUS_RECORD_LEN];
        let mut at = 0;
        let mut put = |b: &[u8]| {
            r[at..at + b.len()].copy_from_slice(b);
            at += b.len();
        };
        let ms = ((now - self.start.unwrap_or(now)) * 1000.0) as u32;
        put(&ms.to_be_bytes());
        put(&self.status_word(body).to_be_bytes());
        put(&Self::tenths(self.ch[0].temp).to_be_bytes());
        put(&Self::tenths(self.ch[1].temp - 0.5).to_be_bytes());
        put(&Self::tenths(self.main_volts()).to_be_bytes());
        put(&Self::tenths(self.logic_volts()).to_be_bytes());
        put(&self.pwm(0).to_be_bytes());
        put(&self.pwm(1).to_be_bytes());
        put(&self.centiamps(0).to_be_bytes());
        put(&self.centiamps(1).to_be_bytes());
        for (c, raw) in self.ch.iter().zip(self.latched) {
            put(&c.count(raw).to_be_bytes());
        }
        for c in &self.ch {
            put(&(c.cur.round() as i32).to_be_bytes());
        }
        for c in &self.ch {
            put(&(c.avg.round() as i32).to_be_bytes());
        }
        for c in &self.ch {
            let e = (c.cur - c.avg).round().clamp(-32768.0, 32767.0) as i16;
            put(&e.to_be_bytes());
        }
        put(&[0; 4]);
        r
    }

    fn answer(&mut self, q: Query, now: f64, body: &BodyState) -> Reply {
        let pair32 = |f: &dyn Fn(&Channel) -> f64| {
            let v = |c: &Channel| f(c).round().clamp(i32::MIN as f64, i32::MAX as f64) as i32;
            Reply::Pair32(v(&self.ch[0]) as u32, v(&self.ch[1]) as u32)
        };
        match q {
            Query::SerialTimeout => Reply::U8(self.timeout_tenths),
            Query::Encoder(m) => {
                let raw = self.latched[m.index()];
                let c = &mut self.ch[m.index()];
                Reply::CountStatus {
                    value: c.count(raw),
                    status: c.take_status(),
                }
            }
            Query::Speed(m) => Self::speed_status(self.ch[m.index()].avg),
            Query::InstSpeed(m) => Self::speed_status(self.ch[m.index()].inst),
            Query::Version => {
                let mut v = heapless::Vec::new();
                let _ = v.extend_from_slice(VERSION);
                Reply::Version(v)
            }
            Query::MainBattery => Reply::U16(Self::tenths(self.main_volts())),
            Query::LogicBattery => Reply::U16(Self::tenths(self.logic_volts())),
            Query::Buffers => Reply::Pair8(self.ch[0].buffer(), self.ch[1].buffer()),
            Query::Pwms => Reply::Pair16(self.pwm(0), self.pwm(1)),
            Query::Currents => Reply::Pair16(self.centiamps(0), self.centiamps(1)),
            Query::VelocityPid(m) => {
                let p = self.ch[m.index()].pid;
                Reply::Quad32([p.p, p.i, p.d, p.qpps])
            }
            Query::StatusRecord => Reply::Record(self.record(now, body)),
            Query::Encoders => Reply::Pair32(
                self.ch[0].count(self.latched[0]),
                self.ch[1].count(self.latched[1]),
            ),
            Query::InstSpeeds => pair32(&|c| c.inst),
            Query::Speeds => pair32(&|c| c.second),
            Query::Temperature => Reply::U16(Self::tenths(self.ch[0].temp)),
            Query::Temperature2 => Reply::U16(Self::tenths(self.ch[1].temp - 0.5)),
            Query::Status => Reply::U32(self.status_word(body)),
            // Both quadrature, nothing reversed.
            Query::EncoderModes => Reply::Pair8(0, 0),
        }
    }

    /// Obeys a write; false when it cannot be taken (a full buffer).
    fn obey(&mut self, cmd: Command) -> bool {
        let duty = |d: i16| f64::from(d.max(-DUTY_MAX)) / f64::from(DUTY_MAX);
        // Duty acceleration is in duty units per second: as counts/s².
        let duty_accel = |a: u32, top: f64| (f64::from(a) / f64::from(DUTY_MAX) * top) as u32;
        let top = self.top;
        match cmd {
            Command::SetSerialTimeout { tenths } => self.timeout_tenths = tenths,
            Command::ResetEncoders => {
                for (c, raw) in self.ch.iter_mut().zip(self.latched) {
                    c.offset = raw;
                    c.flags = 0;
                }
            }
            Command::SetEncoder { motor, count } => {
                let c = &mut self.ch[motor.index()];
                c.offset = self.latched[motor.index()] - i64::from(count);
            }
            Command::SetVelocityPid { motor, pid } => self.ch[motor.index()].pid = pid,
            Command::Duty {
                motor,
                duty: d,
                accel,
            } => self.ch[motor.index()].drive(duty(d) * top, accel.map(|a| duty_accel(a, top))),
            Command::Duties { m1, m2, accel } => {
                let (a1, a2) = match accel {
                    Some((a1, a2)) => (Some(duty_accel(a1, top)), Some(duty_accel(a2, top))),
                    None => (None, None),
                };
                self.ch[0].drive(duty(m1) * top, a1);
                self.ch[1].drive(duty(m2) * top, a2);
            }
            Command::Speed {
                motor,
                speed,
                accel,
                distance,
            } => {
                let c = &mut self.ch[motor.index()];
                match distance {
                    None => c.drive(f64::from(speed), accel),
                    Some(d) => return c.distance(f64::from(speed), accel, d),
                }
            }
            Command::Speeds {
                m1,
                m2,
                accel,
                distance,
            } => return self.speeds(m1, m2, accel, distance),
            Command::Query(_) => {}
        }
        true
    }

    fn speeds(
        &mut self,
        m1: i32,
        m2: i32,
        accel: Accel,
        distance: Option<(u32, u32, bool)>,
    ) -> bool {
        let (a1, a2) = match accel {
            Accel::None => (None, None),
            Accel::Both(a) => (Some(a), Some(a)),
            Accel::Each(a1, a2) => (Some(a1), Some(a2)),
        };
        let Some((d1, d2, buffered)) = distance else {
            self.ch[0].drive(f64::from(m1), a1);
            self.ch[1].drive(f64::from(m2), a2);
            return true;
        };
        let d = |counts| Distance { counts, buffered };
        let ok1 = self.ch[0].distance(f64::from(m1), a1, d(d1));
        let ok2 = self.ch[1].distance(f64::from(m2), a2, d(d2));
        ok1 && ok2
    }

    fn handle(&mut self, cmd: Command, now: f64, body: &BodyState, out: &mut Vec<u8>) {
        let reply = match cmd {
            Command::Query(q) => self.answer(q, now, body),
            write => {
                if !self.obey(write) {
                    self.stats.packets_rejected += 1;
                    return;
                }
                self.timed_out = false;
                Reply::Ack
            }
        };
        out.extend_from_slice(&encode_reply(self.address, cmd.code(), &reply));
    }

    /// Motor 1 and 2 speeds as wheel speeds (m/s).
    fn wheels(&self) -> WheelSpeeds {
        let v1 = self.ch[0].cur / self.counts_per_metre;
        let v2 = self.ch[1].cur / self.counts_per_metre;
        if self.m1_is_left {
            WheelSpeeds {
                left: v1,
                right: v2,
            }
        } else {
            WheelSpeeds {
                left: v2,
                right: v1,
            }
        }
    }
}

impl BaseDevice for RoboClawDevice {
    fn on_bytes(&mut self, bytes: &[u8], now: f64, body: &BodyState, out: &mut Vec<u8>) {
        self.last_byte = now;
        self.stats.bytes_in += bytes.len() as u64;
        let (r1, r2) = self.raw_counts(body);
        self.latched = [r1, r2];
        for &b in bytes {
            match self.decoder.push(b) {
                None => {}
                Some(Ok((addr, cmd))) if addr == self.address => {
                    self.stats.packets_ok += 1;
                    self.last_valid = now;
                    self.handle(cmd, now, body, out);
                }
                // Another controller's packet on a shared bus: not ours.
                Some(Ok(_)) => {}
                Some(Err(
                    FrameError::Crc { .. }
                    | FrameError::UnknownCommand(_)
                    | FrameError::OutsideManual(_),
                )) => self.stats.packets_rejected += 1,
            }
        }
        self.stats.bytes_skipped = self.decoder.skipped;
    }

    fn line_silent(&mut self, until: f64) {
        if until - self.last_byte > PACKET_GAP && self.decoder.reset() > 0 {
            self.stats.packets_cut += 1;
        }
    }

    fn tick(&mut self, now: f64, body: &BodyState, _out: &mut Vec<u8>) -> WheelSpeeds {
        let start = *self.start.get_or_insert(now);
        let prev = self.last_tick.unwrap_or(start);
        let dt = (now - prev).max(0.0);
        self.last_tick = Some(now);
        if self.timeout_tenths > 0
            && !self.timed_out
            && now - self.last_valid > f64::from(self.timeout_tenths) * 0.1
        {
            self.timed_out = true;
            self.stats.device_timeouts += 1;
            self.ch.iter_mut().for_each(Channel::stop);
        }
        let (r1, r2) = self.raw_counts(body);
        let (top, decel) = (self.top, self.decel);
        for (c, raw) in self.ch.iter_mut().zip([r1, r2]) {
            c.sense(raw, dt, top);
            c.step(dt, decel);
        }
        let amps = self.ch[0].current.abs() + self.ch[1].current.abs();
        self.used_ah += amps * dt / 3600.0;
        self.wheels()
    }

    fn stats(&self) -> DeviceStats {
        self.stats
    }
}

#[cfg(test)]
mod tests;
