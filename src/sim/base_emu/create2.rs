//! An emulated Create 2, sans-IO: Open Interface commands in, sensor stream
//! out, wheel set-points to the kinematics. It keeps the OI modes (Off,
//! Passive, Safe, Full; actuators obey only in Safe and Full), drops from Safe
//! to Passive and stops on a wheel drop as the real robot does, streams the
//! requested packets every 15 ms, and has no command timeout.

use crate::motor::create2::codec::{
    encode_stream_frame, OiCommand, OiDecoder, OiMode, SensorState, MAX_STREAM_IDS,
};
use crate::motor::WheelSpeeds;
use crate::sim::base_emu::{BaseDevice, BodyState, DeviceStats};

/// Stream period (s).
pub const STREAM_PERIOD: f64 = 0.015;

/// An emulated Create 2.
#[derive(Clone, Debug)]
pub struct Create2Device {
    counts_per_metre: f64,
    wheel_base: f64,
    decoder: OiDecoder,
    mode: OiMode,
    speeds: WheelSpeeds,
    ids: heapless::Vec<u8, MAX_STREAM_IDS>,
    streaming: bool,
    next_frame: f64,
    stats: DeviceStats,
}

impl Create2Device {
    /// A robot with its OI off; `counts_per_metre` converts wheel travel to
    /// encoder counts; `wheel_base` (m) serves the radius-based Drive command.
    pub fn new(counts_per_metre: f64, wheel_base: f64) -> Self {
        Self {
            counts_per_metre,
            wheel_base,
            decoder: OiDecoder::new(),
            mode: OiMode::Off,
            speeds: WheelSpeeds::STOP,
            ids: heapless::Vec::new(),
            streaming: false,
            next_frame: 0.0,
            stats: DeviceStats::default(),
        }
    }

    /// The current OI mode.
    pub fn mode(&self) -> OiMode {
        self.mode
    }

    fn sensors(&self, body: &BodyState) -> SensorState {
        let mut bits = 0u8;
        bits |= u8::from(body.bumper.right);
        bits |= u8::from(body.bumper.left) << 1;
        bits |= u8::from(body.wheel_drop.right) << 2;
        bits |= u8::from(body.wheel_drop.left) << 3;
        let enc = |m: f64| (m * self.counts_per_metre).round() as i64 as u16;
        SensorState {
            bumps_drops: bits,
            voltage_mv: 14_800,
            oi_mode: self.mode.to_byte(),
            left_encoder: enc(body.encoder.0),
            right_encoder: enc(body.encoder.1),
        }
    }

    fn actuators(&self) -> bool {
        matches!(self.mode, OiMode::Safe | OiMode::Full)
    }

    fn handle(&mut self, c: OiCommand, now: f64, body: &BodyState, out: &mut Vec<u8>) {
        match c {
            OiCommand::Start => self.mode = OiMode::Passive,
            OiCommand::Safe if self.mode != OiMode::Off => self.mode = OiMode::Safe,
            OiCommand::Full if self.mode != OiMode::Off => self.mode = OiMode::Full,
            OiCommand::Stop | OiCommand::Reset => {
                self.mode = OiMode::Off;
                self.speeds = WheelSpeeds::STOP;
                self.streaming = false;
            }
            OiCommand::DriveDirect { right, left } if self.actuators() => {
                let c = |v: i16| v.clamp(-500, 500) as f64 / 1000.0;
                self.speeds = WheelSpeeds {
                    left: c(left),
                    right: c(right),
                };
            }
            OiCommand::Drive { velocity, radius } if self.actuators() => {
                let v = velocity.clamp(-500, 500) as f64 / 1000.0;
                let half = self.wheel_base / 2.0;
                self.speeds = match radius {
                    32767 | -32768 => WheelSpeeds { left: v, right: v },
                    1 => WheelSpeeds { left: -v, right: v },
                    -1 => WheelSpeeds { left: v, right: -v },
                    r => {
                        let r = r as f64 / 1000.0;
                        WheelSpeeds {
                            left: v * (r - half) / r,
                            right: v * (r + half) / r,
                        }
                    }
                };
            }
            OiCommand::Stream(ids) if self.mode != OiMode::Off => {
                self.ids = ids;
                self.streaming = !self.ids.is_empty();
                self.next_frame = now;
            }
            OiCommand::StreamEnable(on) if self.mode != OiMode::Off => {
                self.streaming = on && !self.ids.is_empty();
                self.next_frame = now;
            }
            OiCommand::Sensors(id) if self.mode != OiMode::Off => self.query(&[id], body, out),
            OiCommand::QueryList(ids) if self.mode != OiMode::Off => self.query(&ids, body, out),
            _ => self.stats.packets_rejected += 1,
        }
    }

