//! The emulated sensor itself, sans-IO: command lines in, reply bytes out,
//! scans produced when the emulator clock says a revolution has ended. The
//! runner in [`super`] moves the bytes over the pty.
//!
//! Behaviour follows the real URG-04LX (and UTM-30LX) as captured and as
//! documented in `../shared/research/scip-and-drivers.md`: SCIP 1.1 boot
//! with the `SCIP2.0` switch, a 24-bit millisecond clock reset by RS, time
//! adjust mode (TM0/TM1/TM2, everything else answered `0E` in it), MD/MS/ME
//! streams with the remaining-scan counter in the echo, GD needing the laser
//! on, RB twice within a second to reboot, and the exact VV/PP/II texts.
//!
//! GD is answered as the real unit does (checked against the capture and
//! Hokuyo's urg_library): the scan is the revolution that starts after the
//! command, stamped at its start and sent when it ends, so a GD reply takes
//! one to two scan periods and back-to-back GDs never repeat a scan. Lines
//! received meanwhile are answered after it, in order.
//!
//! Reply latency (on unless [`Sensor::set_reply_latency`] turns it off), as
//! the time-stamped captures show:
//! * every other command (VV, PP, II, BM, CR, QT, RS, SS, HS, TM0, MD/MS,
//!   RB, errors) is handled at the firmware's command tick, once per
//!   revolution, `ModelSpec::tick_lead` before a revolution starts. In the
//!   URG-04LX capture the host sends each command right after the previous
//!   reply, so each reply comes 98-100 ms after its command; the first VV,
//!   sent mid-revolution, was answered after 10 ms. Lines that arrived
//!   before a tick are all handled at it, in order (assumed: the captures
//!   never send two commands at once);
//! * in time-adjust mode the firmware answers at its millisecond clock's
//!   next edge: TM1 about 1 ms after the request, TM2 at the second edge
//!   (about 2 ms), as in the UXM-30LX-E capture (the only one with TM; the
//!   URG-04LX is assumed to do the same), and TM1 reads the clock at that
//!   edge;
//! * GD/GS start measuring at once (the capture's GD reply leaves one
//!   revolution after the command, not at a tick).

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::faults::{Faults, ScanFault};
use super::model::{Model, ModelSpec};
use super::returns::{self, Step};
use super::scene::{Echo, Scene};
use crate::scip::{
    write_status_reply, Cluster, Command, DataKind, DataLineWriter, KvLine, ScanRequest, Status,
    StatusCode, StreamRequest, Tag, TaggedCommand, TimeControl, Width,
};

/// Period of the sensor clock (ms).
pub(crate) const CLOCK_WRAP_MS: u64 = 1 << 24;
/// How many sent scans the log keeps.
pub(crate) const LOG_CAPACITY: usize = 100_000;

/// One scan the emulator put on the wire.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SentScan {
    /// Sequence number over the emulator's life (from 1).
    pub index: u64,
    /// The 24-bit timestamp it carried.
    pub stamp: u32,
    /// The emulator's own unwrapped clock at that scan (ms since the first
    /// boot's clock origin, continuing over reboots).
    pub true_ms: u64,
    /// Which power-on it belongs to (from 1; unplug/replug and RB add one).
    pub boot: u32,
    /// Emulator-clock time (s) at which the scan was measured: the truth a
    /// driver's host stamp is checked against.
    pub at: f64,
    /// What was done to it on the wire, if anything.
    pub fault: Option<ScanFault>,
}

/// What the emulator did, for tests and the CLI's summary.
#[derive(Clone, Debug, Default)]
pub struct EmuLog {
    /// Scans sent (the last `LOG_CAPACITY`).
    pub sent: VecDeque<SentScan>,
    /// Command lines received, in order (the last 1000).
    pub commands: VecDeque<String>,
    /// Power-ons (1 + replugs + reboots).
    pub boots: u32,
    /// Unplugs performed.
    pub unplugs: u32,
    /// Stalls performed.
    pub stalls: u32,
    /// Steps measured over all scans sent.
    pub steps: u64,
    /// Of those, steps sent as an error code (below DMIN).
    pub(crate) error_steps: u64,
}

impl EmuLog {
    /// Share of the measured steps sent as error codes (0 before any scan).
    pub fn error_share(&self) -> f64 {
        if self.steps == 0 {
            0.0
        } else {
            self.error_steps as f64 / self.steps as f64
        }
    }

