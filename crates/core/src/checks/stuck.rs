//! The control stage's progress watch: a path whose follower makes no
//! headway (it reaches no waypoint and gets no closer to the one it drives
//! to) for `daemon.stuck_after` seconds is given up, so the planner hears that
//! the path ended, charges its floor a try and plans something else. Without
//! it, a follower circling a waypoint it cannot settle on (or a robot held
//! still by anything the map does not explain) keeps the planner on one task
//! for ever, since the planner only re-plans when a path ends or is blocked.

/// Default for `daemon.stuck_after`: clock seconds without headway after
/// which a path is given up.
pub const STUCK_AFTER: f64 = 20.0;
/// Getting this much closer to the waypoint (m) counts as headway.
pub(crate) const HEADWAY: f64 = 0.05;

/// Watches the follower's headway on the current path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgressWatch {
    seq: u64,
    next: usize,
    best: f64,
    since: f64,
    after: f64,
}

impl Default for ProgressWatch {
    fn default() -> Self {
        Self::new(STUCK_AFTER)
    }
}

impl ProgressWatch {
    /// A watch that gives a path up after `after` clock seconds without
    /// headway.
    pub fn new(after: f64) -> Self {
        Self {
            seq: u64::MAX,
            next: usize::MAX,
            best: f64::INFINITY,
            since: 0.0,
            after,
        }
    }

    /// Seconds without headway after which a path is given up.
    pub fn after(&self) -> f64 {
        self.after
    }

    /// One observation at clock time `now`: path `seq`, the waypoint index
    /// `next` driven to and the distance to it (`None`: no waypoint left,
    /// the final turn or idle). True when the path has made no headway for
    /// [`after`](Self::after) seconds; the watch then starts over.
    pub fn stuck(&mut self, now: f64, seq: u64, next: usize, distance: Option<f64>) -> bool {
        let d = distance.filter(|d| d.is_finite()).unwrap_or(f64::INFINITY);
        if seq != self.seq || next != self.next {
            *self = Self {
                seq,
                next,
                best: d,
                since: now,
                after: self.after,
            };
            return false;
        }
        if d < self.best - HEADWAY || (d.is_finite() && !self.best.is_finite()) {
            self.best = d;
            self.since = now;
            return false;
        }
        if now - self.since >= self.after {
            self.since = now;
            self.best = d;
            return true;
        }
        false
    }

    /// Forgets the path (after it was given up or finished).
    pub fn reset(&mut self) {
        *self = Self::new(self.after);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headway_or_a_new_waypoint_keeps_the_path() {
        let mut w = ProgressWatch::default();
        let mut d = 4.0;
        let mut t = 0.0;
        // A long lane at 0.2 m/s: always closer, never stuck.
        while d > 0.0 {
            assert!(!w.stuck(t, 1, 3, Some(d)));
            t += 0.05;
            d -= 0.01;
        }
        // The next waypoint starts a new watch.
        assert!(!w.stuck(t + STUCK_AFTER - 1.0, 1, 4, Some(1.0)));
        assert!(!w.stuck(t + STUCK_AFTER + 1.0, 1, 4, Some(0.9)));
    }

    #[test]
    fn circling_a_waypoint_is_caught_once_per_period() {
        let mut w = ProgressWatch::default();
        let mut caught = Vec::new();
        for k in 0..1000 {
            let t = k as f64 * 0.05;
            // Overshooting back and forth 2-4 cm from the waypoint.
            let d = 0.03 + 0.01 * (k as f64 * 0.7).sin();
            if w.stuck(t, 7, 2, Some(d)) {
                caught.push(t);
            }
        }
        assert_eq!(caught.len(), 2, "{caught:?}");
        assert!((caught[0] - STUCK_AFTER).abs() < 0.1, "{caught:?}");
        // A new path is watched afresh.
        assert!(!w.stuck(60.0, 8, 0, Some(0.03)));
        w.reset();
        assert!(!w.stuck(61.0, 8, 0, None));
        assert!(w.stuck(61.0 + STUCK_AFTER, 8, 0, None));
    }

    #[test]
    fn the_limit_is_the_configured_one() {
        let mut w = ProgressWatch::new(5.0);
        assert!(!w.stuck(0.0, 1, 0, Some(1.0)));
        assert!(!w.stuck(4.9, 1, 0, Some(1.0)));
        assert!(w.stuck(5.0, 1, 0, Some(1.0)));
        w.reset();
        assert_eq!(w.after(), 5.0);
        assert!(!w.stuck(6.0, 1, 0, Some(1.0)));
        assert!(w.stuck(11.0, 1, 0, Some(1.0)));
    }
}
