//! People walking through a simulated room (`walker` lines of a world file,
//! or `--walker` of `sweepline coverage` and `sweepline sim`): each a disc in
//! the scanner's plane (a person's legs) that walks out and back along its
//! path at a steady pace. The scanner sees it like any surface and the body
//! runs into it, but it is not part of the ground truth: the floor it walks
//! on must still be covered.
//!
//! A person waits rather than walk into a robot: a walker does not step
//! nearer to the robot once it is within `YIELD_GAP` of the robot's body.
//! Whether the robot keeps off a walker standing still, or one walking away,
//! is the daemon's business; a touch is counted as a contact.
//!
//! Deterministic: where a walker is depends only on the steps' lengths and on
//! where the robot was at each step.

use std::sync::{Mutex, MutexGuard};

use nalgebra::{Point2, Vector2};

use crate::geom::points_along;
use crate::world::{RayHit, World};

/// Gap (m) between a walker and the robot's body within which the walker
/// waits rather than step nearer.
pub(crate) const YIELD_GAP: f64 = 0.15;

/// Reflectivity of a walker when its line gives none (clothes).
pub(crate) const DEFAULT_WALKER_REFLECTIVITY: f64 = 0.4;

/// One person: a disc walking out and back along a path.
#[derive(Clone, Debug, PartialEq)]
pub struct Walker {
    /// Radius of the disc the scanner sees and the body runs into (m).
    pub radius: f64,
    /// Walking speed (m/s).
    pub speed: f64,
    /// Way points, walked in order and back, again and again.
    pub path: Vec<Point2<f64>>,
    /// Surface reflectivity (0..1).
    pub reflectivity: f64,
    /// Simulated time (s) at which the walker comes in at the first way
    /// point (later if the robot stands there).
    pub after: f64,
    /// Walks along the path (one way each) before the walker leaves the
    /// room from where it ends; `None`: it walks for the whole run.
    pub trips: Option<u32>,
    /// Comes in only once the robot's centre is within this distance (m) of
    /// the first way point: someone stepping out in front of the robot.
    pub near: Option<f64>,
}

impl Walker {
    /// A walker from the words of its line: `RADIUS SPEED X0 Y0 X1 Y1
    /// [X Y ...]`, then optionally `refl R` (0..1), `after T` (s),
    /// `trips N` and `near D` (m); the message says what is wrong.
    pub(crate) fn parse_words(words: &[&str]) -> Result<Walker, String> {
        let number = |w: &str| {
            w.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && v.abs() <= 1.0e4)
                .ok_or_else(|| format!("walker: `{w}` is not a number"))
        };
        let mut nums = Vec::new();
        let (mut reflectivity, mut after, mut trips) = (DEFAULT_WALKER_REFLECTIVITY, 0.0, None);
        let mut near = None;
        let mut it = words.iter();
        while let Some(&w) = it.next() {
            if !matches!(w, "refl" | "after" | "trips" | "near") {
                nums.push(number(w)?);
                continue;
            }
            let v = number(
                it.next()
                    .ok_or_else(|| format!("walker: `{w}` needs a value"))?,
            )?;
            match w {
                "refl" if (0.0..=1.0).contains(&v) => reflectivity = v,
                "after" if v >= 0.0 => after = v,
                "trips" if v >= 1.0 && v.fract() == 0.0 => trips = Some(v as u32),
                "near" if v > 0.0 => near = Some(v),
                _ => {
                    return Err(format!(
                        "walker: `{w} {v}` out of range (refl 0..1, after >= 0 s, trips a whole number >= 1, near > 0 m)"
                    ))
                }
            }
        }
        if nums.len() < 6 || !nums.len().is_multiple_of(2) {
            return Err(format!(
                "walker takes RADIUS SPEED and at least two x y way points (got {} numbers)",
                nums.len()
            ));
        }
        let (radius, speed) = (nums[0], nums[1]);
        if !(0.02..=1.0).contains(&radius) {
            return Err(format!("walker radius {radius} m outside 0.02..1"));
        }
        if !(0.01..=3.0).contains(&speed) {
            return Err(format!("walker speed {speed} m/s outside 0.01..3"));
        }
        let path: Vec<Point2<f64>> = nums[2..]
            .chunks(2)
            .map(|c| Point2::new(c[0], c[1]))
            .collect();
        let w = Walker {
            radius,
            speed,
            path,
            reflectivity,
            after,
            trips,
            near,
        };
        if w.length() < 0.1 {
            return Err(format!(
                "walker path is {:.3} m long: at least 0.1 m",
                w.length()
            ));
        }
        Ok(w)
    }

    /// A walker from the text of a `--walker` option: the words of
    /// `Walker::parse_words`, spaces or commas between them.
    pub fn parse(text: &str) -> Result<Walker, String> {
        let words: Vec<&str> = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|w| !w.is_empty())
            .collect();
        Walker::parse_words(&words)
    }

    /// Length of the path one way (m).
    pub fn length(&self) -> f64 {
        self.path.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
    }

    /// Where the walker is `u` metres into its round trip (out along the
    /// path, then back; `u` taken modulo twice the length).
    pub fn at(&self, u: f64) -> Point2<f64> {
        let len = self.length();
        let mut s = u.rem_euclid(2.0 * len);
        if s > len {
            s = 2.0 * len - s;
        }
        for w in self.path.windows(2) {
            let d = (w[1] - w[0]).norm();
            if s <= d {
                return if d > 0.0 {
                    w[0] + (w[1] - w[0]) * (s / d)
                } else {
                    w[0]
                };
            }
            s -= d;
        }
        self.path[self.path.len() - 1]
    }

    /// Points of the path every `step` metres or less, ends included (to
    /// check that it stays on free floor).
    pub fn samples(&self, step: f64) -> impl Iterator<Item = Point2<f64>> + '_ {
        self.path
            .windows(2)
            .flat_map(move |w| points_along(w[0], w[1], step))
    }
}

