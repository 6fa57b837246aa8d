//! The simulator's paced clock: simulated time runs up to `speed` times the
//! wall clock, but never further than `lead` seconds past a scan the daemon
//! has not yet processed. A loaded host (or a slow debug build) then slows
//! the whole simulated world down instead of starving the daemon: the
//! emulated scanner and wheel base wait for it, as the real ones would
//! never have to, because on the robot the daemon runs in real time.
//!
//! The simulator tells the clock when the emulated scanner hands a scan
//! out ([`PacedClock::pending`]) and the daemon tells it when a scan is
//! through localisation ([`PacedClock::done`], keyed by the scan's stamp).
//! A scan the daemon never reports (dropped in transit, cut by an injected
//! fault) holds time for at most `max_hold` of wall time; a stamp of
//! infinity says the daemon stops processing scans, and time runs free.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use super::Clock;

/// Two scans whose stamps are closer than this are taken as one (s): the
/// URG-04LX scans every 100 ms, the daemon's stamp of a scan lies within a
/// few ms of the emulator's.
const SAME_SCAN: f64 = 0.05;

/// What the pacing did over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PaceStats {
    /// Scans the clock was held for (the daemon was behind when the clock
    /// reached the scan's limit).
    pub holds: u64,
    /// Wall time the clock stood still in all (s).
    pub held_wall: f64,
    /// Holds given up after `max_hold` (a scan the daemon never reported).
    pub timeouts: u64,
    /// Scans handed out.
    pub scans: u64,
}

/// A scan handed out and not yet reported processed.
#[derive(Clone, Copy, Debug)]
struct Pending {
    /// The scan's stamp (clock s).
    stamp: f64,
    /// The clock may not pass this until the scan is processed.
    limit: f64,
    /// When the clock first stood at `limit` (wall).
    held_since: Option<Instant>,
}

#[derive(Debug)]
struct State {
    base_wall: Instant,
    base_sim: f64,
    pending: VecDeque<Pending>,
    stats: PaceStats,
    /// The daemon processes no more scans: nothing is held any more.
    closed: bool,
}

/// Simulated time paced by the daemon's progress (see the module docs).
#[derive(Debug)]
pub struct PacedClock {
    speed: f64,
    lead: f64,
    max_hold: Duration,
    state: Mutex<State>,
    moved: Condvar,
}

impl PacedClock {
    /// A clock at 0 now, running at most `speed` times the wall clock
    /// (clamped to 0.01..=1000; not a positive number: 1), held `lead` s
    /// past an unprocessed scan, for at most `max_hold` of wall time per scan.
    pub fn new(speed: f64, lead: f64, max_hold: Duration) -> Self {
        let speed = if speed.is_finite() && speed > 0.0 {
            speed.clamp(0.01, 1000.0)
        } else {
            1.0
        };
        Self {
            speed,
            lead: lead.max(0.0),
            max_hold,
            state: Mutex::new(State {
                base_wall: Instant::now(),
                base_sim: 0.0,
                pending: VecDeque::with_capacity(64),
                stats: PaceStats::default(),
                closed: false,
            }),
            moved: Condvar::new(),
        }
    }

    /// A scan stamped `stamp` was handed out now: time may run at most
    /// `lead` s further until [`PacedClock::done`] reports it.
    pub fn pending(&self, stamp: f64) {
        let mut s = self.lock();
        let now = self.now_locked(&mut s);
        s.stats.scans += 1;
        if s.closed {
            return;
        }
        s.pending.push_back(Pending {
            stamp,
            limit: now + self.lead,
            held_since: None,
        });
    }

    /// The daemon processed the scan stamped `stamp`: it and every earlier
    /// one release the clock. Infinity: the daemon will process no more.
    pub fn done(&self, stamp: f64) {
        let mut s = self.lock();
        s.closed |= stamp == f64::INFINITY;
        // Time that stood still resumes from where it stood.
        self.now_locked(&mut s);
        let before = s.pending.len();
        while s
            .pending
            .front()
            .is_some_and(|p| p.stamp <= stamp + SAME_SCAN)
        {
            let p = s.pending.pop_front();
            if let Some(since) = p.and_then(|p| p.held_since) {
                s.stats.held_wall += since.elapsed().as_secs_f64();
            }
        }
        if s.pending.len() != before {
            self.moved.notify_all();
        }
    }

