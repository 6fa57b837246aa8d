//! Which beams a URG-04LX cannot measure, and the error code it sends for
//! them instead of a range.
//!
//! The real capture (`../shared/datasets/hokuyo-captures/example_urg_04lx.logr`,
//! an office scan) has 101 error codes in 682 steps: 94 × `0`, 6 × `7` and
//! 1 × `10`. The `0`s come in runs where nothing returns light (open space
//! beyond reach, or surfaces too dark to measure: one run lies between two
//! objects 0.45 m away); every `7` sits next to a `0` ("neighbouring steps
//! have errors"); the lone `10` ("other") is not modelled. So:
//!
//! * no surface within DMAX (5.6 m), or too little light back: `0`;
//! * a step that measured but borders a `0`: `7` with probability
//!   [`EDGE_CODE_CHANCE`] (4 of the capture's 16 measured-or-`7` steps next
//!   to a `0` run are `7`), and a `0` step between two `0` steps: `7` with
//!   probability [`INNER_CODE_CHANCE`] (2 of 68 in the capture);
//! * closer than DMIN (20 mm), and the steps outside AMIN..AMAX (they look
//!   at the housing): [`TOO_CLOSE_CODE`] (`19`, "non-measurable step").
//!   *Assumed*: the capture has neither.
//!
//! How much light comes back is modelled as `ρ / r²`: `ρ` is the fraction of
//! light the surface returns towards the sensor (the scene folds the
//! incidence angle in: reflectivity × cos(incidence), a Lambertian surface),
//! `r` the range in metres. Below [`MIN_SIGNAL`] the step fails, with a
//! soft edge (the chance of failing grows from 0 to 1 as the signal falls
//! from √2 to 1/√2 times the threshold). *Assumed*, not measured: the
//! threshold is set so that painted plaster (ρ 0.55) head-on measures out to
//! DMAX, a black surface (ρ 0.05) fails beyond about 3 m, and walls seen at
//! more than about 75-85° from their normal fail beyond 3-5 m, which is what
//! Kneip et al. (ICRA 2009, "Characterization of the compact Hokuyo URG-04LX
//! 2D laser range scanner") describe qualitatively: faulty readings mainly on
//! low-reflectivity surfaces and at high incidence angles.

use rand::Rng;

/// Code sent for a step next to failed steps.
pub(crate) const NEIGHBOUR_CODE: u32 = 7;
/// Code sent for a surface closer than DMIN and for the dead zone (assumed).
pub(crate) const TOO_CLOSE_CODE: u32 = 19;
/// Returned light (`ρ / r²`, m⁻²) below which a step fails (assumed).
pub(crate) const MIN_SIGNAL: f64 = 0.006;
/// Chance that a measured step next to a no-echo step is sent as `7`.
pub(crate) const EDGE_CODE_CHANCE: f64 = 0.25;
/// Chance that a no-echo step between two no-echo steps is sent as `7`.
pub(crate) const INNER_CODE_CHANCE: f64 = 0.03;

/// Chance (0..=1) that a surface returning `rho` of the light at `range`
/// metres is measured.
pub(crate) fn chance_measured(rho: f64, range: f64) -> f64 {
    if !(rho.is_finite() && range.is_finite()) || rho <= 0.0 {
        return 0.0;
    }
    let signal = rho / (range * range).max(1e-6);
    // Linear in log2(signal / MIN_SIGNAL) over [-0.5, 0.5].
    ((signal / MIN_SIGNAL).log2() + 0.5).clamp(0.0, 1.0)
}

/// Whether a surface returning `rho` at `range` metres is measured; draws
/// from `rng` only near the threshold.
pub(crate) fn measured(rho: f64, range: f64, rng: &mut impl Rng) -> bool {
    let p = chance_measured(rho, range);
    p >= 1.0 || (p > 0.0 && rng.random::<f64>() < p)
}

/// One step as measured, before it is put on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Step {
    /// A range (mm) and the intensity of its echo.
    Range {
        /// Distance (mm).
        mm: u32,
        /// Intensity (FF mode).
        intensity: u32,
    },
    /// An error code decided elsewhere (a replayed one, too close, dead zone).
    Code(u32),
    /// No echo: nothing within DMAX, or too little light.
    NoEcho,
}

/// Rewrites `steps` with the neighbour code where the real firmware sends
/// it: see the module doc.
pub(crate) fn mark_neighbours(steps: &mut [Step], rng: &mut impl Rng) {
    // Decide from the steps as measured, not as rewritten: a `7` set at
    // step k must not make step k + 1 look like an edge.
    let mut before = None;
    for k in 0..steps.len() {
        let here = steps[k];
        let after = steps.get(k + 1).copied();
        let (b, a) = (before == Some(Step::NoEcho), after == Some(Step::NoEcho));
        before = Some(here);
        let chance = match here {
            Step::Range { .. } if b || a => EDGE_CODE_CHANCE,
            Step::NoEcho if b && a => INNER_CODE_CHANCE,
            _ => continue,
        };
        if rng.random::<f64>() < chance {
            steps[k] = Step::Code(NEIGHBOUR_CODE);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn bright_walls_measure_to_dmax_and_dark_ones_fail_far() {
        assert_eq!(chance_measured(0.55, 5.6), 1.0);
        assert_eq!(chance_measured(0.05, 1.0), 1.0);
        assert_eq!(chance_measured(0.05, 4.0), 0.0);
        // Plaster seen 85° off its normal, 4 m away.
        assert_eq!(chance_measured(0.55 * 85f64.to_radians().cos(), 4.0), 0.0);
        assert_eq!(chance_measured(0.0, 1.0), 0.0);
        assert_eq!(chance_measured(f64::NAN, 1.0), 0.0);
        assert_eq!(chance_measured(0.5, f64::INFINITY), 0.0);
        let p = chance_measured(MIN_SIGNAL, 1.0);
        assert!((p - 0.5).abs() < 1e-12, "{p}");
    }

    #[test]
    fn neighbour_codes_only_next_to_no_echo() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let r = |mm| Step::Range { mm, intensity: 0 };
        let (mut edges, mut inner) = (0, 0);
        for _ in 0..2000 {
            let mut v = [
                r(500),
                r(500),
                Step::NoEcho,
                Step::NoEcho,
                Step::NoEcho,
                r(600),
                r(600),
            ];
            mark_neighbours(&mut v, &mut rng);
            assert_eq!(
                (v[0], v[2], v[4], v[6]),
                (r(500), Step::NoEcho, Step::NoEcho, r(600))
            );
            edges += usize::from(v[1] == Step::Code(7)) + usize::from(v[5] == Step::Code(7));
            inner += usize::from(v[3] == Step::Code(7));
        }
        assert!((800..1200).contains(&edges), "{edges}");
        assert!((30..100).contains(&inner), "{inner}");
        // A replayed or too-close code is not a no-echo step.
        let mut none = [r(500), Step::Code(0), r(600)];
        mark_neighbours(&mut none, &mut rng);
        assert_eq!(none, [r(500), Step::Code(0), r(600)]);
        mark_neighbours(&mut [], &mut rng);
    }
}