    /// Query replies carry the packets' data only: no header, ids or checksum.
    fn query(&self, ids: &[u8], body: &BodyState, out: &mut Vec<u8>) {
        let s = self.sensors(body);
        for &id in ids {
            let f = encode_stream_frame(&[id], &s);
            if f.len() > 4 {
                out.extend_from_slice(&f[3..f.len() - 1]);
            }
        }
    }
}

impl BaseDevice for Create2Device {
    fn on_bytes(&mut self, bytes: &[u8], now: f64, body: &BodyState, out: &mut Vec<u8>) {
        self.stats.bytes_in += bytes.len() as u64;
        for &b in bytes {
            if let Some(c) = self.decoder.push(b) {
                self.stats.packets_ok += 1;
                self.handle(c, now, body, out);
            }
        }
        self.stats.bytes_skipped = self.decoder.skipped;
    }

    fn tick(&mut self, now: f64, body: &BodyState, out: &mut Vec<u8>) -> WheelSpeeds {
        if self.mode == OiMode::Safe && body.wheel_drop.any() {
            // Safe mode's reflex: drop to Passive and stop.
            self.mode = OiMode::Passive;
        }
        if !self.actuators() {
            self.speeds = WheelSpeeds::STOP;
        }
        if self.streaming && now >= self.next_frame {
            let f = encode_stream_frame(&self.ids, &self.sensors(body));
            out.extend_from_slice(&f);
            self.stats.frames_out += 1;
            self.next_frame += STREAM_PERIOD;
            if self.next_frame < now {
                self.next_frame = now + STREAM_PERIOD;
            }
        }
        self.speeds
    }

    fn stats(&self) -> DeviceStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motor::create2::codec::{encode, StreamParser};

    fn send(d: &mut Create2Device, c: OiCommand, now: f64, out: &mut Vec<u8>) {
        d.on_bytes(&encode(&c), now, &BodyState::default(), out);
    }

    #[test]
    fn drive_needs_safe_or_full_mode() {
        let mut d = Create2Device::new(2250.0, 0.235);
        let mut out = Vec::new();
        send(&mut d, OiCommand::drive_direct(0.1, 0.2), 0.0, &mut out);
        assert_eq!(
            d.tick(0.0, &BodyState::default(), &mut out),
            WheelSpeeds::STOP
        );
        send(&mut d, OiCommand::Start, 0.0, &mut out);
        send(&mut d, OiCommand::drive_direct(0.1, 0.2), 0.0, &mut out);
        assert_eq!(
            d.tick(0.0, &BodyState::default(), &mut out),
            WheelSpeeds::STOP
        );
        send(&mut d, OiCommand::Safe, 0.0, &mut out);
        send(&mut d, OiCommand::drive_direct(0.1, 0.2), 0.0, &mut out);
        assert_eq!(
            d.tick(0.0, &BodyState::default(), &mut out),
            WheelSpeeds {
                left: 0.1,
                right: 0.2
            }
        );
    }

