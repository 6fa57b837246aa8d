//! Host-side safety logic, pure and clocked by the caller: the dead-man timer
//! and the bumper/wheel-drop gate that overrides wheel commands.

use crate::motor::{SafetyEvent, Sides, WheelSpeeds};

/// Stops the wheels when no fresh command arrived within `timeout` seconds.
#[derive(Clone, Debug)]
pub struct DeadMan {
    timeout: f64,
    last_feed: Option<f64>,
    tripped: bool,
}

impl DeadMan {
    /// A dead-man with the given timeout (s); it starts tripped (no command yet).
    pub fn new(timeout: f64) -> Self {
        Self {
            timeout,
            last_feed: None,
            tripped: true,
        }
    }

    /// A fresh command arrived at `now`.
    pub fn feed(&mut self, now: f64) {
        self.last_feed = Some(now);
        self.tripped = false;
    }

    /// Checks at `now`: `true` exactly once when the timer runs out.
    pub fn check(&mut self, now: f64) -> bool {
        if self.tripped {
            return false;
        }
        match self.last_feed {
            Some(t) if now - t <= self.timeout => false,
            _ => {
                self.tripped = true;
                true
            }
        }
    }

    /// Whether the wheels must be held stopped.
    pub(crate) fn tripped(&self) -> bool {
        self.tripped
    }
}

/// Bumper and wheel-drop latch: while a bumper is closed only reversing (no
/// wheel forward) is let through; while a wheel is dropped nothing moves.
#[derive(Clone, Debug, Default)]
pub(crate) struct SafetyGate {
    bumper: Sides,
    drop: Sides,
}

impl SafetyGate {
    /// A gate with nothing active.
    pub fn new() -> Self {
        Self::default()
    }

    /// Updates the bumper state; returns the event on a change.
    pub(crate) fn set_bumper(&mut self, s: Sides) -> Option<SafetyEvent> {
        let was = self.bumper;
        self.bumper = s;
        match (was.any(), s.any()) {
            (_, true) if s != was => Some(SafetyEvent::Bumper(s)),
            (true, false) => Some(SafetyEvent::BumperReleased),
            _ => None,
        }
    }

    /// Updates the wheel-drop state; returns the event on a change.
    pub(crate) fn set_wheel_drop(&mut self, s: Sides) -> Option<SafetyEvent> {
        let was = self.drop;
        self.drop = s;
        match (was.any(), s.any()) {
            (_, true) if s != was => Some(SafetyEvent::WheelDrop(s)),
            (true, false) => Some(SafetyEvent::WheelDropCleared),
            _ => None,
        }
    }

    /// Whether a bumper or wheel drop is active.
    pub fn active(&self) -> bool {
        self.bumper.any() || self.drop.any()
    }

    /// The command that may actually be sent instead of `cmd`.
    pub fn filter(&self, cmd: WheelSpeeds) -> WheelSpeeds {
        if self.drop.any() {
            return WheelSpeeds::STOP;
        }
        if self.bumper.any() && (cmd.left > 0.0 || cmd.right > 0.0) {
            return WheelSpeeds::STOP;
        }
        cmd
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deadman_fires_once_after_timeout() {
        let mut d = DeadMan::new(0.25);
        assert!(d.tripped());
        d.feed(1.0);
        assert!(!d.check(1.2));
        assert!(!d.tripped());
        assert!(d.check(1.26));
        assert!(!d.check(1.3));
        assert!(d.tripped());
        d.feed(2.0);
        assert!(!d.tripped());
    }

    #[test]
    fn bumper_allows_only_reversing() {
        let mut g = SafetyGate::new();
        let fwd = WheelSpeeds {
            left: 0.1,
            right: 0.1,
        };
        let back = WheelSpeeds {
            left: -0.1,
            right: -0.05,
        };
        let spin = WheelSpeeds {
            left: -0.1,
            right: 0.1,
        };
        assert_eq!(g.filter(fwd), fwd);
        let e = g.set_bumper(Sides {
            left: true,
            right: false,
        });
        assert_eq!(
            e,
            Some(SafetyEvent::Bumper(Sides {
                left: true,
                right: false
            }))
        );
        assert_eq!(
            g.set_bumper(Sides {
                left: true,
                right: false
            }),
            None
        );
        assert_eq!(g.filter(fwd), WheelSpeeds::STOP);
        assert_eq!(g.filter(spin), WheelSpeeds::STOP);
        assert_eq!(g.filter(back), back);
        assert_eq!(
            g.set_bumper(Sides::default()),
            Some(SafetyEvent::BumperReleased)
        );
        assert_eq!(g.filter(fwd), fwd);
    }

    #[test]
    fn wheel_drop_blocks_everything() {
        let mut g = SafetyGate::new();
        assert!(matches!(
            g.set_wheel_drop(Sides {
                left: false,
                right: true
            }),
            Some(SafetyEvent::WheelDrop(_))
        ));
        assert_eq!(
            g.filter(WheelSpeeds {
                left: -0.1,
                right: -0.1
            }),
            WheelSpeeds::STOP
        );
        assert_eq!(
            g.set_wheel_drop(Sides::default()),
            Some(SafetyEvent::WheelDropCleared)
        );
        assert!(!g.active());
    }
}
