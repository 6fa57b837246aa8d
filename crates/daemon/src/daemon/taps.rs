//! Taps: copies of what flows through the pipeline, for the live view and
//! the recorder (`sweepline-live`), which run outside the stages.
//!
//! Each tap is an edge of its own, registered with the pipeline so that
//! its drops show in the report. A full tap drops the new copy (oldest
//! kept): a stalled disk or viewer loses telemetry, never a scan, and no
//! stage ever waits for it. The copies are plain memory moves into the
//! edge's preallocated slots: nothing on the scan path allocates.

use sweepline_wire::scip::Reading;

use super::messages::{PoseFix, ScanMsg};
use crate::capacity::MAX_BEAMS;
use crate::motor::Odometry;
use crate::pipeline::{queue, Overflow, Rx, Tx};
use crate::urg::UrgScan;

/// Scans a tap holds before it drops (3 s at 10 Hz).
const SCAN_TAP_DEPTH: usize = 32;
/// Pose fixes a tap holds before it drops.
const FIX_TAP_DEPTH: usize = 64;
/// Odometry readings a tap holds before it drops (2.5 s at 50 Hz).
const ODOMETRY_TAP_DEPTH: usize = 128;

/// The sensor's own view of a scan: what the driver read before turning it
/// into metres, so that a recording keeps the bytes' meaning losslessly.
#[derive(Clone, Debug, Default)]
pub struct SensorScan {
    /// The 24-bit timestamp as the sensor sent it (ms).
    pub raw_stamp: u32,
    /// The sensor clock unwrapped (ms, within one epoch).
    pub sensor_ms: u64,
    /// Sensor clock epoch (increases when the clock restarted).
    pub epoch: u32,
    /// Scans missing just before this one (timestamp gap).
    pub dropped_before: u64,
    /// Per beam, the raw value the sensor sent: a range in millimetres, or
    /// an error code below DMIN.
    pub raw: heapless::Vec<u32, MAX_BEAMS>,
}

impl SensorScan {
    /// The sensor's part of a driver scan.
    pub fn of(scan: &UrgScan) -> Self {
        let mut raw = heapless::Vec::new();
        for r in &scan.readings {
            let v = match *r {
                Reading::Range(mm) | Reading::BeyondMax(mm) => mm,
                Reading::Error(e) => e.code,
            };
            // Both hold at most MAX_BEAMS: the push cannot fail.
            let _ = raw.push(v);
        }
        Self {
            raw_stamp: scan.raw_stamp,
            sensor_ms: scan.sensor_ms,
            epoch: scan.epoch,
            dropped_before: scan.dropped_before,
            raw,
        }
    }
}

/// A scan as the localise stage received it, with the sensor's own view.
#[derive(Clone, Debug)]
pub struct TapScan {
    /// The message the localise stage was handed.
    pub msg: ScanMsg,
    /// The sensor's raw values and clock.
    pub sensor: SensorScan,
}

/// The producer ends, held by the stages.
#[derive(Clone)]
pub(crate) struct TapSenders {
    /// Scans, from the scanner stage.
    pub(crate) scans: Tx<TapScan>,
    /// Pose fixes, from the localise stage.
    pub(crate) fixes: Tx<PoseFix>,
    /// Wheel odometry readings, from the motor stage.
    pub(crate) odometry: Tx<Odometry>,
}

/// The consumer ends, for the telemetry thread.
pub struct Taps {
    /// Every scan handed to the localise stage.
    pub scans: Rx<TapScan>,
    /// Every pose the localise stage handed to the control stage.
    pub fixes: Rx<PoseFix>,
    /// Every wheel odometry reading the motor stage took.
    pub odometry: Rx<Odometry>,
}

/// A new set of taps.
pub(crate) fn taps() -> (TapSenders, Taps) {
    let (scans_tx, scans) = queue("tap_scans", SCAN_TAP_DEPTH, Overflow::RejectNewest);
    let (fixes_tx, fixes) = queue("tap_fixes", FIX_TAP_DEPTH, Overflow::RejectNewest);
    let (odo_tx, odometry) = queue("tap_odometry", ODOMETRY_TAP_DEPTH, Overflow::RejectNewest);
    (
        TapSenders {
            scans: scans_tx,
            fixes: fixes_tx,
            odometry: odo_tx,
        },
        Taps {
            scans,
            fixes,
            odometry,
        },
    )
}

/// A wheel odometry reading as a recording keeps it (a JSON document per
/// reading in `run.mcap`, channel `/sweepline/odometry_input`): the
/// driver's increment as the motor stage got it, every number exact.
/// Composing the increments in order gives the odometry pose the scanner
/// stage paired each scan with.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OdometryRecord {
    /// Time of the earlier encoder reading (s, the daemon's clock).
    pub t0: f64,
    /// Time of the later reading (s).
    pub t1: f64,
    /// Motion from the earlier to the later reading in the earlier base
    /// frame (x m, y m, heading rad).
    pub delta: [f64; 3],
    /// Left wheel travel (m).
    pub left: f64,
    /// Right wheel travel (m).
    pub right: f64,
}

impl OdometryRecord {
    /// The record of a reading.
    pub fn of(o: &Odometry) -> Self {
        Self {
            t0: o.t0,
            t1: o.t1,
            delta: xyt(&o.delta),
            left: o.left,
            right: o.right,
        }
    }

    /// The reading back.
    pub fn to_odometry(&self) -> Odometry {
        let [x, y, t] = self.delta;
        Odometry {
            t0: self.t0,
            t1: self.t1,
            delta: crate::geom::pose(x, y, t),
            left: self.left,
            right: self.right,
        }
    }
}