/// Locks the people shared between the emulators and the sampler, even if a
/// thread that held them panicked (their state is plain positions, never
/// left half-written).
pub(crate) fn lock_crowd(c: &Mutex<Crowd>) -> MutexGuard<'_, Crowd> {
    c.lock().unwrap_or_else(|e| e.into_inner())
}

/// A disc standing in the scanner's plane: a walker where it is now.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    /// Centre (world frame, m).
    pub centre: Point2<f64>,
    /// Radius (m).
    pub radius: f64,
    /// Surface reflectivity (0..1).
    pub reflectivity: f64,
}

/// Where every walker of a world is, stepped along the simulation's clock.
#[derive(Clone, Debug, Default)]
pub(crate) struct Crowd {
    walkers: Vec<Walker>,
    /// Per walker, metres into its round trip.
    walked: Vec<f64>,
    /// Per walker, where it is when in the room.
    at: Vec<Option<Point2<f64>>>,
    /// The walkers in the room, as discs.
    bodies: Vec<Body>,
    /// Simulated time stepped (s).
    time: f64,
    /// Steps a walker waited for the robot, summed.
    waits: u64,
}

impl Crowd {
    /// The walkers, none in the room yet.
    pub fn new(walkers: &[Walker]) -> Crowd {
        Crowd {
            walkers: walkers.to_vec(),
            walked: vec![0.0; walkers.len()],
            at: vec![None; walkers.len()],
            ..Crowd::default()
        }
    }

    /// True when there is nobody.
    pub fn is_empty(&self) -> bool {
        self.walkers.is_empty()
    }

    /// Moves every walker on by `dt` seconds of walking, except one that would
    /// step nearer to the robot (a disc of `robot_radius` at `robot`) while
    /// within [`YIELD_GAP`] of it: that one waits. A walker comes in at its
    /// time (at its first way point, once the robot is clear of it, and for
    /// a walker with `near`, once the robot is that near) and leaves after
    /// its trips.
    pub fn step(&mut self, dt: f64, robot: &Point2<f64>, robot_radius: f64) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        self.time += dt;
        self.bodies.clear();
        for ((w, u), at) in self
            .walkers
            .iter()
            .zip(self.walked.iter_mut())
            .zip(self.at.iter_mut())
        {
            let keep = robot_radius + w.radius + YIELD_GAP;
            let trip_end = w.trips.map_or(f64::INFINITY, |n| f64::from(n) * w.length());
            match *at {
                None if *u == 0.0
                    && self.time >= w.after
                    && (keep..=w.near.unwrap_or(f64::INFINITY))
                        .contains(&(w.path[0] - robot).norm()) =>
                {
                    *at = Some(w.path[0]);
                }
                None => continue,
                Some(now) => {
                    let next_u = (*u + w.speed * dt).min(trip_end);
                    let next = w.at(next_u);
                    let next_d = (next - robot).norm();
                    if next_d < keep && next_d < (now - robot).norm() {
                        self.waits += 1;
                    } else if next_u >= trip_end {
                        *u = trip_end;
                        *at = None;
                        continue;
                    } else {
                        *u = next_u;
                        *at = Some(next);
                    }
                }
            }
            if let Some(c) = *at {
                self.bodies.push(Body {
                    centre: c,
                    radius: w.radius,
                    reflectivity: w.reflectivity,
                });
            }
        }
    }

    /// The walkers in the room, as discs where they are now.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Steps a walker waited for the robot, summed over walkers.
    #[cfg(test)]
    pub(crate) fn waits(&self) -> u64 {
        self.waits
    }
}