    /// What the pacing did so far.
    pub fn stats(&self) -> PaceStats {
        self.lock().stats
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The current time, holding at the oldest pending scan's limit.
    fn now_locked(&self, s: &mut State) -> f64 {
        let wall = Instant::now();
        let free = s.base_sim + wall.duration_since(s.base_wall).as_secs_f64() * self.speed;
        loop {
            let Some(p) = s.pending.front_mut() else {
                return free;
            };
            if free <= p.limit {
                return free;
            }
            let since = *p.held_since.get_or_insert(wall);
            if wall.duration_since(since) >= self.max_hold {
                s.stats.timeouts += 1;
                s.stats.held_wall += wall.duration_since(since).as_secs_f64();
                s.pending.pop_front();
                continue;
            }
            if since == wall {
                s.stats.holds += 1;
            }
            // Stand still at the limit: when released, time runs on from it.
            let limit = p.limit;
            s.base_sim = limit;
            s.base_wall = wall;
            return limit;
        }
    }
}

impl Clock for PacedClock {
    fn now(&self) -> f64 {
        let mut s = self.lock();
        self.now_locked(&mut s)
    }

    fn sleep(&self, secs: f64) {
        if !(secs > 0.0 && secs.is_finite()) {
            return;
        }
        let mut s = self.lock();
        let target = self.now_locked(&mut s) + secs;
        loop {
            let now = self.now_locked(&mut s);
            if now >= target {
                return;
            }
            let wall = Duration::from_secs_f64(((target - now) / self.speed).min(1.0e6))
                .max(Duration::from_micros(20));
            // Woken early by a release; otherwise sleeps out the wall time.
            s = match self.moved.wait_timeout(s, wall) {
                Ok((g, _)) => g,
                Err(e) => e.into_inner().0,
            };
        }
    }

    fn speed(&self) -> f64 {
        self.speed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn runs_free_without_pending_scans() {
        let c = PacedClock::new(20.0, 0.1, ms(500));
        c.sleep(0.4);
        let t = c.now();
        assert!(t >= 0.4, "{t}");
        assert_eq!(c.stats().holds, 0);
    }

    #[test]
    fn an_unprocessed_scan_holds_time_until_done() {
        let c = PacedClock::new(100.0, 0.2, Duration::from_secs(5));
        c.pending(0.0);
        std::thread::sleep(ms(20)); // 2 s of free time at ×100
        let held = c.now();
        assert!((held - 0.2).abs() < 0.01, "held at {held}");
        std::thread::sleep(ms(5));
        assert_eq!(c.now(), held, "time moved while held");
        c.done(0.0);
        std::thread::sleep(ms(5));
        let after = c.now();
        // Resumes from where it stood, not from where it would have been.
        assert!(after > held && after < held + 1.5, "{held} -> {after}");
        let st = c.stats();
        assert_eq!((st.holds, st.timeouts, st.scans), (1, 0, 1));
        assert!(st.held_wall > 0.0);
    }

    #[test]
    fn a_sleeper_wakes_when_the_scan_is_done() {
        let c = std::sync::Arc::new(PacedClock::new(100.0, 0.1, Duration::from_secs(5)));
        c.pending(0.0);
        let c2 = c.clone();
        let sleeper = std::thread::spawn(move || {
            c2.sleep(0.5);
            c2.now()
        });
        std::thread::sleep(ms(30));
        assert!(!sleeper.is_finished(), "slept through a hold");
        c.done(0.01);
        let t = sleeper.join().unwrap();
        assert!(t >= 0.5, "{t}");
    }

    #[test]
    fn a_daemon_that_stops_holds_nothing_any_more() {
        let c = PacedClock::new(100.0, 0.1, Duration::from_secs(5));
        c.pending(0.0);
        c.done(f64::INFINITY);
        c.pending(0.1);
        c.sleep(1.0);
        assert_eq!(c.stats().holds, 0);
    }

    #[test]
    fn a_scan_never_reported_holds_only_max_hold() {
        let c = PacedClock::new(100.0, 0.1, ms(20));
        c.pending(0.0);
        c.sleep(1.0);
        let st = c.stats();
        assert_eq!(st.timeouts, 1);
        assert!(c.now() >= 1.0);
    }

    #[test]
    fn a_later_scan_done_releases_earlier_ones_and_time_never_goes_back() {
        let c = PacedClock::new(50.0, 0.05, Duration::from_secs(5));
        let mut last = 0.0;
        for k in 0..5 {
            c.pending(k as f64 * 0.1);
            let t = c.now();
            assert!(t >= last);
            last = t;
        }
        std::thread::sleep(ms(10));
        c.done(0.4);
        std::thread::sleep(ms(10));
        assert!(c.now() > last);
        assert_eq!(c.lock().pending.len(), 0);
    }
}