    /// Scans whose data were damaged on the wire.
    pub fn corrupted(&self) -> usize {
        self.sent
            .iter()
            .filter(|s| s.fault.is_some_and(|f| f.corrupts()))
            .count()
    }
}

/// Something the runner must do after a scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Go silent for this many seconds.
    Stall(f64),
    /// Unplug for this many seconds, then replug and power on again.
    Unplug(f64),
}

/// What [`Sensor::poll`] does next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Due {
    /// Send the streamed scan.
    Scan,
    /// Send the GD reply.
    Get,
    /// Handle the first inbox line.
    Line,
}

/// A GD waiting for its revolution to end.
#[derive(Clone, Copy)]
struct PendingGet {
    req: ScanRequest,
    /// Start of the revolution measured (emulator clock, s): the stamp.
    start: f64,
    /// When the reply is sent: the end of that revolution.
    due: f64,
}

struct Stream {
    req: StreamRequest,
    tag: Tag,
    /// Scans still to send; `None` = until QT.
    remaining: Option<u8>,
    next: f64,
}

/// The sensor state machine.
pub struct Sensor {
    spec: ModelSpec,
    faults: Faults,
    scip1_boot: bool,
    rng: ChaCha8Rng,
    scene: Box<dyn Scene>,
    log: Arc<Mutex<EmuLog>>,
    scip2: bool,
    laser: bool,
    adjust: bool,
    high_sensitivity: bool,
    stream: Option<Stream>,
    get: Option<PendingGet>,
    /// The echo line of the pending GD.
    get_echo: Vec<u8>,
    /// Command lines received and not handled yet (LF-terminated, in order).
    inbox: Vec<u8>,
    /// When each line of `inbox` arrived (emulator clock, s).
    inbox_at: VecDeque<f64>,
    /// Scratch: the line being handled.
    current: Vec<u8>,
    /// When the last line was handled, or the last GD reply sent: no line
    /// is handled before the ones ahead of it.
    busy_until: f64,
    /// Whether replies wait for the firmware's ticks (see the module doc).
    latency: bool,
    /// Offset (s) of the revolution starts from the clock origin.
    phase: f64,
    /// Sensor clock (ms) at `t0`.
    clock0: u64,
    t0: f64,
    /// Unwrapped true clock (ms) at `t0`, continuing over reboots.
    true0: u64,
    boot: u32,
    rate: f64,
    rb_at: Option<f64>,
    sent: u64,
    hung: bool,
    last_stamp: u32,
    action: Option<Action>,
    angles: Vec<f64>,
    echoes: Vec<Echo>,
    /// Scratch: what each step of the scan being measured saw.
    steps: Vec<Step>,
    /// Draws of the return model (apart from `rng`, so fault placement
    /// does not depend on the scene).
    optics: ChaCha8Rng,
    block: Vec<u8>,
}

fn ok() -> Status {
    Status::Scip2(StatusCode::OK)
}

fn st(code: &[u8; 2]) -> Status {
    Status::Scip2(StatusCode(*code))
}

impl Sensor {
    /// A sensor powered on at `now` (emulator clock, s).
    pub fn new(
        spec: ModelSpec,
        faults: Faults,
        scip1_boot: bool,
        scene: Box<dyn Scene>,
        seed: u64,
        log: Arc<Mutex<EmuLog>>,
        now: f64,
    ) -> Self {
        let clock0 = if faults.clock_wrap {
            CLOCK_WRAP_MS - 2000
        } else {
            0
        };
        if let Ok(mut l) = log.lock() {
            // Steady state never grows the log (no allocation per scan).
            l.sent.reserve(4096);
            l.commands.reserve(1000);
        }
        let mut s = Sensor {
            spec,
            faults,
            scip1_boot,
            rng: ChaCha8Rng::seed_from_u64(seed),
            scene,
            log,
            scip2: true,
            laser: false,
            adjust: false,
            high_sensitivity: false,
            stream: None,
            get: None,
            get_echo: Vec::with_capacity(64),
            inbox: Vec::with_capacity(256),
            inbox_at: VecDeque::with_capacity(16),
            current: Vec::with_capacity(64),
            busy_until: now,
            latency: true,
            phase: 0.0,
            clock0,
            t0: now,
            true0: clock0,
            boot: 0,
            rate: 1.0,
            rb_at: None,
            sent: 0,
            hung: false,
            last_stamp: 0,
            action: None,
            angles: Vec::new(),
            echoes: Vec::new(),
            steps: Vec::new(),
            optics: ChaCha8Rng::seed_from_u64(seed ^ 0x0971_c5e5),
            block: Vec::with_capacity(8192),
        };
        s.power_on(now, false);
        s
    }

