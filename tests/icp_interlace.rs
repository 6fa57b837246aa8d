//! `replay::interlace_lag`: how much later the odd beams of a log's scans were
//! measured than the even ones, estimated without ground truth. Checked on
//! generated logs of a turning robot whose odd beams are (or are not) taken
//! 13.3 ms after the even ones, and on the MIT CSAIL log (a SICK LMS 2xx in
//! 0.5° mode: two interleaved sweeps at 75 Hz, 13.3 ms apart).

use sweepline::cli::replay::{interlace_lag, replay_log};
use sweepline::geom::pose;
use sweepline::icp::synth::{cast, room, ScanSpec, Wall};
use sweepline::icp::IcpParams;
use sweepline::sim::carmen::{self, CarmenLog, LaserRecord, Record};
use sweepline::sim::eval::Stamped;

fn scene() -> Vec<Wall> {
    let mut w = room(7.0, 5.0, 0.5);
    w.push(Wall::new(2.0, 1.0, 3.0, 1.6, 0.5));
    w.push(Wall::new(5.0, 3.5, 5.6, 4.2, 0.5));
    w
}

/// A robot turning on the spot at `rate` (rad/s) while driving slowly; each
/// 361-beam scan's odd beams are taken `lag` seconds after its even ones.
fn log(lag: f64, rate: f64) -> (CarmenLog, Vec<Stamped>) {
    let walls = scene();
    let spec = ScanSpec {
        beams: 361,
        start_angle: -90f64.to_radians(),
        end_angle: 90f64.to_radians(),
        max_range: 20.0,
        range_noise: 0.005,
        seed: 1,
    };
    let (mut records, mut truth) = (Vec::new(), Vec::new());
    for k in 0..60 {
        let t = 0.2 * k as f64;
        // Turn left, then right: the lag must show with both signs.
        let w = if k < 30 { rate } else { -rate };
        let th = if k < 30 {
            rate * t
        } else {
            rate * (6.0 - (t - 6.0))
        };
        let at = pose(3.0 + 0.02 * k as f64, 2.5, th);
        let later = at * pose(0.0, 0.0, w * lag);
        let even = cast(
            &walls,
            &at,
            &ScanSpec {
                seed: 2 * k,
                ..spec
            },
        );
        let odd = cast(
            &walls,
            &later,
            &ScanSpec {
                seed: 2 * k + 1,
                ..spec
            },
        );
        assert_eq!(
            (even.len(), odd.len()),
            (361, 361),
            "closed room: every beam hits"
        );
        let ranges = (0..361)
            .map(|i| {
                let p = if i % 2 == 0 { &even[i] } else { &odd[i] };
                p.x.hypot(p.y)
            })
            .collect();
        records.push(Record::Laser(LaserRecord {
            stamp: t,
            logger_stamp: t,
            start_angle: spec.start_angle,
            angle_step: 0.5f64.to_radians(),
            ranges,
            remissions: Vec::new(),
            laser_pose: at,
            odom_pose: at,
        }));
        truth.push(Stamped { t, pose: at });
    }
    (
        CarmenLog {
            records,
            skipped_lines: 0,
        },
        truth,
    )
}

#[test]
fn interlaced_scans_show_their_lag_and_plain_ones_none() {
    let params = IcpParams::default();
    let (interlaced, truth) = log(0.0133, 0.6);
    let (lag, used) = interlace_lag(&interlaced, &truth, &params).unwrap();
    assert!(used >= 50, "{used} scans");
    assert!((lag - 0.0133).abs() < 0.002, "lag {lag} s");
    let (plain, truth) = log(0.0, 0.6);
    let (lag, _) = interlace_lag(&plain, &truth, &params).unwrap();
    assert!(lag.abs() < 0.002, "lag {lag} s without interlacing");
    // A robot that never turns says nothing about the lag.
    let (still, truth) = log(0.0133, 0.0);
    assert!(interlace_lag(&still, &truth, &params).is_none());
    // A trajectory of another length is not this log's.
    assert!(interlace_lag(&plain, &truth[..10], &params).is_none());
}

#[test]
fn mit_csail_scans_are_two_sweeps_one_period_apart() {
    let path = sweepline::require_shared!("datasets/mit-csail/mit-csail.clf");
    let log = carmen::read_file(&path).unwrap();
    let params = IcpParams::default();
    let res = replay_log(&log, &params).unwrap();
    let (lag, used) = interlace_lag(&log, &res.trajectory, &params).unwrap();
    eprintln!(
        "odd beams {:.1} ms after even ones ({used} scans)",
        lag * 1e3
    );
    assert!(used > 1500);
    // One sweep of a 75 Hz SICK LMS 2xx: 13.3 ms.
    assert!((lag - 1.0 / 75.0).abs() < 0.002, "lag {lag} s");
}