/// Radius of a person drawn by [`random_walkers`] (m).
const RANDOM_RADIUS: f64 = 0.2;

/// `n` people for `world`, drawn from the generator seeded with `seed`
/// (the same world and seed give the same people): each walks a straight
/// line of at least 1.5 m (2 m where the room has one) between two points
/// of free floor, the disc clear of every obstacle all along, its ends at
/// least 1 m from the robot's start; at 0.6-1.2 m/s, coming in at 0-300 s,
/// for 2-6 trips. Fewer when the room has no such line (a cluttered room).
pub fn random_walkers(world: &World, n: usize, seed: u64) -> Vec<Walker> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let f = &world.free;
    let start = Point2::from(world.start.translation.vector);
    // Places a person fits, on a 10 cm lattice.
    let stride = (0.1 / f.resolution).round().max(1.0) as usize;
    let mut spots = Vec::new();
    for cy in (0..f.height).step_by(stride) {
        for cx in (0..f.width).step_by(stride) {
            let p = f.centre_of(cx, cy);
            if (p - start).norm() >= 1.0 && world.disk_is_free(&p, RANDOM_RADIUS) {
                spots.push(p);
            }
        }
    }
    let clear = |a: &Point2<f64>, b: &Point2<f64>| {
        points_along(*a, *b, 0.05).all(|p| world.disk_is_free(&p, RANDOM_RADIUS))
    };
    let mut out = Vec::new();
    if spots.len() < 2 {
        return out;
    }
    for _ in 0..n {
        let mut found = None;
        for (tries, min_len) in [(400, 2.0), (400, 1.5)] {
            for _ in 0..tries {
                let a = spots[rng.random_range(0..spots.len())];
                let b = spots[rng.random_range(0..spots.len())];
                if (b - a).norm() >= min_len && clear(&a, &b) {
                    found = Some((a, b));
                    break;
                }
            }
            if found.is_some() {
                break;
            }
        }
        let Some((a, b)) = found else {
            break;
        };
        out.push(Walker {
            radius: RANDOM_RADIUS,
            speed: rng.random_range(0.6..=1.2),
            path: vec![a, b],
            reflectivity: DEFAULT_WALKER_REFLECTIVITY,
            after: rng.random_range(0.0..=300.0),
            near: None,
            trips: Some(rng.random_range(2..=6)),
        });
    }
    out
}

/// Whether a disc of `radius` at `p` overlaps any of `bodies`.
pub fn touches(bodies: &[Body], p: &Point2<f64>, radius: f64) -> bool {
    bodies
        .iter()
        .any(|b| (b.centre - p).norm() < b.radius + radius)
}

/// Whether any of `bodies` covers the point `p`.
pub fn covers(bodies: &[Body], p: &Point2<f64>) -> bool {
    touches(bodies, p, 0.0)
}

/// [`World::cast_ray`] with `bodies` standing in the room: the nearest of the
/// wall hit and the discs' hits.
pub(crate) fn cast_ray_among(
    world: &World,
    bodies: &[Body],
    origin: &Point2<f64>,
    angle: f64,
    max_range: f64,
) -> Option<RayHit> {
    let wall = world.cast_ray(origin, angle, max_range);
    if bodies.is_empty() {
        return wall;
    }
    let dir = Vector2::new(angle.cos(), angle.sin());
    let mut best = wall;
    for b in bodies {
        if let Some(t) = ray_disc(origin, &dir, b) {
            if t <= max_range && best.is_none_or(|h| t < h.range) {
                let hit = origin + dir * t;
                let n = (hit - b.centre) / b.radius;
                best = Some(RayHit {
                    range: t,
                    reflectivity: b.reflectivity,
                    incidence: dir.dot(&n).abs().min(1.0).acos(),
                });
            }
        }
    }
    best
}

