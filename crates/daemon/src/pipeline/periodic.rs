//! [`Every`]: a timer for work the supervisor does on its tick (checkpoints,
//! heartbeats, metrics files), due once per period however late the tick
//! comes. It runs on the daemon's injected clock (robot time, seconds), read
//! once per tick by the supervisor and passed in as a value: in the
//! simulator at 15 times real time a 2 s checkpoint period is 2 s of the
//! simulated robot's time, as on the robot, not 30 s.

/// Fires once every `period` seconds of the clock it is given, starting one
/// period after the first time it is asked.
#[derive(Clone, Copy, Debug)]
pub struct Every {
    period: f64,
    last: Option<f64>,
}

impl Every {
    /// A timer with period `period` seconds (at least 1 ms; a non-finite
    /// period never fires). It counts from the first [`Every::due`], so it
    /// needs no clock reading to be built.
    pub fn new(period: f64) -> Self {
        let period = if period.is_finite() {
            period.max(0.001)
        } else {
            f64::INFINITY
        };
        Self { period, last: None }
    }

    /// True when a period has passed at clock time `now` (s) since it last
    /// fired (and re-arms); the first call only starts the count.
    pub fn due(&mut self, now: f64) -> bool {
        match self.last {
            None => {
                self.last = Some(now);
                false
            }
            Some(last) if now - last >= self.period => {
                self.last = Some(now);
                true
            }
            Some(_) => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fires_once_per_period() {
        let s = 1.0;
        let mut e = Every::new(2.0);
        assert!(!e.due(s));
        assert!(!e.due(s + 1.999));
        assert!(e.due(s + 2.0));
        assert!(!e.due(s + 2.5));
        assert!(e.due(s + 10.0));
        let mut never = Every::new(f64::NAN);
        assert!(!never.due(s));
        assert!(!never.due(f64::MAX));
    }
}
