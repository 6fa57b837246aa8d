//! Injected clocks: the driver and the emulator read time only through
//! [`Clock`], so tests and the time-scaled simulator can drive them.

use std::time::{Duration, Instant};

/// A monotonic clock in seconds, with a matching sleep.
pub trait Clock: Send + Sync {
    /// Seconds since an arbitrary fixed origin; never decreases.
    fn now(&self) -> f64;
    /// Sleeps `dt` seconds of this clock's time.
    fn sleep(&self, dt: f64);
    /// How many seconds of this clock pass per real second (1 for real time).
    fn rate(&self) -> f64 {
        1.0
    }
}

/// The host's monotonic clock (`CLOCK_MONOTONIC` through `Instant`).
#[derive(Clone, Copy, Debug)]
pub struct MonotonicClock {
    origin: Instant,
}

impl MonotonicClock {
    /// A clock whose zero is now.
    pub fn new() -> Self {
        Self {
            origin: Instant::now(),
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
        self.origin.elapsed().as_secs_f64()
    }
    fn sleep(&self, dt: f64) {
        if dt > 0.0 && dt.is_finite() {
            std::thread::sleep(Duration::from_secs_f64(dt));
        }
    }
}

/// Real time sped up by `rate` (time-scaled simulation and fast tests): one
/// real second is `rate` seconds of this clock.
#[derive(Clone, Copy, Debug)]
pub struct ScaledClock {
    origin: Instant,
    rate: f64,
}

impl ScaledClock {
    /// A clock running `rate` times faster than real time (`rate` > 0;
    /// anything else is taken as 1).
    pub fn new(rate: f64) -> Self {
        let rate = if rate.is_finite() && rate > 0.0 {
            rate
        } else {
            1.0
        };
        Self {
            origin: Instant::now(),
            rate,
        }
    }
}

impl Clock for ScaledClock {
    fn now(&self) -> f64 {
        self.origin.elapsed().as_secs_f64() * self.rate
    }
    fn sleep(&self, dt: f64) {
        if dt > 0.0 && dt.is_finite() {
            std::thread::sleep(Duration::from_secs_f64(dt / self.rate));
        }
    }
    fn rate(&self) -> f64 {
        self.rate
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
        let c = ScaledClock::new(10.0);
        let t0 = c.now();
        c.sleep(0.2);
        let dt = c.now() - t0;
        assert!((0.19..1.0).contains(&dt), "{dt}");
        assert_eq!(ScaledClock::new(-1.0).rate(), 1.0);
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
}
