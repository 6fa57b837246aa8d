//! An emulated RoboClaw, sans-IO: host packets in, replies out, wheel
//! set-points to the kinematics. It checks every packet's CRC and stays silent
//! on a bad one, acknowledges writes with 0xFF, answers reads with a CRC over
//! address, command and data, and enforces its serial timeout: when armed and
//! no valid packet arrived within it, both motors stop.

use crate::motor::roboclaw::codec::{
    encode_reply, Command, CommandDecoder, FrameError, Reply, STATUS_ESTOP,
};
use crate::motor::WheelSpeeds;
use crate::sim::base_emu::{BaseDevice, BodyState, DeviceStats};

/// The firmware version string the emulator reports.
pub const VERSION: &[u8] = b"sweepline emulated RoboClaw 2x7A v4.1.34";

/// Gap (s) after which a partial packet is dropped.
const PACKET_GAP: f64 = 0.05;

/// An emulated RoboClaw with quadrature encoders on both motors.
#[derive(Clone, Debug)]
pub struct RoboClawDevice {
    address: u8,
    counts_per_metre: f64,
    m1_is_left: bool,
    decoder: CommandDecoder,
    set_m1: i32,
    set_m2: i32,
    ramp: Option<f64>,
    cur: (f64, f64),
    last_tick: f64,
    timeout_tenths: u8,
    last_valid: f64,
    last_byte: f64,
    timed_out: bool,
    enc_offset: (i64, i64),
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
            decoder: CommandDecoder::new(),
            set_m1: 0,
            set_m2: 0,
            ramp: None,
            cur: (0.0, 0.0),
            last_tick: 0.0,
            timeout_tenths: 0,
            last_valid: 0.0,
            last_byte: 0.0,
            timed_out: false,
            enc_offset: (0, 0),
            stats: DeviceStats::default(),
        }
    }

    fn counts(&self, body: &BodyState) -> (u32, u32) {
        let l = (body.encoder.0 * self.counts_per_metre).round() as i64;
        let r = (body.encoder.1 * self.counts_per_metre).round() as i64;
        let (m1, m2) = if self.m1_is_left { (l, r) } else { (r, l) };
        (
            (m1 - self.enc_offset.0) as u32,
            (m2 - self.enc_offset.1) as u32,
        )
    }

    fn handle(&mut self, cmd: Command, body: &BodyState, out: &mut Vec<u8>) {
        let code = cmd.code();
        let reply = match cmd {
            Command::SetSerialTimeout { tenths } => {
                self.timeout_tenths = tenths;
                Reply::Ack
            }
            Command::ResetEncoders => {
                let l = (body.encoder.0 * self.counts_per_metre).round() as i64;
                let r = (body.encoder.1 * self.counts_per_metre).round() as i64;
                self.enc_offset = if self.m1_is_left { (l, r) } else { (r, l) };
                Reply::Ack
            }
            Command::ReadVersion => {
                let mut v = heapless::Vec::new();
                let _ = v.extend_from_slice(VERSION);
                Reply::Version(v)
            }
            Command::ReadMainBattery => Reply::MainBattery(121),
            Command::DriveSpeeds { m1, m2 } => {
                self.set_m1 = m1;
                self.set_m2 = m2;
                self.ramp = None;
                self.timed_out = false;
                Reply::Ack
            }
            Command::DriveSpeedsAccel { accel, m1, m2 } => {
                self.set_m1 = m1;
                self.set_m2 = m2;
                self.ramp = Some(accel as f64);
                self.timed_out = false;
                Reply::Ack
            }
            Command::ReadEncoders => {
                let (m1, m2) = self.counts(body);
                Reply::Encoders { m1, m2 }
            }
            Command::ReadStatus => Reply::Status(if body.bumper.any() { STATUS_ESTOP } else { 0 }),
        };
        out.extend_from_slice(&encode_reply(self.address, code, &reply));
    }
}

impl BaseDevice for RoboClawDevice {
    fn on_bytes(&mut self, bytes: &[u8], now: f64, body: &BodyState, out: &mut Vec<u8>) {
        if now - self.last_byte > PACKET_GAP {
            self.decoder.reset();
        }
        self.last_byte = now;
        self.stats.bytes_in += bytes.len() as u64;
        for &b in bytes {
            match self.decoder.push(b) {
                None => {}
                Some(Ok((addr, cmd))) if addr == self.address => {
                    self.stats.packets_ok += 1;
                    self.last_valid = now;
                    self.handle(cmd, body, out);
                }
                Some(Ok(_)) => {}
                Some(Err(FrameError::Crc { .. })) => self.stats.packets_rejected += 1,
                Some(Err(FrameError::UnknownCommand(_))) => self.stats.packets_rejected += 1,
            }
        }
        self.stats.bytes_skipped = self.decoder.skipped;
    }