    /// Power-on reset at `now`: SCIP mode as booted, laser off, no stream;
    /// `reset_clock` restarts the sensor clock at 0 (a reboot), otherwise it
    /// keeps its origin (first boot).
    pub(crate) fn power_on(&mut self, now: f64, reset_clock: bool) {
        if reset_clock {
            self.true0 = self.true_ms(now);
            self.clock0 = 0;
            self.t0 = now;
        }
        self.scip2 = !self.scip1_boot;
        self.laser = false;
        self.adjust = false;
        self.high_sensitivity = false;
        self.stream = None;
        self.get = None;
        self.inbox.clear();
        self.inbox_at.clear();
        self.busy_until = now;
        self.rb_at = None;
        self.hung = false;
        self.boot += 1;
        if let Ok(mut l) = self.log.lock() {
            l.boots = self.boot;
        }
    }

    /// The model's fixed facts.
    pub fn spec(&self) -> &ModelSpec {
        &self.spec
    }

    /// The 24-bit sensor clock at `now` (ms).
    pub fn clock_ms(&self, now: f64) -> u32 {
        ((self.clock0 + self.elapsed_ms(now)) % CLOCK_WRAP_MS) as u32
    }

    fn elapsed_ms(&self, now: f64) -> u64 {
        // The epsilon keeps k·period from flooring to the millisecond below.
        ((now - self.t0).max(0.0) * 1000.0 * self.rate + 1e-6).floor() as u64
    }

    /// Makes the sensor's crystal run fast (positive) or slow by `ppm`
    /// parts per million relative to the emulator clock.
    pub fn set_drift_ppm(&mut self, ppm: f64) {
        let now = self.t0;
        if ppm.is_finite() && ppm.abs() < 1e5 {
            self.true0 = self.true_ms(now);
            self.rate = 1.0 + ppm * 1e-6;
        }
    }

    fn true_ms(&self, now: f64) -> u64 {
        self.true0 + self.elapsed_ms(now)
    }

    /// When the streamed revolution now due is sent (emulator clock), if
    /// streaming: once it has been measured, a period after it starts, as
    /// a GD reply is.
    fn stream_due(&self) -> Option<f64> {
        self.stream.as_ref().map(|s| s.next + self.spec.period())
    }

    /// When the next scan, GD reply or command reply is due (emulator
    /// clock), if any.
    pub fn next_due(&self) -> Option<f64> {
        self.next_event().map(|(t, _)| t)
    }

