//! The wheel-command side every driver shares: the requested set-point
//! (checked and clamped), the dead-man timer, the bumper/wheel-drop gate, and
//! the safety events waiting for the next poll. A driver owns one and asks it
//! what may be sent; how it is sent is the driver's business.

use crate::motor::safety::{DeadMan, SafetyGate};
use crate::motor::{
    BaseFeedback, LinkHealth, MotorError, Odometry, SafetyEvent, Sides, WheelSpeeds,
};

/// Requested wheel speeds, dead-man, safety gate and pending safety events.
#[derive(Clone, Debug)]
pub(crate) struct WheelCommand {
    /// The last accepted set-point (clamped), before the dead-man and gate.
    pub requested: WheelSpeeds,
    /// Stops the wheels when commands stop arriving.
    pub deadman: DeadMan,
    /// Bumper and wheel-drop latch.
    pub gate: SafetyGate,
    deadman_time: f64,
    max_wheel_speed: f64,
    pending: heapless::Vec<SafetyEvent, 8>,
}

impl WheelCommand {
    /// Nothing requested yet (the dead-man starts tripped); set-points are
    /// clamped to ±`max_wheel_speed` (m/s), the dead-man runs out after
    /// `deadman_time` (s).
    pub fn new(max_wheel_speed: f64, deadman_time: f64) -> Self {
        Self {
            requested: WheelSpeeds::STOP,
            deadman: DeadMan::new(deadman_time),
            gate: SafetyGate::new(),
            deadman_time,
            max_wheel_speed,
            pending: heapless::Vec::new(),
        }
    }

    /// Takes a new set-point at `now`: rejects non-finite speeds, clamps each
    /// wheel to the speed limit and feeds the dead-man.
    pub fn accept(&mut self, cmd: WheelSpeeds, now: f64) -> Result<(), MotorError> {
        if !cmd.is_finite() {
            return Err(MotorError::BadCommand {
                left: cmd.left,
                right: cmd.right,
            });
        }
        let m = self.max_wheel_speed;
        self.requested = WheelSpeeds {
            left: cmd.left.clamp(-m, m),
            right: cmd.right.clamp(-m, m),
        };
        self.deadman.feed(now);
        Ok(())
    }

    /// The set-point that may be sent now: stop while the dead-man is tripped,
    /// else the request as the safety gate lets it through.
    pub(crate) fn effective(&self) -> WheelSpeeds {
        if self.deadman.tripped() {
            WheelSpeeds::STOP
        } else {
            self.gate.filter(self.requested)
        }
    }

    /// Checks the dead-man at `now`; when it just ran out, counts and logs the
    /// stop, queues [`SafetyEvent::DeadMan`] and returns `true`.
    pub(crate) fn check_deadman(&mut self, now: f64, health: &mut LinkHealth) -> bool {
        if !self.deadman.check(now) {
            return false;
        }
        health.deadman_stops += 1;
        log::warn!("wheel base: no wheel command for more than the dead-man time; wheels stopped");
        self.push(SafetyEvent::DeadMan);
        true
    }

    /// Updates the bumper state; on a newly closed bumper counts and logs the
    /// safety stop and returns `true` (the driver must send
    /// [`WheelCommand::effective`] now). Any change is queued as an event.
    pub(crate) fn set_bumper(&mut self, s: Sides, health: &mut LinkHealth) -> bool {
        let Some(e) = self.gate.set_bumper(s) else {
            return false;
        };
        let stop = matches!(e, SafetyEvent::Bumper(_));
        if stop {
            log::warn!("wheel base: bumper closed ({s:?}); wheels stopped");
            health.safety_stops += 1;
        }
        self.push(e);
        stop
    }

    /// Updates the wheel-drop state, as [`WheelCommand::set_bumper`] does the
    /// bumper's.
    pub(crate) fn set_wheel_drop(&mut self, s: Sides, health: &mut LinkHealth) -> bool {
        let Some(e) = self.gate.set_wheel_drop(s) else {
            return false;
        };
        let stop = matches!(e, SafetyEvent::WheelDrop(_));
        if stop {
            log::warn!("wheel base: wheel drop ({s:?}); wheels stopped");
            health.safety_stops += 1;
        }
        self.push(e);
        stop
    }

