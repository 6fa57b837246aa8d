//! Differential-drive kinematics for the simulator: wheel set-points in, true
//! pose, encoder travel and bumper contact out. Wheels follow their set-points
//! under an acceleration limit; the floor lets them slip (the ground travel
//! differs from what the encoders count) and the encoders add noise, both from
//! a seeded generator. Time is injected: the caller passes each step's `dt`.
//!
//! Contact: the robot is a disk of the robot's radius; a step that would put
//! it onto non-free floor of the collision [`World`] is not taken (the wheels
//! stall), and the front bumper is closed while something touches the front
//! half of the body.

use nalgebra::Point2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::geom::{heading, polar, Pose};
use crate::motor::odometry::arc_increment;
use crate::motor::{Sides, WheelSpeeds};
use crate::walker::{covers, touches, Body};
use crate::world::World;

/// Physical and noise parameters of the simulated base (serde-ready for a
/// simulator config table; unknown keys are errors).
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct KinematicsParams {
    /// Distance between the wheels' contact points (m).
    pub wheel_base: f64,
    /// Radius of the robot's circular body (m), for contact.
    pub body_radius: f64,
    /// Wheel acceleration limit (m/s²).
    pub max_accel: f64,
    /// Fastest wheel speed the motors reach (m/s).
    pub max_wheel_speed: f64,
    /// Slip: standard deviation of ground travel relative to wheel travel
    /// (dimensionless, per unit of travel), drawn per wheel per step.
    pub slip: f64,
    /// Systematic ground-travel error of the left and right wheel (worn or
    /// mis-measured tyres: 0.002 = the wheel covers 0.2 % more floor than its
    /// encoder counts). Makes odometry drift the way real bases do.
    pub scale_error: (f64, f64),
    /// Standard deviation of encoder noise per step (m of wheel travel).
    pub encoder_noise: f64,
    /// How far beyond the body the bumper senses contact (m).
    pub bumper_margin: f64,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl Default for KinematicsParams {
    fn default() -> Self {
        Self {
            wheel_base: 0.235,
            body_radius: 0.17,
            max_accel: 1.0,
            max_wheel_speed: 0.5,
            slip: 0.01,
            scale_error: (0.002, -0.001),
            encoder_noise: 2e-5,
            bumper_margin: 0.02,
            seed: 1,
        }
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepOutcome {
    /// The step was refused because the body would have hit something.
    pub blocked: bool,
    /// Bumper state after the step.
    pub bumper: Sides,
}

/// A simulated differential-drive base.
#[derive(Clone, Debug)]
pub struct DiffDriveSim {
    params: KinematicsParams,
    pose: Pose,
    wheel: WheelSpeeds,
    encoder: (f64, f64),
    bumper: Sides,
    rng: ChaCha8Rng,
    /// Share of each wheel's travel lost to the floor (a slip burst).
    loss: (f64, f64),
}

impl DiffDriveSim {
    /// A base at rest at `start`.
    pub fn new(params: KinematicsParams, start: Pose) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(params.seed);
        Self {
            params,
            pose: start,
            wheel: WheelSpeeds::STOP,
            encoder: (0.0, 0.0),
            bumper: Sides::default(),
            rng,
            loss: (0.0, 0.0),
        }
    }

    /// Makes each wheel cover this share (left, right) less floor than
    /// its encoder counts, until set back to (0, 0): a slip burst on a rug
    /// or a wet patch. Shares are clamped to 0..=1.
    pub fn set_slip_loss(&mut self, loss: (f64, f64)) {
        self.loss = (loss.0.clamp(0.0, 1.0), loss.1.clamp(0.0, 1.0));
    }

    /// Moves the body `dx` ahead and `dy` to the left of where it stands
    /// and turns it by `turn` (rad), at once and with nothing counted by
    /// the encoders: a person lifting the robot and putting it down
    /// elsewhere, or (no move) a knock that turns it. When that spot is
    /// not free, the same move is tried turned by a quarter, a half and
    /// three quarters of a turn. Returns the move made (robot frame), or
    /// `None` when no spot was free.
    pub fn displace(
        &mut self,
        dx: f64,
        dy: f64,
        turn: f64,
        world: Option<&World>,
    ) -> Option<(f64, f64)> {
        for k in 0..4 {
            let (s, c) = (f64::from(k) * std::f64::consts::FRAC_PI_2).sin_cos();
            let (mx, my) = (c * dx - s * dy, s * dx + c * dy);
            let to = self.pose * crate::geom::pose(mx, my, 0.0);
            let at = Point2::from(to.translation.vector);
            if world.is_none_or(|w| w.disk_is_free(&at, self.params.body_radius)) {
                self.pose = to * crate::geom::pose(0.0, 0.0, turn);
                self.wheel = WheelSpeeds::STOP;
                return Some((mx, my));
            }
        }
        None
    }

    /// The true pose (ground truth).
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// Current wheel surface speeds (m/s).
    pub(crate) fn wheel_speeds(&self) -> WheelSpeeds {
        self.wheel
    }

    /// Wheel travel counted by the encoders since start (m, left and right).
    pub fn encoder_travel(&self) -> (f64, f64) {
        self.encoder
    }

    /// Bumper state after the last step.
    pub fn bumper(&self) -> Sides {
        self.bumper
    }

    fn gauss(&mut self) -> f64 {
        super::noise::gauss(&mut self.rng)
    }

    /// Advances by `dt` seconds towards wheel set-points `target`; `world`, when
    /// given, is what the body collides with.
    pub fn step(&mut self, target: WheelSpeeds, dt: f64, world: Option<&World>) -> StepOutcome {
        self.step_among(target, dt, world, &[])
    }

    /// [`Self::step`] with people standing in the room where `bodies` are:
    /// the body runs into them as into the world's obstacles.
    pub(crate) fn step_among(
        &mut self,
        target: WheelSpeeds,
        dt: f64,
        world: Option<&World>,
        bodies: &[Body],
    ) -> StepOutcome {
        if !(dt.is_finite() && dt > 0.0) {
            return StepOutcome {
                blocked: false,
                bumper: self.bumper,
            };
        }
        let p = self.params.clone();
        let vmax = p.max_wheel_speed;
        let clamp = |v: f64| {
            if v.is_finite() {
                v.clamp(-vmax, vmax)
            } else {
                0.0
            }
        };
        let dv = p.max_accel * dt;
        let approach = |cur: f64, tgt: f64| cur + (tgt - cur).clamp(-dv, dv);
        let next = WheelSpeeds {
            left: approach(self.wheel.left, clamp(target.left)),
            right: approach(self.wheel.right, clamp(target.right)),
        };
        let dl = 0.5 * (self.wheel.left + next.left) * dt;
        let dr = 0.5 * (self.wheel.right + next.right) * dt;
        let (slip, noise) = (p.slip, p.encoder_noise);
        let (el, er) = p.scale_error;
        let gl = dl * (1.0 + el + slip * self.gauss()) * (1.0 - self.loss.0);
        let gr = dr * (1.0 + er + slip * self.gauss()) * (1.0 - self.loss.1);
        let candidate = self.pose * arc_increment(gl, gr, p.wheel_base);
        let (c, c0) = (
            Point2::from(candidate.translation.vector),
            Point2::from(self.pose.translation.vector),
        );
        let moving = dl != 0.0 || dr != 0.0;
        // A body already overlapping something (a bad start, a person who
        // stepped into it) may move; otherwise the disk must stay on free floor.
        let blocked = match world {
            Some(w) if moving => {
                !w.disk_is_free(&c, p.body_radius) && w.disk_is_free(&c0, p.body_radius)
            }
            _ => false,
        } || (moving
            && touches(bodies, &c, p.body_radius)
            && !touches(bodies, &c0, p.body_radius));
        if blocked {
            // The wheels stall against the obstacle: no travel, nothing counted.
            self.wheel = WheelSpeeds::STOP;
        } else {
            self.pose = candidate;
            self.wheel = next;
            // A quadrature counter counts only while its wheel turns: the
            // noise (always drawn, so the random stream does not depend on
            // the motion) is applied to a turning wheel only, and never
            // turns its count backwards.
            let nl = noise * self.gauss();
            let nr = noise * self.gauss();
            self.encoder.0 += counted(dl, nl);
            self.encoder.1 += counted(dr, nr);
        }
        self.bumper = self.front_contact(world, bodies);
        StepOutcome {
            blocked,
            bumper: self.bumper,
        }
    }

    /// Which side of the front half touches something: the world's
    /// obstacles or a person.
    fn front_contact(&self, world: Option<&World>, bodies: &[Body]) -> Sides {
        let r = self.params.body_radius + self.params.bumper_margin;
        let th = heading(&self.pose);
        let c = Point2::from(self.pose.translation.vector);
        let mut s = Sides::default();
        // Every 2° of the ±80° arc: a real shell is continuous, and points
        // 10° apart let a turn in place or a few millimetres of backing off
        // close the bumper on a corner that sat between two of them.
        for k in -40i32..=40 {
            let a = th + (k as f64) * 2f64.to_radians();
            let q = polar(c, a, r);
            if world.is_some_and(|w| !w.free.is_free(&q)) || covers(bodies, &q) {
                if k >= 0 {
                    s.left = true;
                }
                if k <= 0 {
                    s.right = true;
                }
            }
        }
        s
    }
}

/// The travel an encoder counts for a wheel step `d` with noise `n`: none
/// for a wheel standing still, and never of the other sign than `d`.
fn counted(d: f64, n: f64) -> f64 {
    if d == 0.0 {
        0.0
    } else if d > 0.0 {
        (d + n).max(0.0)
    } else {
        (d + n).min(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;

    fn quiet() -> KinematicsParams {
        KinematicsParams {
            slip: 0.0,
            scale_error: (0.0, 0.0),
            encoder_noise: 0.0,
            max_accel: 1e9,
            ..KinematicsParams::default()
        }
    }

    #[test]
    fn straight_and_turn_without_noise() {
        let mut s = DiffDriveSim::new(quiet(), pose(0.0, 0.0, 0.0));
        for _ in 0..100 {
            s.step(
                WheelSpeeds {
                    left: 0.2,
                    right: 0.2,
                },
                0.01,
                None,
            );
        }
        // The first step ramps up (trapezoid): 1 mm short of 0.2 m.
        assert!((s.pose().translation.x - 0.199).abs() < 1e-9);
        let (el, er) = s.encoder_travel();
        assert!((el - 0.199).abs() < 1e-9 && (er - 0.199).abs() < 1e-9);
        let w = WheelSpeeds::from_body(0.0, 1.0, 0.235);
        for _ in 0..100 {
            s.step(w, 0.01, None);
        }
        // The ramp from straight to spinning costs half a step of turn.
        assert!(
            (heading(&s.pose()) - 1.0).abs() < 0.01,
            "{}",
            heading(&s.pose())
        );
    }

    #[test]
    fn acceleration_is_limited() {
        let p = KinematicsParams {
            max_accel: 0.5,
            ..quiet()
        };
        let mut s = DiffDriveSim::new(p, pose(0.0, 0.0, 0.0));
        s.step(
            WheelSpeeds {
                left: 0.4,
                right: 0.4,
            },
            0.1,
            None,
        );
        assert!((s.wheel_speeds().left - 0.05).abs() < 1e-12);
    }

    #[test]
    fn slip_moves_ground_truth_away_from_encoders_deterministically() {
        let p = KinematicsParams {
            slip: 0.05,
            ..KinematicsParams::default()
        };
        let run = |seed| {
            let mut s =
                DiffDriveSim::new(KinematicsParams { seed, ..p.clone() }, pose(0.0, 0.0, 0.0));
            for _ in 0..500 {
                s.step(
                    WheelSpeeds {
                        left: 0.2,
                        right: 0.2,
                    },
                    0.01,
                    None,
                );
            }
            s.pose()
        };
        let a = run(7);
        assert_eq!(a, run(7), "same seed, same run");
        assert_ne!(a, run(8));
        // Encoders said ~1 m straight; truth wandered but stayed close.
        assert!((a.translation.x - 1.0).abs() < 0.05, "{a}");
        assert!(a.translation.y.abs() > 1e-6);
    }

    #[test]
    fn a_person_in_the_way_blocks_and_closes_the_bumper_on_their_side() {
        let w = World::parse("room 0 0 4 0 4 2 0 2\n").unwrap();
        // Standing ahead and a little to the left of the robot's line.
        let person = Body {
            centre: Point2::new(2.0, 1.25),
            radius: 0.2,
            reflectivity: 0.4,
        };
        let mut s = DiffDriveSim::new(quiet(), pose(1.0, 1.0, 0.0));
        let ahead = WheelSpeeds {
            left: 0.2,
            right: 0.2,
        };
        let hit = (0..1000).find(|_| s.step_among(ahead, 0.01, Some(&w), &[person]).blocked);
        assert!(hit.is_some(), "walked through the person");
        let c = Point2::from(s.pose().translation.vector);
        let gap = (c - person.centre).norm() - 0.2 - 0.17;
        assert!((0.0..=0.003).contains(&gap), "stopped {gap} m off");
        assert!(s.bumper().left && !s.bumper().right, "{:?}", s.bumper());
        // Nobody there: the same step drives on.
        assert!(!s.step_among(ahead, 0.01, Some(&w), &[]).blocked);
    }

    #[test]
    fn wall_blocks_and_closes_the_bumper_and_reversing_frees_it() {
        let w = World::parse("room 0 0 2 0 2 2 0 2\n").unwrap();
        let mut s = DiffDriveSim::new(quiet(), pose(1.0, 1.0, 0.0));
        let mut hit = None;
        for i in 0..1000 {
            let o = s.step(
                WheelSpeeds {
                    left: 0.2,
                    right: 0.2,
                },
                0.01,
                Some(&w),
            );
            if o.blocked {
                hit = Some(i);
                break;
            }
        }
        assert!(hit.is_some(), "never reached the wall");
        let x = s.pose().translation.x;
        // Within one ground-truth raster cell (0.02 m) of touching.
        assert!((x - (2.0 - 0.17)).abs() <= 0.02 + 1e-9, "stopped at {x}");
        assert!(s.bumper().left && s.bumper().right, "{:?}", s.bumper());
        // Pushing on stays put.
        s.step(
            WheelSpeeds {
                left: 0.2,
                right: 0.2,
            },
            0.01,
            Some(&w),
        );
        assert_eq!(s.pose().translation.x, x);
        for _ in 0..50 {
            s.step(
                WheelSpeeds {
                    left: -0.2,
                    right: -0.2,
                },
                0.01,
                Some(&w),
            );
        }
        assert!(!s.bumper().any());
        assert!(s.pose().translation.x < x);
    }

    #[test]
    fn params_parse_with_defaults_and_reject_unknown_keys() {
        let p: KinematicsParams = toml::from_str("slip = 0.02\nseed = 9\n").unwrap();
        assert_eq!(p.slip, 0.02);
        assert_eq!(p.seed, 9);
        assert_eq!(p.wheel_base, KinematicsParams::default().wheel_base);
        assert!(toml::from_str::<KinematicsParams>("slipp = 1.0\n").is_err());
    }

    #[test]
    fn bad_dt_is_ignored() {
        let mut s = DiffDriveSim::new(quiet(), pose(0.0, 0.0, 0.0));
        s.step(
            WheelSpeeds {
                left: 1.0,
                right: 1.0,
            },
            f64::NAN,
            None,
        );
        s.step(
            WheelSpeeds {
                left: 1.0,
                right: 1.0,
            },
            -1.0,
            None,
        );
        s.step(
            WheelSpeeds {
                left: f64::NAN,
                right: 0.0,
            },
            0.1,
            None,
        );
        assert!(s.pose().translation.vector.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn a_slip_burst_shortens_the_ground_travel_and_a_displacement_moves_the_body() {
        let p = KinematicsParams {
            slip: 0.0,
            scale_error: (0.0, 0.0),
            encoder_noise: 0.0,
            max_accel: 100.0,
            ..KinematicsParams::default()
        };
        let mut sim = DiffDriveSim::new(p, Pose::identity());
        sim.set_slip_loss((0.5, 0.5));
        let ahead = WheelSpeeds {
            left: 0.2,
            right: 0.2,
        };
        for _ in 0..100 {
            sim.step(ahead, 0.01, None);
        }
        let (l, r) = sim.encoder_travel();
        let x = sim.pose().translation.x;
        assert!(
            (x - 0.5 * l).abs() < 0.01 && (l - r).abs() < 1e-9,
            "x {x}, encoders {l}"
        );
        let moved = sim.displace(1.0, 0.0, 0.5, None).unwrap();
        assert_eq!(moved, (1.0, 0.0));
        assert!((sim.pose().translation.x - x - 1.0).abs() < 1e-9);
        assert!((crate::geom::heading(&sim.pose()) - 0.5).abs() < 1e-9);
        assert_eq!(sim.encoder_travel(), (l, r), "nothing counted");
    }
}
