//! What the emulated Create 2 measures of its body: encoder counts, distance
//! and angle since they were last read, and its battery.

use crate::base_emu::BodyState;
use crate::motor::WheelSpeeds;

/// Wheel odometry as the robot keeps it.
#[derive(Clone, Debug, Default)]
pub(super) struct WheelTrack {
    /// The body's encoder travel at the last observation (m; the body counts
    /// from 0 at the start).
    last: (f64, f64),
    /// The wheels' speeds at the last observation.
    last_speeds: WheelSpeeds,
    /// Travel the encoders counted since the last reset (m).
    counted: (f64, f64),
    /// Distance since last read (mm, not yet rounded).
    distance_mm: f64,
    /// Angle since last read (degrees, not yet rounded).
    angle_deg: f64,
}

/// Whether a wheel stood still since the last observation: an encoder counts
/// nothing then (the kinematics' encoder noise is not wheel motion).
fn still(now: f64, before: f64) -> bool {
    now == 0.0 && before == 0.0
}

/// Takes a rounded value out of an accumulator as the OI reports it: an i16
/// capped at its extremes when not read often enough (the specification),
/// the sub-unit remainder kept for the next read so repeated reads add up to
/// the true travel (an assumption: the specification does not say).
fn take(acc: &mut f64) -> i16 {
    let v = acc.round();
    if v > f64::from(i16::MAX) || v < f64::from(i16::MIN) {
        *acc = 0.0;
        return if v > 0.0 { i16::MAX } else { i16::MIN };
    }
    *acc -= v;
    v as i16
}

impl WheelTrack {
    /// Accounts for the wheel travel since the last observation.
    pub(super) fn observe(&mut self, body: &BodyState, wheel_base: f64) {
        let (l, r) = body.encoder;
        let (l0, r0) = self.last;
        let w = body.wheels;
        let dl = if still(w.left, self.last_speeds.left) {
            0.0
        } else {
            l - l0
        };
        let dr = if still(w.right, self.last_speeds.right) {
            0.0
        } else {
            r - r0
        };
        if dl.is_finite() && dr.is_finite() {
            self.counted.0 += dl;
            self.counted.1 += dr;
            self.distance_mm += 0.5 * (dl + dr) * 1000.0;
            if wheel_base > 0.0 {
                self.angle_deg += ((dr - dl) / wheel_base).to_degrees();
            }
        }
        self.last = (l, r);
        self.last_speeds = body.wheels;
    }

    /// Encoder counts (left, right) as packets 43 and 44 carry them: wrapping
    /// 16-bit counters.
    pub(super) fn counts(&self, counts_per_metre: f64) -> (u16, u16) {
        let c = |m: f64| (m * counts_per_metre).round() as i64 as u16;
        (c(self.counted.0), c(self.counted.1))
    }

    /// Packet 19 (mm since last read); reading resets it.
    pub(super) fn read_distance(&mut self) -> i16 {
        take(&mut self.distance_mm)
    }

    /// Packet 20 (degrees since last read, counter-clockwise positive);
    /// reading resets it.
    pub(super) fn read_angle(&mut self) -> i16 {
        take(&mut self.angle_deg)
    }

    /// Distance and angle as a read would report them, without resetting.
    pub(super) fn peek(&self) -> (i16, i16) {
        let (mut d, mut a) = (self.distance_mm, self.angle_deg);
        (take(&mut d), take(&mut a))
    }

    /// A reset robot counts from zero again.
    pub(super) fn reset(&mut self) {
        self.counted = (0.0, 0.0);
        self.distance_mm = 0.0;
        self.angle_deg = 0.0;
    }
}

/// Capacity of the emulated pack (mAh): assumed, the specification gives
/// none (Create 2 packs vary).
pub(super) const CAPACITY_MAH: f64 = 3000.0;
/// Current the electronics draw at rest (mA): assumed.
const IDLE_MA: f64 = 180.0;
/// Current one drive motor draws at full speed (mA): assumed.
const WHEEL_MA: f64 = 450.0;

/// The battery: drains with the time the robot is on and its motors' work.
#[derive(Clone, Debug)]
pub(super) struct Battery {
    charge_mah: f64,
    current_ma: f64,
    wheel_ma: (f64, f64),
    last: Option<f64>,
}

impl Default for Battery {
    fn default() -> Self {
        Self {
            charge_mah: CAPACITY_MAH,
            current_ma: -IDLE_MA,
            wheel_ma: (0.0, 0.0),
            last: None,
        }
    }
}

impl Battery {
    /// Lets time pass to `now` with the wheels at `w` (m/s) and the cleaning
    /// motors drawing `brushes_ma`.
    pub(super) fn run(&mut self, now: f64, w: WheelSpeeds, brushes_ma: f64) {
        let wheel = |v: f64| {
            if v == 0.0 || !v.is_finite() {
                0.0
            } else {
                WHEEL_MA * (0.2 + 0.8 * (v.abs() / 0.5).min(1.0))
            }
        };
        self.wheel_ma = (wheel(w.left), wheel(w.right));
        self.current_ma = -(IDLE_MA + self.wheel_ma.0 + self.wheel_ma.1 + brushes_ma);
        if let Some(t0) = self.last {
            let dt = (now - t0).clamp(0.0, 1.0);
            self.charge_mah = (self.charge_mah + self.current_ma * dt / 3600.0).max(0.0);
        }
        self.last = Some(now);
    }

    /// Packet 25 (mAh).
    pub(super) fn charge(&self) -> u16 {
        self.charge_mah.round() as u16
    }

    /// Packet 23 (mA, negative: discharging).
    pub(super) fn current(&self) -> i16 {
        self.current_ma.round().clamp(-32768.0, 32767.0) as i16
    }

    /// Packet 22 (mV): a NiMH pack's 13.2-16 V over its charge, less its
    /// internal resistance times the current (assumed 0.1 Ω).
    pub(super) fn voltage(&self) -> u16 {
        let soc = self.charge_mah / CAPACITY_MAH;
        (13_200.0 + 2_800.0 * soc + 0.1 * self.current_ma).round() as u16
    }

    /// Packets 54 and 55: the drive motors' currents (mA).
    pub(super) fn wheel_currents(&self) -> (i16, i16) {
        (
            self.wheel_ma.0.round() as i16,
            self.wheel_ma.1.round() as i16,
        )
    }
}
