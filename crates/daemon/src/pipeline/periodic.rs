//! Timers on the monotonic clock: [`Every`] for work the supervisor does on
//! its tick (checkpoints, metrics files), due once per period however late
//! the tick comes; [`Ticker`] for a fixed-rate stage (control at 20 Hz) to
//! use in its `wait`.

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

/// A fixed-rate schedule for a stage's [`Stage::wait`](super::Stage::wait):
/// waits until the next deadline but never longer than the poll timeout, and
/// after a stall skips the missed deadlines (counted) instead of bursting.
#[derive(Clone, Copy, Debug)]
pub struct Ticker {
    period: Duration,
    next: Stamp,
    missed: u64,
}

impl Ticker {
    /// A ticker firing every `period` (at least 1 µs), first at `start + period`.
    pub fn new(period: Duration, start: Stamp) -> Self {
        let period = period.max(Duration::from_micros(1));
        Self {
            period,
            next: start.after(period),
            missed: 0,
        }
    }

    /// Sleeps until the next deadline or `timeout`, whichever is sooner;
    /// true when the deadline has come (the stage should run a step).
    pub fn wait(&mut self, timeout: Duration) -> bool {
        let now = Stamp::now();
        if now < self.next {
            std::thread::sleep(self.next.since(now).min(timeout));
        }
        self.fire(Stamp::now())
    }

    /// The non-sleeping part of [`Ticker::wait`]: fires if `now` has reached
    /// the deadline, and re-arms.
    pub fn fire(&mut self, now: Stamp) -> bool {
        if now < self.next {
            return false;
        }
        let late = now.since(self.next);
        let skipped = (late.as_nanos() / self.period.as_nanos()) as u64;
        self.missed += skipped;
        self.next = self.next.after(
            self.period
                .saturating_mul(u32::try_from(skipped + 1).unwrap_or(u32::MAX)),
        );
        true
    }

    /// Deadlines skipped because the stage was late by whole periods.
    pub fn missed(&self) -> u64 {
        self.missed
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

    #[test]
    fn ticker_keeps_its_rate_and_counts_missed_deadlines() {
        let ms = Duration::from_millis;
        let s = Stamp(1_000_000_000);
        let mut t = Ticker::new(ms(50), s);
        assert!(!t.fire(s.after(ms(49))));
        assert!(t.fire(s.after(ms(50))));
        assert!(!t.fire(s.after(ms(60))));
        assert!(t.fire(s.after(ms(101))));
        assert_eq!(t.missed(), 0);
        // 3.2 periods late (deadlines 150..300 passed): fires once, three skipped,
        // and stays on the 50 ms grid.
        assert!(t.fire(s.after(ms(310))));
        assert_eq!(t.missed(), 3);
        assert!(!t.fire(s.after(ms(349))));
        assert!(t.fire(s.after(ms(350))));
        // Real sleeping: a short timeout returns before the deadline.
        let mut r = Ticker::new(ms(200), Stamp::now());
        assert!(!r.wait(ms(1)));
        let mut r = Ticker::new(ms(5), Stamp::now());
        assert!(r.wait(ms(1000)));
    }
}
