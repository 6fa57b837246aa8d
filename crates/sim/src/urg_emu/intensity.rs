//! The intensity a Hokuyo reports for an echo: how it depends on the
//! surface's reflectivity, the range and the angle of incidence.
//!
//! Measured, not the textbook: the one real intensity scan in `../shared`
//! (the UTM-30LX `ME` capture of gbiggs/hokuyoaist) gives, over its 189
//! steps at 0.5-8 m on straight surfaces,
//! `I ≈ 2918 · r^-0.18 · cos(α)^0.13` (r in metres, α the angle of
//! incidence; residual 0.20 in log units, the surfaces' own reflectivities;
//! `python3 scripts/intensity_fit.py` prints the fit). The reported value
//! is nearly flat in range and angle: the sensor does not report the
//! received power `ρ·cos α / r²` of the LIDAR equation (which still decides
//! *whether* a step is measured, see [`super::returns`]). That agrees with
//! the literature: Steder et al. (IROS 2012, remission calibration) and
//! Khan's data-driven intensity model of the UTM-30LX both find the raw
//! value far from `ρ·cos α / r²`, each scanner with its own curve.
//!
//! *Assumed*: the value is proportional to the surface's reflectivity `ρ`,
//! and the capture's office surfaces have the reflectivity this project
//! gives painted plaster (0.55), which sets the scale [`PER_REFLECTIVITY`].
//! The URG-04LX's raw intensity mode (`FF` cluster) is given the same shape
//! and scale: no capture of it exists here. Below 0.5 m the capture only
//! has grazing steps at 0.10-0.14 m (440-1180), too few to fit a near-field
//! term; the model is cut off at [`NEAREST`].

/// Intensity units per unit of reflectivity at 1 m, head-on: the fit's
/// 2918 for surfaces taken to have reflectivity 0.55.
pub(crate) const PER_REFLECTIVITY: f64 = 2918.0 / 0.55;
/// Exponent of the range (the fit's −0.18).
pub(crate) const RANGE_EXPONENT: f64 = -0.18;
/// Exponent of cos(incidence) (the fit's 0.13).
pub(crate) const INCIDENCE_EXPONENT: f64 = 0.13;
/// Range below which the model is held at its value there (m).
pub(crate) const NEAREST: f64 = 0.1;
/// Smallest cos(incidence) the model is evaluated at (a beam along a wall).
const GRAZING: f64 = 0.05;

/// The intensity reported for a surface of reflectivity `rho` (0..=1) at
/// `range` metres, seen at `cos_incidence` from its normal.
pub(crate) fn reported(rho: f64, cos_incidence: f64, range: f64) -> f64 {
    if !(rho.is_finite() && cos_incidence.is_finite() && range.is_finite()) {
        return 0.0;
    }
    PER_REFLECTIVITY
        * rho.clamp(0.0, 1.0)
        * range.max(NEAREST).powf(RANGE_EXPONENT)
        * cos_incidence
            .abs()
            .clamp(GRAZING, 1.0)
            .powf(INCIDENCE_EXPONENT)
}

/// The reflectivity that, seen head-on at `range` metres, is reported as
/// `intensity`: the inverse of [`reported`], for replaying a recorded scan.
pub(crate) fn reflectivity_of(intensity: f64, range: f64) -> f64 {
    let per = reported(1.0, 1.0, range);
    if per > 0.0 && intensity.is_finite() {
        (intensity / per).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_of_the_capture_is_reproduced_for_plaster() {
        // Plaster head-on at 1 m reports the capture's fitted 2918; at 4 m,
        // 4^-0.18 of it (the capture's 2-4 m median is 2383).
        assert!((reported(0.55, 1.0, 1.0) - 2918.0).abs() < 1.0);
        let far = reported(0.55, 1.0, 4.0);
        assert!((far / 2918.0 - 4f64.powf(-0.18)).abs() < 1e-9, "{far}");
        assert!((2000.0..2700.0).contains(&far), "{far}");
    }

    #[test]
    fn reflectivity_decides_range_and_angle_barely_do() {
        // A retro-reflective tape (0.95) against plaster (0.55): the
        // contrast is the reflectivities' ratio at any range and angle.
        for (r, c) in [(0.5, 1.0), (2.0, 0.5), (5.0, 0.1)] {
            let ratio = reported(0.95, c, r) / reported(0.55, c, r);
            assert!((ratio - 0.95 / 0.55).abs() < 1e-9);
        }
        // Halving the range or turning the wall to 60° moves the value by
        // less than 15 %, where ρ·cos/r² would move it 4× and 2×.
        let head_on = reported(0.55, 1.0, 2.0);
        assert!(reported(0.55, 1.0, 1.0) / head_on < 1.15);
        assert!(reported(0.55, 0.5, 2.0) / head_on > 0.9);
        assert_eq!(reported(f64::NAN, 1.0, 1.0), 0.0);
        assert_eq!(reported(0.5, 1.0, 0.01), reported(0.5, 1.0, NEAREST));
    }

    #[test]
    fn a_recorded_intensity_replays_as_the_same_value() {
        for (i, r) in [(2500.0, 1.3), (900.0, 4.0), (4000.0, 0.7)] {
            let rho = reflectivity_of(i, r);
            assert!((reported(rho, 1.0, r) - i).abs() < 1e-6, "{i} at {r}");
        }
        assert_eq!(reflectivity_of(1e9, 1.0), 1.0);
        assert_eq!(reflectivity_of(f64::NAN, 1.0), 0.0);
    }
}