/// Distance along the unit ray `origin + t dir` to where it enters disc `b`
/// (`None`: it misses, or starts inside).
fn ray_disc(origin: &Point2<f64>, dir: &Vector2<f64>, b: &Body) -> Option<f64> {
    let f = origin - b.centre;
    let along = f.dot(dir);
    let c = f.norm_squared() - b.radius * b.radius;
    if c <= 0.0 {
        return None;
    }
    let disc = along * along - c;
    if disc < 0.0 {
        return None;
    }
    let t = -along - disc.sqrt();
    (t > 1e-9).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn across() -> Walker {
        Walker::parse("0.2 1.0 1 2 5 2").unwrap()
    }

    #[test]
    fn a_walker_goes_out_and_back_along_its_path() {
        let w = Walker::parse("0.2, 1.0, 0 0, 3 0, 3 4").unwrap();
        assert!((w.length() - 7.0).abs() < 1e-12);
        assert!((w.at(1.5) - Point2::new(1.5, 0.0)).norm() < 1e-12);
        assert!((w.at(5.0) - Point2::new(3.0, 2.0)).norm() < 1e-12);
        // 9 m into the round trip: 2 m back from the far end.
        assert!((w.at(9.0) - Point2::new(3.0, 2.0)).norm() < 1e-12);
        assert!((w.at(14.0) - Point2::new(0.0, 0.0)).norm() < 1e-12);
        assert!((w.at(15.0) - Point2::new(1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn bad_walker_lines_are_refused_with_the_reason() {
        for (text, says) in [
            ("0.2 1.0 1 2", "at least two x y way points"),
            ("0.2 1.0 1 2 3", "at least two"),
            ("5 1.0 1 2 3 4", "radius"),
            ("0.2 0 1 2 3 4", "speed"),
            ("0.2 1 1 2 1 2.05", "at least 0.1 m"),
            ("0.2 1 1 2 x 4", "`x` is not a number"),
            ("0.2 1 1 2 NaN 4", "`NaN` is not a number"),
            ("0.2 1 1 2 3 4 trips 1.5", "out of range"),
            ("0.2 1 1 2 3 4 after -1", "out of range"),
            ("0.2 1 1 2 3 4 refl 2", "out of range"),
            ("0.2 1 1 2 3 4 near 0", "out of range"),
            ("0.2 1 1 2 3 4 trips", "`trips` needs a value"),
        ] {
            let e = Walker::parse(text).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn a_walker_waits_for_the_robot_in_its_way_and_walks_on_when_it_has_gone() {
        let mut c = Crowd::new(&[across()]);
        let robot = Point2::new(3.0, 2.0);
        for _ in 0..400 {
            c.step(0.01, &robot, 0.17);
        }
        let x = c.bodies()[0].centre.x;
        // It stopped short of the robot's body by the yield gap or less.
        let keep = 0.17 + 0.2 + YIELD_GAP;
        assert!(x < 3.0 - keep + 0.011 && x > 3.0 - keep - 0.011, "x {x}");
        assert!(c.waits() > 0);
        assert!(!touches(c.bodies(), &robot, 0.17));
        // The robot moves off: the walker goes on to the far end.
        let gone = Point2::new(3.0, 3.5);
        for _ in 0..250 {
            c.step(0.01, &gone, 0.17);
        }
        assert!(c.bodies()[0].centre.x > 4.95, "{:?}", c.bodies()[0]);
    }

    #[test]
    fn a_walker_walks_away_from_a_robot_beside_it() {
        let mut c = Crowd::new(&[across()]);
        c.step(0.01, &Point2::new(5.0, 3.5), 0.17);
        assert_eq!(c.bodies()[0].centre, Point2::new(1.0, 2.0));
        // The robot right behind the walker: stepping on moves away.
        let robot = Point2::new(0.7, 2.0);
        c.step(0.5, &robot, 0.17);
        assert!((c.bodies()[0].centre.x - 1.5).abs() < 1e-12);
        assert_eq!(c.waits(), 0);
    }

    #[test]
    fn a_walker_comes_in_at_its_time_clear_of_the_robot_and_leaves_after_its_trips() {
        let w = Walker::parse("0.2 1.0 1 2 3 2 after 1.0 trips 3 refl 0.7").unwrap();
        assert_eq!((w.after, w.trips, w.reflectivity), (1.0, Some(3), 0.7));
        let mut c = Crowd::new(&[w]);
        let away = Point2::new(2.0, 3.5);
        for _ in 0..99 {
            c.step(0.01, &away, 0.17);
        }
        assert!(c.bodies().is_empty(), "in before its time");
        // The robot stands at the way in: the walker waits outside.
        let at_door = Point2::new(1.2, 2.0);
        for _ in 0..50 {
            c.step(0.01, &at_door, 0.17);
        }
        assert!(c.bodies().is_empty(), "came in onto the robot");
        c.step(0.01, &away, 0.17);
        assert_eq!(c.bodies()[0].centre, Point2::new(1.0, 2.0));
        // Three trips of 2 m at 1 m/s: gone after 6 s, at the far end.
        for _ in 0..600 {
            c.step(0.01, &away, 0.17);
        }
        assert!(
            (c.bodies()[0].centre.x - 3.0).abs() < 1e-6,
            "{:?}",
            c.bodies()
        );
        c.step(0.01, &away, 0.17);
        assert!(c.bodies().is_empty());
        for _ in 0..1000 {
            c.step(0.01, &away, 0.17);
        }
        assert!(c.bodies().is_empty(), "came back");
    }

    #[test]
    fn a_walker_with_near_steps_in_only_when_the_robot_comes_that_near() {
        let w = Walker::parse("0.2 0.01 3 2 3 2.12 near 0.8").unwrap();
        assert_eq!(w.near, Some(0.8));
        let mut c = Crowd::new(&[w]);
        // Far off: nobody. Within 0.8 m but nearer than the yield gap
        // allows (0.52 m): nobody either.
        for x in [0.5, 1.5, 2.1, 2.6] {
            c.step(0.1, &Point2::new(x, 2.0), 0.17);
            assert!(c.bodies().is_empty(), "in with the robot at x {x}");
        }
        // 0.7 m off, driving towards the way point: in.
        let mut c = Crowd::new(&c.walkers);
        c.step(0.1, &Point2::new(2.3, 2.0), 0.17);
        assert_eq!(c.bodies()[0].centre, Point2::new(3.0, 2.0));
    }

    #[test]
    fn random_people_walk_clear_lines_and_repeat_with_their_seed() {
        let world =
            World::parse("room 0 0 6 0 6 4 0 4\nbox 2.5 1.5 3.5 2.5\nstart 0.5 0.5 0\n").unwrap();
        let a = random_walkers(&world, 3, 7);
        assert_eq!(a, random_walkers(&world, 3, 7));
        assert_ne!(a, random_walkers(&world, 3, 8));
        assert_eq!(a.len(), 3);
        for w in &a {
            assert!(w.length() >= 2.0, "{w:?}");
            assert!(
                w.samples(0.02).all(|p| world.disk_is_free(&p, w.radius)),
                "{w:?}"
            );
            assert!((0.6..=1.2).contains(&w.speed) && (0.0..=300.0).contains(&w.after));
            assert!(w
                .path
                .iter()
                .all(|p| (p - Point2::new(0.5, 0.5)).norm() >= 1.0));
        }
        // A room with no room to walk gets nobody.
        let tiny = World::parse("room 0 0 1 0 1 1 0 1\nstart 0.5 0.5 0\n").unwrap();
        assert!(random_walkers(&tiny, 2, 1).is_empty());
    }

    #[test]
    fn rays_hit_a_walker_before_the_wall_behind_it() {
        let world = World::parse("room 0 0 6 0 6 4 0 4 refl 0.7\n").unwrap();
        let body = Body {
            centre: Point2::new(3.0, 2.0),
            radius: 0.2,
            reflectivity: 0.4,
        };
        let o = Point2::new(1.0, 2.0);
        let h = cast_ray_among(&world, &[body], &o, 0.0, 5.6).unwrap();
        assert!((h.range - 1.8).abs() < 1e-9, "{h:?}");
        assert!((h.reflectivity - 0.4).abs() < 1e-12);
        assert!(h.incidence.abs() < 1e-9);
        // Past it, the wall; away from it, the wall too.
        let h = cast_ray_among(&world, &[body], &o, 0.3, 5.6).unwrap();
        assert!((h.reflectivity - 0.7).abs() < 1e-12, "{h:?}");
        let h = cast_ray_among(&world, &[body], &o, std::f64::consts::PI, 5.6).unwrap();
        assert!((h.range - 1.0).abs() < 1e-9);
        // Grazing the disc's edge at 90° incidence.
        let edge = (0.2f64 / 2.0).asin();
        let h = cast_ray_among(&world, &[body], &o, edge - 1e-7, 5.6).unwrap();
        assert!((h.reflectivity - 0.4).abs() < 1e-12 && h.incidence > 1.5);
        assert!(touches(&[body], &Point2::new(3.0, 2.36), 0.17));
        assert!(!touches(&[body], &Point2::new(3.0, 2.38), 0.17));
    }
}