    #[test]
    fn wheel_drop_in_safe_mode_drops_to_passive() {
        let mut d = Create2Device::new(2250.0, 0.235);
        let mut out = Vec::new();
        send(&mut d, OiCommand::Start, 0.0, &mut out);
        send(&mut d, OiCommand::Safe, 0.0, &mut out);
        send(&mut d, OiCommand::drive_direct(0.1, 0.1), 0.0, &mut out);
        let mut body = BodyState::default();
        body.wheel_drop.left = true;
        assert_eq!(d.tick(0.1, &body, &mut out), WheelSpeeds::STOP);
        assert_eq!(d.mode(), OiMode::Passive);
    }

    #[test]
    fn full_mode_has_no_wheel_drop_reflex_and_stop_turns_the_oi_off() {
        let mut d = Create2Device::new(2250.0, 0.235);
        let mut out = Vec::new();
        send(&mut d, OiCommand::Start, 0.0, &mut out);
        send(&mut d, OiCommand::Full, 0.0, &mut out);
        send(&mut d, OiCommand::drive_direct(0.1, 0.1), 0.0, &mut out);
        let body = BodyState {
            wheel_drop: crate::motor::Sides {
                left: true,
                right: true,
            },
            ..BodyState::default()
        };
        assert_eq!(
            d.tick(0.1, &body, &mut out),
            WheelSpeeds {
                left: 0.1,
                right: 0.1
            }
        );
        assert_eq!(d.mode(), OiMode::Full);
        send(&mut d, OiCommand::Stop, 0.2, &mut out);
        assert_eq!(d.mode(), OiMode::Off);
        assert_eq!(d.tick(0.3, &body, &mut out), WheelSpeeds::STOP);
        // Off: Safe is ignored until Start.
        send(&mut d, OiCommand::Safe, 0.3, &mut out);
        assert_eq!(d.mode(), OiMode::Off);
    }

    #[test]
    fn query_list_returns_bare_packet_data() {
        let mut d = Create2Device::new(1000.0, 0.235);
        let mut out = Vec::new();
        send(&mut d, OiCommand::Start, 0.0, &mut out);
        let mut ids = heapless::Vec::new();
        ids.extend_from_slice(&[35, 43]).unwrap();
        let body = BodyState {
            encoder: (0.258, 0.0),
            ..BodyState::default()
        };
        d.on_bytes(&encode(&OiCommand::QueryList(ids)), 0.0, &body, &mut out);
        // Mode 1 (Passive), then left encoder 258 = 0x0102: no ids, no checksum.
        assert_eq!(out, vec![1, 0x01, 0x02]);
    }

    #[test]
    fn stream_every_15_ms_with_pause_and_resume() {
        let mut d = Create2Device::new(2250.0, 0.235);
        let mut out = Vec::new();
        send(&mut d, OiCommand::Start, 0.0, &mut out);
        let mut ids = heapless::Vec::new();
        ids.extend_from_slice(&[7, 43, 44]).unwrap();
        send(&mut d, OiCommand::Stream(ids), 0.0, &mut out);
        let body = BodyState {
            encoder: (1.0, -1.0),
            ..BodyState::default()
        };
        let mut t = 0.0;
        while t < 0.15 - 1e-9 {
            d.tick(t, &body, &mut out);
            t += 0.001;
        }
        let mut frames = Vec::new();
        StreamParser::new().feed(&out, &mut |r| frames.push(r.unwrap()));
        assert_eq!(frames.len(), 10);
        assert_eq!(frames[0].left_encoder, Some(2250));
        assert_eq!(frames[0].right_encoder, Some(2250u16.wrapping_neg()));
        out.clear();
        send(&mut d, OiCommand::StreamEnable(false), t, &mut out);
        d.tick(t + 0.1, &body, &mut out);
        assert!(out.is_empty());
        send(&mut d, OiCommand::StreamEnable(true), t + 0.1, &mut out);
        d.tick(t + 0.1, &body, &mut out);
        assert!(!out.is_empty());
    }
}
