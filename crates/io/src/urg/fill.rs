//! A SCIP scan reply turned into the daemon's [`LaserScan`]: angles from the
//! sensor's own PP, ranges in metres, error codes as invalid beams. The wire
//! view ([`ScanData`]) is the codec's; this is the driver's side of it.

use crate::scan::{Beam, LaserScan};
use crate::scip::{Reading, ScanData, ScanError, SensorParams};

/// Fills `out` with the beams of `scan`: each value's angle from the sensor's
/// own PP (`AFRT`, `ARES`; the centre of its cluster), its range in metres,
/// intensity, and validity (error codes and values beyond DMAX are invalid,
/// never ranges). `stamp` is the host time of the scan (s). Allocation-free.
pub fn fill_laser_scan(
    scan: &ScanData<'_>,
    params: &SensorParams,
    stamp: f64,
    seq: u64,
    out: &mut LaserScan,
) -> Result<usize, ScanError> {
    out.beams.clear();
    out.stamp = stamp;
    out.seq = seq;
    out.first_beam_time = 0.0;
    out.beam_interval = 0.0;
    let family = params.family();
    let step_angle = params.step_angle();
    let front = f64::from(params.afrt);
    let (dmin, dmax) = (params.dmin, params.dmax);
    for v in scan.values() {
        let centre = f64::from(v.step) + (f64::from(v.steps) - 1.0) * 0.5;
        let (range, valid) = match Reading::classify(v.distance, dmin, dmax, family) {
            Reading::Range(mm) => (f64::from(mm) * 1e-3, true),
            Reading::BeyondMax(mm) => (f64::from(mm) * 1e-3, false),
            Reading::Error(_) => (0.0, false),
        };
        let intensity = match (valid, v.intensity) {
            (true, Some(i)) => f64::from(i),
            _ => 0.0,
        };
        let beam = Beam {
            angle: (centre - front) * step_angle,
            range,
            intensity,
            valid,
        };
        if out.beams.is_empty() {
            // Beams are measured one step after another from AMIN; the
            // stamp is the time of the first step measured.
            let tps = params.time_per_step();
            out.first_beam_time =
                params.time_of_step(centre) - params.time_of_step(f64::from(v.step));
            out.beam_interval = f64::from(v.steps) * tps;
        }
        out.beams.push(beam).map_err(|_| ScanError::TooManyBeams)?;
    }
    Ok(out.beams.len())
}