    fn tick(&mut self, now: f64, _body: &BodyState, _out: &mut Vec<u8>) -> WheelSpeeds {
        if self.timeout_tenths > 0
            && !self.timed_out
            && now - self.last_valid > self.timeout_tenths as f64 * 0.1
        {
            self.timed_out = true;
            self.stats.device_timeouts += 1;
            self.set_m1 = 0;
            self.set_m2 = 0;
            self.ramp = None;
        }
        let dt = (now - self.last_tick).max(0.0);
        self.last_tick = now;
        let (t1, t2) = (self.set_m1 as f64, self.set_m2 as f64);
        self.cur = match self.ramp {
            // Command 40: the controller ramps its set-point at `a` counts/s².
            Some(a) => {
                let dv = a * dt;
                (
                    self.cur.0 + (t1 - self.cur.0).clamp(-dv, dv),
                    self.cur.1 + (t2 - self.cur.1).clamp(-dv, dv),
                )
            }
            None => (t1, t2),
        };
        let v1 = self.cur.0 / self.counts_per_metre;
        let v2 = self.cur.1 / self.counts_per_metre;
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

    fn stats(&self) -> DeviceStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motor::roboclaw::codec::{encode_command, ReplyDecoder};

    fn ask(d: &mut RoboClawDevice, c: Command, now: f64, body: &BodyState) -> Option<Reply> {
        let mut out = Vec::new();
        d.on_bytes(&encode_command(0x80, &c), now, body, &mut out);
        let mut dec = ReplyDecoder::new(0x80, &c);
        out.iter().find_map(|&b| dec.push(b).ok().flatten())
    }

    #[test]
    fn speeds_encoders_and_serial_timeout() {
        let mut d = RoboClawDevice::new(0x80, 1000.0, true);
        let mut body = BodyState::default();
        assert_eq!(
            ask(&mut d, Command::SetSerialTimeout { tenths: 3 }, 0.0, &body),
            Some(Reply::Ack)
        );
        assert_eq!(
            ask(
                &mut d,
                Command::DriveSpeeds { m1: 200, m2: -100 },
                0.0,
                &body
            ),
            Some(Reply::Ack)
        );
        let mut out = Vec::new();
        let w = d.tick(0.1, &body, &mut out);
        assert_eq!(
            w,
            WheelSpeeds {
                left: 0.2,
                right: -0.1
            }
        );
        body.encoder = (0.5, -0.001);
        assert_eq!(
            ask(&mut d, Command::ReadEncoders, 0.2, &body),
            Some(Reply::Encoders {
                m1: 500,
                m2: u32::MAX
            })
        );
        // Silence beyond 0.3 s stops the motors by themselves.
        assert_eq!(
            d.tick(0.45, &body, &mut out),
            WheelSpeeds {
                left: 0.2,
                right: -0.1
            }
        );
        assert_eq!(d.tick(0.55, &body, &mut out), WheelSpeeds::STOP);
        assert_eq!(d.stats().device_timeouts, 1);
    }

    #[test]
    fn command_40_ramps_at_its_acceleration() {
        let mut d = RoboClawDevice::new(0x80, 1000.0, true);
        let body = BodyState::default();
        let mut out = Vec::new();
        d.tick(0.0, &body, &mut out);
        let c = Command::DriveSpeedsAccel {
            accel: 500,
            m1: 200,
            m2: 200,
        };
        assert_eq!(ask(&mut d, c, 0.0, &body), Some(Reply::Ack));
        // 500 counts/s² = 0.5 m/s²: 0.05 m/s after 0.1 s, capped at 0.2.
        let w = d.tick(0.1, &body, &mut out);
        assert!((w.left - 0.05).abs() < 1e-12, "{w:?}");
        let w = d.tick(1.0, &body, &mut out);
        assert!((w.left - 0.2).abs() < 1e-12, "{w:?}");
        // Command 37 stops at once.
        let c = Command::DriveSpeeds { m1: 0, m2: 0 };
        assert_eq!(ask(&mut d, c, 1.0, &body), Some(Reply::Ack));
        assert_eq!(d.tick(1.01, &body, &mut out), WheelSpeeds::STOP);
    }

    #[test]
    fn bad_crc_gets_no_reply_and_is_counted() {
        let mut d = RoboClawDevice::new(0x80, 1000.0, true);
        let mut p = encode_command(0x80, &Command::DriveSpeeds { m1: 1, m2: 1 });
        p[4] ^= 0x10;
        let mut out = Vec::new();
        d.on_bytes(&p, 0.0, &BodyState::default(), &mut out);
        assert!(out.is_empty());
        assert_eq!(d.stats().packets_rejected, 1);
        assert_eq!(
            d.tick(0.0, &BodyState::default(), &mut out),
            WheelSpeeds::STOP
        );
    }

    #[test]
    fn bumper_sets_the_estop_status_bit() {
        let mut d = RoboClawDevice::new(0x80, 1000.0, true);
        let mut body = BodyState::default();
        assert_eq!(
            ask(&mut d, Command::ReadStatus, 0.0, &body),
            Some(Reply::Status(0))
        );
        body.bumper.left = true;
        assert_eq!(
            ask(&mut d, Command::ReadStatus, 0.0, &body),
            Some(Reply::Status(STATUS_ESTOP))
        );
    }
}
