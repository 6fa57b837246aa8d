//! A period timer for work the supervisor does on its tick (checkpoints,
//! metrics files): due once per period on the monotonic clock, never twice
//! for one period however late the tick comes.

use std::time::Duration;

use super::clock::Stamp;

/// Fires once every `period`, starting one period after `start`.
#[derive(Clone, Copy, Debug)]
pub struct Every {
    period: Duration,
    last: Stamp,
}

impl Every {
    /// A timer with period `period` seconds (clamped to at least 1 ms; a
    /// non-finite period never fires), counting from `start`.
    pub fn new(period: f64, start: Stamp) -> Self {
        let period = if period.is_finite() {
            Duration::from_secs_f64(period.max(0.001))
        } else {
            Duration::MAX
        };
        Self {
            period,
            last: start,
        }
    }

    /// True when a period has passed since it last fired (and re-arms).
    pub fn due(&mut self, now: Stamp) -> bool {
        if now.since(self.last) >= self.period {
            self.last = now;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fires_once_per_period() {
        let s = Stamp(1_000_000_000);
        let mut e = Every::new(2.0, s);
        assert!(!e.due(s));
        assert!(!e.due(s.after(Duration::from_millis(1999))));
        assert!(e.due(s.after(Duration::from_secs(2))));
        assert!(!e.due(s.after(Duration::from_millis(2500))));
        assert!(e.due(s.after(Duration::from_secs(10))));
        let mut never = Every::new(f64::NAN, s);
        assert!(!never.due(Stamp(u64::MAX)));
    }
}