    /// Forgets the request and re-arms the dead-man tripped: after an explicit
    /// stop nothing moves until a fresh command arrives.
    pub fn halt(&mut self) {
        self.requested = WheelSpeeds::STOP;
        self.deadman = DeadMan::new(self.deadman_time);
    }

    /// Queues a safety event for the next feedback (a ninth is dropped).
    pub fn push(&mut self, e: SafetyEvent) {
        let _ = self.pending.push(e);
    }

    /// The feedback of one poll, carrying (and clearing) the queued events.
    pub(crate) fn feedback(
        &mut self,
        odometry: Option<Odometry>,
        link_up: bool,
        battery: Option<f64>,
    ) -> BaseFeedback {
        BaseFeedback {
            odometry,
            events: std::mem::take(&mut self.pending),
            link_up,
            battery,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accept_rejects_non_finite_and_clamps() {
        let mut c = WheelCommand::new(0.5, 0.25);
        assert!(matches!(
            c.accept(
                WheelSpeeds {
                    left: f64::NAN,
                    right: 0.0
                },
                1.0
            ),
            Err(MotorError::BadCommand { .. })
        ));
        assert_eq!(c.effective(), WheelSpeeds::STOP, "nothing accepted yet");
        c.accept(
            WheelSpeeds {
                left: 2.0,
                right: -0.2,
            },
            1.0,
        )
        .unwrap();
        assert_eq!(
            c.effective(),
            WheelSpeeds {
                left: 0.5,
                right: -0.2
            }
        );
    }

    #[test]
    fn deadman_and_gate_hold_the_wheels() {
        let mut c = WheelCommand::new(1.0, 0.25);
        let mut h = LinkHealth::default();
        c.accept(
            WheelSpeeds {
                left: 0.3,
                right: 0.3,
            },
            1.0,
        )
        .unwrap();
        assert!(!c.check_deadman(1.2, &mut h));
        let bumped = Sides {
            left: true,
            right: false,
        };
        assert!(c.set_bumper(bumped, &mut h), "a closing bumper stops");
        assert!(!c.set_bumper(bumped, &mut h), "no change, no stop");
        assert_eq!(h.safety_stops, 1);
        assert_eq!(c.effective(), WheelSpeeds::STOP, "bumper blocks forward");
        assert!(!c.set_bumper(Sides::default(), &mut h), "release");
        assert!(c.set_wheel_drop(bumped, &mut h));
        assert_eq!(h.safety_stops, 2);
        assert_eq!(
            c.effective(),
            WheelSpeeds::STOP,
            "a dropped wheel holds all"
        );
        assert!(!c.set_wheel_drop(Sides::default(), &mut h));
        assert_eq!(
            c.effective(),
            WheelSpeeds {
                left: 0.3,
                right: 0.3
            }
        );
        assert!(c.check_deadman(1.3, &mut h));
        assert_eq!(h.deadman_stops, 1);
        assert_eq!(c.effective(), WheelSpeeds::STOP);
        let fb = c.feedback(None, true, Some(12.0));
        assert_eq!(
            fb.events.as_slice(),
            &[
                SafetyEvent::Bumper(bumped),
                SafetyEvent::BumperReleased,
                SafetyEvent::WheelDrop(bumped),
                SafetyEvent::WheelDropCleared,
                SafetyEvent::DeadMan
            ]
        );
        assert!(c.feedback(None, true, None).events.is_empty());
    }

    #[test]
    fn halt_forgets_the_request_until_a_new_command() {
        let mut c = WheelCommand::new(1.0, 0.25);
        c.accept(
            WheelSpeeds {
                left: 0.3,
                right: 0.1,
            },
            1.0,
        )
        .unwrap();
        c.halt();
        assert_eq!(c.requested, WheelSpeeds::STOP);
        assert!(c.deadman.tripped());
        c.accept(
            WheelSpeeds {
                left: 0.3,
                right: 0.1,
            },
            2.0,
        )
        .unwrap();
        assert_eq!(
            c.effective(),
            WheelSpeeds {
                left: 0.3,
                right: 0.1
            }
        );
    }
}