/// A scan as a recording keeps it: everything the localise stage was
/// handed and the sensor's raw values, in plain fields (a JSON document per
/// scan in `run.mcap`, channel `/sweepline/scan_input`). Reading it back
/// gives the very message the stage localised with ([`ScanRecord::to_tap`]).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScanRecord {
    /// Host time of the first beam (s, the daemon's clock).
    pub stamp: f64,
    /// The producer's sequence number.
    pub seq: u64,
    /// Wheel odometry at the scan (x m, y m, heading rad).
    pub odom: [f64; 3],
    /// Whether the odometry reached the end of the sweep.
    pub odom_current: bool,
    /// Time between two delivered scans (s).
    pub interval: f64,
    /// Odometry motion over the window ending with the sweep (x, y, heading).
    pub motion: [f64; 3],
    /// Time from `stamp` to the first beam (s).
    pub first_beam_time: f64,
    /// Time between neighbouring beams (s).
    pub beam_interval: f64,
    /// Beam angles in the sensor frame (rad). Empty in a recording: the
    /// same as the scan before's in the file (a scanner's beams keep their
    /// angles; the first scan of each file has them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub angles: Vec<f64>,
    /// Ranges (m; what the driver made of the raw values).
    pub ranges: Vec<f64>,
    /// Intensities (sensor units; 0 without).
    pub intensities: Vec<f64>,
    /// Indices of the beams that are not valid ranges.
    pub invalid: Vec<u32>,
    /// The 24-bit sensor timestamp as sent (ms).
    pub raw_stamp: u32,
    /// The sensor clock unwrapped (ms).
    pub sensor_ms: u64,
    /// Sensor clock epoch.
    pub epoch: u32,
    /// Scans the sensor's clock says were lost before this one.
    pub dropped_before: u64,
    /// Per beam, the raw value sent: millimetres or an error code.
    pub raw: Vec<u32>,
}

/// Why a recorded scan cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The beam arrays disagree in length or hold too many beams.
    #[error("scan {seq}: {what}")]
    Shape {
        /// The scan's sequence number.
        seq: u64,
        /// What is wrong.
        what: String,
    },
}

/// A finite number, or 0 (JSON has no NaN; a non-finite value of a beam
/// already marked invalid carries nothing).
fn finite(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

fn xyt(p: &crate::geom::Pose) -> [f64; 3] {
    [
        p.translation.vector.x,
        p.translation.vector.y,
        p.rotation.angle(),
    ]
}

impl ScanRecord {
    /// The record of a tapped scan, written into `self` reusing its
    /// buffers.
    pub fn fill_from(&mut self, tap: &TapScan) {
        let m = &tap.msg;
        let s = &m.scan;
        self.stamp = m.stamp;
        self.seq = s.seq;
        self.odom = xyt(&m.odom);
        self.odom_current = m.odom_current;
        self.interval = finite(m.interval);
        self.motion = xyt(&m.motion);
        self.first_beam_time = finite(s.first_beam_time);
        self.beam_interval = finite(s.beam_interval);
        self.angles.clear();
        self.ranges.clear();
        self.intensities.clear();
        self.invalid.clear();
        for (i, b) in s.beams.iter().enumerate() {
            let valid = b.valid && b.range.is_finite() && b.angle.is_finite();
            self.angles.push(finite(b.angle));
            self.ranges.push(finite(b.range));
            self.intensities.push(finite(b.intensity));
            if !valid {
                self.invalid.push(i as u32);
            }
        }
        self.raw_stamp = tap.sensor.raw_stamp;
        self.sensor_ms = tap.sensor.sensor_ms;
        self.epoch = tap.sensor.epoch;
        self.dropped_before = tap.sensor.dropped_before;
        self.raw.clear();
        self.raw.extend_from_slice(&tap.sensor.raw);
    }

    /// The tapped scan back: the message as the localise stage got it
    /// (its hand-over stamp is now).
    pub fn to_tap(&self) -> Result<TapScan, RecordError> {
        let n = self.angles.len();
        let shape = |what: String| RecordError::Shape {
            seq: self.seq,
            what,
        };
        if self.ranges.len() != n || self.intensities.len() != n {
            return Err(shape(format!(
                "{n} angles, {} ranges, {} intensities",
                self.ranges.len(),
                self.intensities.len()
            )));
        }
        if n > MAX_BEAMS || self.raw.len() > MAX_BEAMS {
            return Err(shape(format!("{n} beams, at most {MAX_BEAMS}")));
        }
        let mut scan = crate::scan::LaserScan {
            stamp: self.stamp,
            seq: self.seq,
            first_beam_time: self.first_beam_time,
            beam_interval: self.beam_interval,
            ..Default::default()
        };
        for i in 0..n {
            let _ = scan.beams.push(crate::scan::Beam {
                angle: self.angles[i],
                range: self.ranges[i],
                intensity: self.intensities[i],
                valid: true,
            });
        }
        for &i in &self.invalid {
            let b = scan
                .beams
                .get_mut(i as usize)
                .ok_or_else(|| shape(format!("invalid beam {i} of {n}")))?;
            b.valid = false;
        }
        let [x, y, t] = self.odom;
        let [mx, my, mt] = self.motion;
        let mut raw = heapless::Vec::new();
        for &v in &self.raw {
            let _ = raw.push(v);
        }
        Ok(TapScan {
            msg: ScanMsg {
                t0: crate::pipeline::clock::Stamp::now(),
                stamp: self.stamp,
                odom: crate::geom::pose(x, y, t),
                odom_current: self.odom_current,
                interval: self.interval,
                motion: crate::geom::pose(mx, my, mt),
                scan,
            },
            sensor: SensorScan {
                raw_stamp: self.raw_stamp,
                sensor_ms: self.sensor_ms,
                epoch: self.epoch,
                dropped_before: self.dropped_before,
                raw,
            },
        })
    }
}
