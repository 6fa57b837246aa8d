//! Injected time. Every part that reads time or sleeps takes a [`Clock`], so
//! the same code runs in real time on the robot, time-scaled for the emulators
//! (`sweepline emulate --rate N`), paced by the daemon's progress in the
//! simulator ([`PacedClock`]) and stepped in deterministic tests.

use std::sync::Arc;
use std::time::{Duration, Instant};

mod paced;
pub use paced::{PaceStats, PacedClock};

/// A monotonic clock in seconds, with a matching sleep.
pub trait Clock: Send + Sync {
    /// Seconds since this clock's epoch (monotonic, never goes back).
    fn now(&self) -> f64;
    /// Blocks the calling thread for `secs` seconds of this clock's time.
    fn sleep(&self, secs: f64);
    /// How many clock seconds pass per wall-clock second (1 in real time).
    fn speed(&self) -> f64 {
        1.0
    }
    /// Converts a duration of clock time into wall time, for OS timeouts.
    fn to_wall(&self, secs: f64) -> Duration {
        Duration::from_secs_f64((secs / self.speed()).clamp(0.0, 1.0e6))
    }
}

/// A shared clock handle.
pub type SharedClock = Arc<dyn Clock>;

/// The host's monotonic clock (`Instant`), epoch at construction.
#[derive(Debug, Clone, Copy)]
pub struct MonotonicClock {
    epoch: Instant,
}

impl MonotonicClock {
    /// A clock whose epoch is now.
    pub fn new() -> Self {
        Self {
            epoch: Instant::now(),
        }
    }
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for MonotonicClock {
    fn now(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }
    fn sleep(&self, secs: f64) {
        if secs > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(secs.min(1.0e6)));
        }
    }
}

/// Monotonic time running `speed` times faster than the wall clock: the
/// simulator's clock. Both the emulated devices and the daemon read the same
/// instance, so nothing in the daemon knows it is simulated.
#[derive(Debug, Clone, Copy)]
pub struct ScaledClock {
    epoch: Instant,
    speed: f64,
}

impl ScaledClock {
    /// A clock starting now at 0 and running `speed` times real time
    /// (clamped to 0.01..=1000; not a positive number: 1).
    pub fn new(speed: f64) -> Self {
        let speed = if speed.is_finite() && speed > 0.0 {
            speed.clamp(0.01, 1000.0)
        } else {
            1.0
        };
        Self {
            epoch: Instant::now(),
            speed,
        }
    }
}

impl ScaledClock {
    /// A clock running `speed` times real time that read 0 at UNIX time
    /// `epoch` (s): two processes building it from the same pair read the
    /// same time (to the system clock's resolution). An epoch in the future
    /// is taken as now.
    pub fn since_unix(speed: f64, epoch: f64) -> Self {
        let mut c = Self::new(speed);
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0);
        let ago = now - epoch;
        if ago.is_finite() && ago > 0.0 {
            if let Some(e) = c.epoch.checked_sub(Duration::from_secs_f64(ago)) {
                c.epoch = e;
            }
        }
        c
    }
}

impl Clock for ScaledClock {
    fn now(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64() * self.speed
    }
    fn sleep(&self, secs: f64) {
        if secs > 0.0 {
            std::thread::sleep(self.to_wall(secs));
        }
    }
    fn speed(&self) -> f64 {
        self.speed
    }
}

/// A clock that only moves when told to (lock-step simulation, tests):
/// `sleep` advances it instead of waiting.
#[derive(Debug, Default)]
pub struct ManualClock {
    bits: std::sync::atomic::AtomicU64,
}

impl ManualClock {
    /// A clock reading `t` seconds.
    pub fn new(t: f64) -> Self {
        Self {
            bits: std::sync::atomic::AtomicU64::new(t.to_bits()),
        }
    }

    /// Sets the time; a value earlier than now is ignored (monotonic).
    pub fn set(&self, t: f64) {
        use std::sync::atomic::Ordering::Relaxed;
        let _ = self.bits.fetch_update(Relaxed, Relaxed, |b| {
            (t > f64::from_bits(b)).then_some(t.to_bits())
        });
    }

    /// Moves the time forward by `dt` seconds.
    pub fn advance(&self, dt: f64) {
        if dt > 0.0 && dt.is_finite() {
            self.set(self.now() + dt);
        }
    }
}

impl Clock for ManualClock {
    fn now(&self) -> f64 {
        f64::from_bits(self.bits.load(std::sync::atomic::Ordering::Relaxed))
    }
    fn sleep(&self, dt: f64) {
        self.advance(dt);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_clock_runs_faster() {
        let c = ScaledClock::new(20.0);
        let t0 = c.now();
        c.sleep(0.2);
        let dt = c.now() - t0;
        assert!(dt >= 0.2, "slept {dt}");
        assert_eq!(c.to_wall(2.0), Duration::from_millis(100));
    }

    #[test]
    fn clocks_from_one_unix_epoch_agree() {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64();
        let a = ScaledClock::since_unix(10.0, now - 3.0);
        let b = ScaledClock::since_unix(10.0, now - 3.0);
        assert!((a.now() - 30.0).abs() < 0.5, "{}", a.now());
        assert!((a.now() - b.now()).abs() < 0.01);
        assert!(ScaledClock::since_unix(10.0, now + 100.0).now() < 0.5);
    }

    #[test]
    fn manual_clock_moves_only_forward() {
        let c = ManualClock::new(1.0);
        c.sleep(0.5);
        assert_eq!(c.now(), 1.5);
        c.set(1.0);
        assert_eq!(c.now(), 1.5);
        c.advance(f64::NAN);
        assert_eq!(c.now(), 1.5);
    }

    #[test]
    fn silly_speeds_are_clamped() {
        assert_eq!(ScaledClock::new(f64::NAN).speed(), 1.0);
        assert_eq!(ScaledClock::new(1e9).speed(), 1000.0);
        assert_eq!(ScaledClock::new(-1.0).speed(), 1.0);
    }
}