    /// The earliest pending event and its time.
    fn next_event(&self) -> Option<(f64, Due)> {
        [
            self.stream_due().map(|t| (t, Due::Scan)),
            self.get.map(|g| (g.due, Due::Get)),
            self.inbox_due().map(|t| (t, Due::Line)),
        ]
        .into_iter()
        .flatten()
        .min_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// Turns the reply latency of the real firmware on (the default) or off
    /// (every line answered the moment it arrives, for clients that want a
    /// fast bench sensor).
    pub fn set_reply_latency(&mut self, on: bool) {
        self.latency = on;
    }

    /// When the first line of the inbox is handled, if there is one and no
    /// GD measurement holds it back.
    fn inbox_due(&self) -> Option<f64> {
        if self.get.is_some() {
            return None;
        }
        let arrived = *self.inbox_at.front()?;
        let end = self.inbox.iter().position(|&b| b == b'\n')?;
        let seen = arrived.max(self.busy_until);
        Some(self.reply_time(&self.inbox[..end], seen))
    }

    /// When the firmware handles `line`, first seen at `seen`: see the
    /// module doc for what the captures show.
    fn reply_time(&self, line: &[u8], seen: f64) -> f64 {
        if !self.latency {
            return seen;
        }
        let body = line.split(|&b| b == b';').next().unwrap_or(line);
        if self.adjust && self.scip2 {
            let edges = if body == b"TM2" { 2 } else { 1 };
            return self.clock_edge_after(seen, edges);
        }
        if self.scip2 && !self.hung && body.first() == Some(&b'G') {
            return seen;
        }
        self.next_phase(seen, -self.spec.tick_lead)
    }

    /// The `n`-th edge of the sensor's millisecond clock after `t`.
    fn clock_edge_after(&self, t: f64, n: u64) -> f64 {
        let ms = self.elapsed_ms(t) + n;
        self.t0 + ms as f64 / (1000.0 * self.rate)
    }

    /// Sets where in the sensor clock the mirror's revolutions start (s,
    /// taken modulo the scan period; 0 by default). A real unit's phase is
    /// arbitrary; tests set it to reproduce a captured timestamp.
    pub fn set_revolution_phase(&mut self, phase: f64) {
        let p = self.spec.period();
        if phase.is_finite() && p > 0.0 {
            self.phase = phase.rem_euclid(p);
        }
    }

    /// Start of the first revolution that begins strictly after `now` (a
    /// line arriving at a revolution start is too late for it; the epsilon
    /// keeps rounding from deciding that).
    fn next_revolution(&self, now: f64) -> f64 {
        self.next_phase(now, 0.0)
    }

    /// The first time strictly after `now` that lies `offset` seconds from
    /// a revolution start.
    fn next_phase(&self, now: f64, offset: f64) -> f64 {
        let p = self.spec.period();
        let base = self.t0 + self.phase + offset;
        let k = ((now - base) / p + 1e-9).floor() + 1.0;
        base + k * p
    }

    /// The pending stall or unplug, if any.
    pub(crate) fn take_action(&mut self) -> Option<Action> {
        self.action.take()
    }

    /// Takes one received command line (without its line end) at `now`;
    /// it is answered in `out` now or, with reply latency, by a later
    /// [`Sensor::poll`] (see [`Sensor::next_due`]).
    pub fn on_line(&mut self, line: &[u8], now: f64, out: &mut Vec<u8>) {
        if line.is_empty() {
            return;
        }
        self.inbox.extend_from_slice(line);
        self.inbox.push(b'\n');
        self.inbox_at.push_back(now);
        self.serve_lines(now, out);
    }

    /// Handles the inbox lines due at or before `now`, in order.
    fn serve_lines(&mut self, now: f64, out: &mut Vec<u8>) {
        while let Some(due) = self.inbox_due().filter(|&t| t <= now) {
            self.handle_next_line(due, out);
        }
    }

    /// Takes the first inbox line off and handles it at `due`.
    fn handle_next_line(&mut self, due: f64, out: &mut Vec<u8>) {
        let Some(end) = self.inbox.iter().position(|&b| b == b'\n') else {
            return;
        };
        let mut line = std::mem::take(&mut self.current);
        line.clear();
        line.extend_from_slice(&self.inbox[..end]);
        self.inbox.drain(..=end);
        self.inbox_at.pop_front();
        self.busy_until = due;
        self.handle(&line, due, out);
        self.current = line;
    }

    /// Answers one command line at `now`, the time the firmware handles it.
    fn handle(&mut self, line: &[u8], now: f64, out: &mut Vec<u8>) {
        if let Ok(mut l) = self.log.lock() {
            if l.commands.len() >= 1000 {
                l.commands.pop_front();
            }
            l.commands
                .push_back(String::from_utf8_lossy(line).into_owned());
        }
        if !self.scip2 {
            // SCIP 1.1 firmware: only the switch is understood here; every
            // other line gets the one-character error status.
            let status = if line == b"SCIP2.0" {
                self.scip2 = true;
                Status::Scip1(b'0')
            } else {
                Status::Scip1(b'E')
            };
            let _ = write_status_reply(line, status, out);
            return;
        }
        let body = line.split(|&b| b == b';').next().unwrap_or(line);
        if body == b"RB" {
            self.reboot_request(line, now, out);
            return;
        }
        if self.hung {
            return;
        }
        self.rb_at = None;
        let cmd = match TaggedCommand::parse(line) {
            Ok(c) => c,
            Err(e) => {
                let _ = write_status_reply(line, Status::Scip2(e.status()), out);
                return;
            }
        };
        if self.adjust && !matches!(cmd.command, Command::Tm(_) | Command::Rs) {
            let _ = write_status_reply(line, Status::Scip2(StatusCode::UNDEFINED), out);
            return;
        }
        match cmd.command {
            Command::Scip20 => {
                let _ = write_status_reply(line, Status::Scip2(StatusCode::UNDEFINED), out);
            }
            Command::Vv => {
                let fields = self.spec.vv;
                Self::kv_reply(line, fields.iter().map(|(k, v)| (*k, v.to_string())), out);
            }
            Command::Pp => Self::kv_reply(line, self.spec.pp().into_iter(), out),
            Command::Ii => {
                let ii = self.spec.ii(self.laser, self.clock_ms(now));
                Self::kv_reply(line, ii.into_iter(), out)
            }
            Command::Bm => {
                let s = if self.laser { st(b"02") } else { ok() };
                self.laser = true;
                let _ = write_status_reply(line, s, out);
            }
            Command::Qt => {
                self.stream = None;
                self.laser = false;
                let _ = write_status_reply(line, ok(), out);
            }
            Command::Rs => {
                self.stream = None;
                self.laser = false;
                self.adjust = false;
                self.high_sensitivity = false;
                self.true0 = self.true_ms(now);
                self.clock0 = 0;
                self.t0 = now;
                let _ = write_status_reply(line, ok(), out);
            }
            Command::Tm(tc) => self.time_command(line, tc, now, out),
            Command::Ss(_) => {
                // USB-CDC: the bit rate cannot be changed.
                let _ = write_status_reply(line, st(b"04"), out);
            }
            Command::Cr(level) => {
                let s = match self.spec.model {
                    Model::Urg04lx if level == 0 => st(&self.spec.cr_status),
                    Model::Urg04lx if level <= 10 || level == 99 => ok(),
                    Model::Urg04lx => st(b"02"),
                    Model::Utm30lx => st(&self.spec.cr_status),
                };
                let _ = write_status_reply(line, s, out);
            }
            Command::Hs(on) => {
                let s = match self.spec.model {
                    Model::Urg04lx if on == self.high_sensitivity => st(b"02"),
                    Model::Urg04lx => {
                        self.high_sensitivity = on;
                        ok()
                    }
                    Model::Utm30lx => st(b"03"),
                };
                let _ = write_status_reply(line, s, out);
            }
            Command::Get(req) => {
                if let Err(s) = self.check_request(&req) {
                    let _ = write_status_reply(line, s, out);
                } else if !self.laser {
                    let _ = write_status_reply(line, Status::Scip2(StatusCode::DENIED), out);
                } else {
                    let start = self.next_revolution(now);
                    self.get_echo.clear();
                    self.get_echo.extend_from_slice(line);
                    self.get = Some(PendingGet {
                        req,
                        start,
                        due: start + self.spec.period(),
                    });
                }
            }
            Command::Stream(req) => {
                if let Err(s) = self.check_request(&req.scan) {
                    let _ = write_status_reply(line, s, out);
                    return;
                }
                self.laser = true;
                let _ = write_status_reply(line, ok(), out);
                let next = self.next_revolution(now);
                self.stream = Some(Stream {
                    req,
                    tag: cmd.tag,
                    remaining: (req.count > 0).then_some(req.count),
                    next,
                });
            }
        }
    }

    fn check_request(&self, req: &ScanRequest) -> Result<(), Status> {
        if req.kind == DataKind::DistanceIntensity && !self.spec.has_me {
            return Err(Status::Scip2(StatusCode::UNDEFINED));
        }
        if req.cluster == Cluster::UrgIntensity && (!self.spec.has_ff || self.faults.no_ff) {
            return Err(st(b"03"));
        }
        // The firmware takes any step up to the last one it measures (step
        // D), not only the detection range PP reports.
        req.check_range(0, self.spec.last_step)
            .map_err(Status::Scip2)
    }

    fn reboot_request(&mut self, line: &[u8], now: f64, out: &mut Vec<u8>) {
        match self.rb_at {
            Some(t) if now - t <= 1.0 => {
                let _ = write_status_reply(line, ok(), out);
                self.power_on(now, true);
            }
            _ => {
                self.rb_at = Some(now);
                let _ = write_status_reply(line, st(b"01"), out);
            }
        }
    }

    fn time_command(&mut self, line: &[u8], tc: TimeControl, now: f64, out: &mut Vec<u8>) {
        match tc {
            TimeControl::Enter => {
                let s = if self.stream.is_some() {
                    Status::Scip2(StatusCode::DENIED)
                } else if self.adjust {
                    st(b"02")
                } else {
                    self.adjust = true;
                    self.laser = false;
                    ok()
                };
                let _ = write_status_reply(line, s, out);
            }
            TimeControl::Read => {
                if !self.adjust {
                    let _ = write_status_reply(line, st(b"04"), out);
                    return;
                }
                out.extend_from_slice(line);
                out.push(b'\n');
                let _ = crate::scip::reply::write_status(ok(), out);
                let mut w = DataLineWriter::new(out);
                let _ = w.put_value(self.clock_ms(now), Width::Four);
                let _ = w.finish();
                out.push(b'\n');
            }
            TimeControl::Leave => {
                let s = if self.adjust {
                    self.adjust = false;
                    ok()
                } else {
                    st(b"03")
                };
                let _ = write_status_reply(line, s, out);
            }
        }
    }

    fn kv_reply(
        line: &[u8],
        fields: impl Iterator<Item = (&'static str, String)>,
        out: &mut Vec<u8>,
    ) {
        out.extend_from_slice(line);
        out.push(b'\n');
        let _ = crate::scip::reply::write_status(ok(), out);
        for (k, v) in fields {
            let _ = KvLine::encode(k, &v, out);
        }
        out.push(b'\n');
    }

    /// Produces what is due at or before `now` (streamed scans, a GD reply,
    /// command replies), in time order; writes it to `out`.
    pub fn poll(&mut self, now: f64, out: &mut Vec<u8>) {
        while let Some((t, what)) = self.next_event() {
            if t > now {
                break;
            }
            match what {
                // A hung firmware sends nothing, but still takes lines (RB).
                Due::Scan | Due::Get if self.hung => {
                    self.stream = None;
                    self.get = None;
                }
                Due::Scan => self.poll_stream(now, out),
                Due::Get => self.poll_get(out),
                Due::Line => self.handle_next_line(t, out),
            }
        }
    }

    /// Sends the pending GD reply (its revolution has ended); the lines that
    /// arrived meanwhile are handled after it.
    fn poll_get(&mut self, out: &mut Vec<u8>) {
        let Some(g) = self.get else {
            return;
        };
        self.get = None;
        self.busy_until = self.busy_until.max(g.due);
        let mut block = std::mem::take(&mut self.block);
        block.clear();
        block.extend_from_slice(&self.get_echo);
        block.push(b'\n');
        let _ = crate::scip::reply::write_status(ok(), &mut block);
        {
            let mut w = DataLineWriter::new(&mut block);
            let _ = w.put_value(self.clock_ms(g.start), Width::Four);
            let _ = w.finish();
        }
        self.measure(g.start, &g.req, &mut block);
        block.push(b'\n');
        out.extend_from_slice(&block);
        self.block = block;
    }

    /// Produces the scan due at or before `now`, if streaming.
    fn poll_stream(&mut self, now: f64, out: &mut Vec<u8>) {
        if self.stream_due().is_none_or(|sent| now < sent) {
            return;
        }
        let p = self.spec.period();
        let Some(stream) = self.stream.as_mut() else {
            return;
        };
        let interval = p * f64::from(stream.req.skip + 1);
        let t = stream.next;
        // Revolutions that ended while we were late are lost, as on the sensor.
        while stream.next + p <= now {
            stream.next += interval;
        }
        let remaining = match stream.remaining {
            Some(r) => r.saturating_sub(1),
            None => 0,
        };
        let finished = stream.remaining == Some(1);
        if let Some(r) = stream.remaining.as_mut() {
            *r -= 1;
        }
        let echo = TaggedCommand::with_tag(
            Command::Stream(stream.req.with_remaining(remaining)),
            stream.tag.clone(),
        );
        let req = stream.req.scan;
        if finished {
            self.stream = None;
        }
        self.sent += 1;
        let fault = self.faults.scan_fault(self.sent);
        let stamp = if fault == Some(ScanFault::StuckClock) {
            self.last_stamp
        } else {
            self.clock_ms(t)
        };
        self.last_stamp = stamp;
        let mut block = std::mem::take(&mut self.block);
        block.clear();
        if self.faults.noise_every > 0
            && self.sent.is_multiple_of(u64::from(self.faults.noise_every))
        {
            block.extend_from_slice(b"\x00\x13\xfe\x07~\xff\n");
        }
        let _ = echo.encode(&mut block);
        if fault == Some(ScanFault::ErrorStatus) {
            let _ = crate::scip::reply::write_status(st(&self.faults.status_code), &mut block);
            block.push(b'\n');
        } else {
            let _ = crate::scip::reply::write_status(Status::Scip2(StatusCode::DATA), &mut block);
            let data_start = {
                let mut w = DataLineWriter::new(&mut block);
                let _ = w.put_value(stamp, Width::Four);
                let _ = w.finish();
                block.len()
            };
            self.measure(t, &req, &mut block);
            if let Some(f) = fault {
                self.damage(&mut block, data_start, f);
            }
            block.push(b'\n');
        }
        out.extend_from_slice(&block);
        self.block = block;
        let entry = SentScan {
            index: self.sent,
            stamp,
            true_ms: self.true_ms(t),
            boot: self.boot,
            at: t,
            fault,
        };
        if let Ok(mut l) = self.log.lock() {
            if l.sent.len() >= LOG_CAPACITY {
                l.sent.pop_front();
            }
            l.sent.push_back(entry);
        }
        if self.faults.hang_after > 0 && self.sent == u64::from(self.faults.hang_after) {
            self.hung = true;
        }
        let hit = |every: u32| every > 0 && self.sent.is_multiple_of(u64::from(every));
        if let Some((n, d)) = self.faults.unplug {
            if hit(n) {
                self.action = Some(Action::Unplug(d));
            }
        }
        if let Some((n, d)) = self.faults.stall {
            if hit(n) && self.action.is_none() {
                self.action = Some(Action::Stall(d));
                // The revolutions during the stall are never sent.
                if let Some(s) = self.stream.as_mut() {
                    while s.next <= now + d {
                        s.next += interval;
                    }
                }
            }
        }
    }

    /// Damages one data line of the block (after `data_start`) as `fault` says.
    fn damage(&mut self, block: &mut Vec<u8>, data_start: usize, fault: ScanFault) {
        // Data lines: [start, end) of each line's bytes without the LF.
        let mut lines: Vec<(usize, usize)> = Vec::new();
        let mut s = data_start;
        for (i, &b) in block.iter().enumerate().skip(data_start) {
            if b == b'\n' {
                if i > s + 1 {
                    lines.push((s, i));
                }
                s = i + 1;
            }
        }
        if lines.is_empty() {
            return;
        }
        let (a, e) = lines[self.rng.random_range(0..lines.len())];
        let sum_at = e - 1;
        match fault {
            ScanFault::Checksum => {
                let old = block[sum_at];
                let mut new = old;
                while new == old {
                    new = self.rng.random_range(0x30u8..=0x6f);
                }
                block[sum_at] = new;
            }
            ScanFault::DroppedByte => {
                let at = self.rng.random_range(a..sum_at);
                block.remove(at);
            }
            ScanFault::ExtraByte => {
                // Never '@' (0x40 ≡ 0 mod 64): the checksum must change.
                let mut c = b'@';
                while c == b'@' {
                    c = self.rng.random_range(0x30u8..=0x6f);
                }
                let at = self.rng.random_range(a..=sum_at);
                block.insert(at, c);
            }
            ScanFault::ErrorStatus | ScanFault::StuckClock => {}
        }
    }

    /// Samples the scene and writes the data lines of one scan of `req` at
    /// time `t`.
    fn measure(&mut self, t: f64, req: &ScanRequest, out: &mut Vec<u8>) {
        self.sample_steps(t, req);
        let spec = &self.spec;
        let mut w = DataLineWriter::new(out);
        let (start, end) = (req.start, req.end);
        let steps = self.steps.len();
        match req.cluster {
            Cluster::UrgIntensity => {
                // Experimental URG-04LX raw intensity mode: the value of an
                // even step is the distance of the pair (s, s+1), the value of
                // an odd step the intensity of the pair (s-1, s).
                for (k, s) in (start..=end).enumerate() {
                    let (base, is_dist) = if s % 2 == 0 {
                        (k, true)
                    } else {
                        (k.saturating_sub(usize::from(k > 0)), false)
                    };
                    let (d, i) = wire(spec, self.steps[base]);
                    let _ = w.put_value(if is_dist { d } else { i }, Width::Three);
                }
            }
            Cluster::Steps(c) => {
                let c = usize::from(c.max(1));
                let mut k = 0;
                while k < steps {
                    let group = &self.steps[k..(k + c).min(steps)];
                    let mut best: Option<(u32, u32)> = None;
                    let mut first_err = None;
                    for e in group {
                        let (d, i) = wire(spec, *e);
                        if d >= spec.dmin {
                            if best.is_none_or(|(bd, _)| d < bd) {
                                best = Some((d, i));
                            }
                        } else if first_err.is_none() {
                            first_err = Some((d, 0));
                        }
                    }
                    let (d, i) = best.or(first_err).unwrap_or((spec.no_return_code, 0));
                    match req.kind {
                        DataKind::Distance => {
                            let _ = w.put_value(d, Width::Three);
                        }
                        DataKind::ShortDistance => {
                            let _ = w.put_value(d.min(4095), Width::Two);
                        }
                        DataKind::DistanceIntensity => {
                            let _ = w.put_value(d, Width::Three);
                            let _ = w.put_value(i.min(262_143), Width::Three);
                        }
                    }
                    k += c;
                }
            }
        }
        let _ = w.finish();
    }

    /// Samples the scene for the steps of `req` at time `t` and decides what
    /// each step measures (`self.steps`).
    fn sample_steps(&mut self, t: f64, req: &ScanRequest) {
        let (start, end) = (req.start, req.end);
        self.angles.clear();
        self.angles
            .extend((start..=end).map(|s| self.spec.angle(s)));
        self.echoes.clear();
        self.echoes.resize(self.angles.len(), Echo::NoReturn);
        // Steps are measured one after another from the first one asked for,
        // at the time of the stamp.
        let step_time = self.spec.period() / f64::from(self.spec.ares.max(1));
        self.scene
            .sample(t, step_time, &self.angles, &mut self.echoes);
        self.steps.clear();
        for (k, s) in (start..=end).enumerate() {
            let e = self.echoes.get(k).copied().unwrap_or(Echo::NoReturn);
            let step = self.step_of(s, e);
            self.steps.push(step);
        }
        if self.spec.model == Model::Urg04lx {
            returns::mark_neighbours(&mut self.steps, &mut self.optics);
        }
        let errors = self
            .steps
            .iter()
            .filter(|s| !matches!(s, Step::Range { .. }))
            .count();
        if let Ok(mut l) = self.log.lock() {
            l.steps += self.steps.len() as u64;
            l.error_steps += errors as u64;
        }
    }

    /// What step `s` measures of echo `e`: see [`returns`] for the URG-04LX
    /// model (the UTM-30LX keeps plain geometry: too close or too far only).
    fn step_of(&mut self, s: u16, e: Echo) -> Step {
        let urg = self.spec.model == Model::Urg04lx;
        if urg && !(self.spec.amin..=self.spec.amax).contains(&s) {
            return Step::Code(returns::TOO_CLOSE_CODE);
        }
        match e {
            Echo::Hit {
                range,
                reflectivity,
                cos_incidence,
            } => {
                let mm = (range * 1000.0).round();
                if !mm.is_finite() || mm > f64::from(self.spec.dmax) {
                    Step::NoEcho
                } else if mm < f64::from(self.spec.dmin) {
                    Step::Code(if urg { returns::TOO_CLOSE_CODE } else { 2 })
                } else if urg
                    && !returns::measured(reflectivity * cos_incidence, range, &mut self.optics)
                {
                    Step::NoEcho
                } else {
                    let i = super::intensity::reported(reflectivity, cos_incidence, range);
                    Step::Range {
                        mm: mm as u32,
                        intensity: i.round() as u32,
                    }
                }
            }
            Echo::NoReturn => Step::NoEcho,
            Echo::Error(c) => Step::Code(c.min(self.spec.dmin.saturating_sub(1))),
        }
    }
}

/// The wire values (distance mm or error code, intensity) of one step.
fn wire(spec: &ModelSpec, s: Step) -> (u32, u32) {
    match s {
        Step::Range { mm, intensity } => (mm, intensity),
        Step::Code(c) => (c, 0),
        Step::NoEcho => (spec.no_return_code, 0),
    }
}

#[cfg(test)]
#[path = "sensor_tests.rs"]
mod tests;
