//! Reader for CARMEN log files (`.clf`, `.log`, optionally gzip-compressed):
//! `FLASER` and `ROBOTLASER1` laser messages (with remissions) and `ODOM`.
//! `PARAM`, `NEFF`, comments and other message types are skipped.
//!
//! Formats are described in `../shared/datasets/README.md`. Beam angles of
//! `FLASER` are not stored in the file; we use the convention of CSM and of the
//! benchmark evaluation: 180° field of view, beam `i` at `-90° + i·180°/(n-1)`.
//! Every malformed line is an error naming the line number and what was expected.

use std::io::BufRead;
use std::path::Path;

use crate::capacity::MAX_BEAMS;
use crate::geom::{pose, Pose};
use crate::scan::{Beam, LaserScan};

/// Why a CARMEN log could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CarmenError {
    /// The file could not be opened or read (or is not valid gzip).
    #[error("cannot read CARMEN log {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS or decompression error.
        source: std::io::Error,
    },
    /// A line does not follow the message format.
    #[error("line {line}: {message}")]
    Malformed {
        /// 1-based line number.
        line: usize,
        /// What was expected and what was found.
        message: String,
    },
}

/// One laser message (`FLASER` or `ROBOTLASER1`) of a log.
#[derive(Clone, Debug, PartialEq)]
pub struct LaserRecord {
    /// Acquisition time (`ipc_timestamp`), seconds; the relations files refer to it.
    pub stamp: f64,
    /// Time since the logger started (`logger_timestamp`), seconds.
    pub logger_stamp: f64,
    /// Angle of the first beam in the sensor frame (rad).
    pub start_angle: f64,
    /// Angle between successive beams (rad, positive = counter-clockwise).
    pub angle_step: f64,
    /// Ranges in metres, in scanning order.
    pub ranges: Vec<f64>,
    /// Remission (intensity) values; empty when the log has none.
    pub remissions: Vec<f64>,
    /// Pose of the laser in the log's world frame (odometry-based in raw logs).
    pub laser_pose: Pose,
    /// Pose of the robot from wheel odometry.
    pub odom_pose: Pose,
}

/// One odometry message (`ODOM`).
#[derive(Clone, Debug, PartialEq)]
pub struct OdomRecord {
    /// Acquisition time (`ipc_timestamp`), seconds.
    pub stamp: f64,
    /// Odometry pose.
    pub pose: Pose,
    /// Translational velocity (m/s).
    pub tv: f64,
    /// Rotational velocity (rad/s).
    pub(crate) rv: f64,
}

/// A message of interest in a CARMEN log.
#[derive(Clone, Debug, PartialEq)]
pub enum Record {
    /// A laser scan with its poses.
    Laser(LaserRecord),
    /// An odometry reading.
    Odom(OdomRecord),
}

/// A whole log: the records in file order, and how many lines were skipped.
#[derive(Clone, Debug, Default)]
pub struct CarmenLog {
    /// `FLASER`, `ROBOTLASER1` and `ODOM` records, in file order.
    pub records: Vec<Record>,
    /// Lines skipped: comments, blank lines, `PARAM`, `NEFF` and other message types.
    pub skipped_lines: usize,
}

impl CarmenLog {
    /// The laser records, in file order.
    pub fn lasers(&self) -> impl Iterator<Item = &LaserRecord> {
        self.records.iter().filter_map(|r| match r {
            Record::Laser(l) => Some(l),
            Record::Odom(_) => None,
        })
    }
}

/// Value at or above which a range means "no return" in the benchmark logs
/// (81.91 m in the SICK logs); CSM drops readings outside (0, 80) m likewise.
pub const NO_RETURN_RANGE: f64 = 80.0;

impl LaserRecord {
    /// Angle of beam `i` in the sensor frame (rad).
    pub fn beam_angle(&self, i: usize) -> f64 {
        self.start_angle + i as f64 * self.angle_step
    }

    /// Converts the record to a [`LaserScan`] in the sensor frame. Beams whose
    /// range is not finite, not positive, or at least `max_range` are marked invalid.
    /// Intensities are the remissions when the log has one per beam, else 0.
    /// Scans with more than [`MAX_BEAMS`] beams cannot occur: the parser rejects them.
    pub fn to_scan(&self, seq: u64, max_range: f64) -> LaserScan {
        let mut scan = LaserScan {
            stamp: self.stamp,
            seq,
            beams: heapless::Vec::new(),
            // The logs do not say when each beam was measured.
            ..LaserScan::default()
        };
        let with_rem = self.remissions.len() == self.ranges.len();
        for (i, &r) in self.ranges.iter().enumerate().take(MAX_BEAMS) {
            let beam = Beam {
                angle: self.beam_angle(i),
                range: r,
                intensity: if with_rem { self.remissions[i] } else { 0.0 },
                valid: r.is_finite() && r > 0.0 && r < max_range,
            };
            // Capacity is MAX_BEAMS and we take at most MAX_BEAMS beams.
            let _ = scan.beams.push(beam);
        }
        scan
    }
}

/// Opens and reads a whole CARMEN log; a name ending in `.gz` is decompressed.
pub fn read_file(path: &Path) -> Result<CarmenLog, CarmenError> {
    let io = |source| CarmenError::Io {
        path: path.display().to_string(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let gz = path.extension().is_some_and(|e| e == "gz");
    if gz {
        read(std::io::BufReader::new(flate2::read::GzDecoder::new(file)))
            .map_err(|e| relabel(e, path))
    } else {
        read(std::io::BufReader::new(file)).map_err(|e| relabel(e, path))
    }
}

fn relabel(e: CarmenError, path: &Path) -> CarmenError {
    match e {
        CarmenError::Io { source, .. } => CarmenError::Io {
            path: path.display().to_string(),
            source,
        },
        other => other,
    }
}

/// Reads a CARMEN log from any buffered reader.
pub fn read<R: BufRead>(reader: R) -> Result<CarmenLog, CarmenError> {
    let mut log = CarmenLog::default();
    for (i, line) in reader.split(b'\n').enumerate() {
        let line_no = i + 1;
        let bytes = line.map_err(|source| CarmenError::Io {
            path: "<stream>".into(),
            source,
        })?;
        let text = std::str::from_utf8(&bytes).map_err(|_| CarmenError::Malformed {
            line: line_no,
            message: "expected ASCII text, found bytes that are not UTF-8".into(),
        })?;
        match parse_line(text, line_no)? {
            Some(r) => log.records.push(r),
            None => log.skipped_lines += 1,
        }
    }
    Ok(log)
}

/// Parses one line. `Ok(None)` for lines that are skipped on purpose (blank,
/// `#` comments, `PARAM`, `NEFF` and other well-formed message names).
pub(crate) fn parse_line(line: &str, line_no: usize) -> Result<Option<Record>, CarmenError> {
    let line = line.trim_end_matches(['\r', '\n']);
    let trimmed = line.trim_start();
    if trimmed.is_empty() || trimmed.starts_with('#') {
        return Ok(None);
    }
    let mut f = Fields::new(trimmed, line_no);
    let name = f.word("a message name")?;
    match name {
        "FLASER" => parse_flaser(&mut f).map(|l| Some(Record::Laser(l))),
        "ROBOTLASER1" => parse_robotlaser1(&mut f).map(|l| Some(Record::Laser(l))),
        "ODOM" => parse_odom(&mut f).map(|o| Some(Record::Odom(o))),
        _ if is_message_name(name) => Ok(None),
        other => Err(CarmenError::Malformed {
            line: line_no,
            message: format!(
                "expected a message name (FLASER, ROBOTLASER1, ODOM, PARAM, ...), found `{}`",
                shorten(other)
            ),
        }),
    }
}

fn is_message_name(s: &str) -> bool {
    s.len() <= 40
        && s.starts_with(|c: char| c.is_ascii_uppercase())
        && s.chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
}

fn shorten(s: &str) -> String {
    let mut out: String = s.chars().take(24).collect();
    if s.chars().count() > 24 {
        out.push('…');
    }
    out
}

/// A cursor over the space-separated fields of one line.
struct Fields<'a> {
    it: std::str::SplitAsciiWhitespace<'a>,
    line: usize,
    msg: &'static str,
}

impl<'a> Fields<'a> {
    fn new(line: &'a str, line_no: usize) -> Self {
        Self {
            it: line.split_ascii_whitespace(),
            line: line_no,
            msg: "line",
        }
    }

    fn err(&self, message: String) -> CarmenError {
        CarmenError::Malformed {
            line: self.line,
            message,
        }
    }

    fn word(&mut self, what: &str) -> Result<&'a str, CarmenError> {
        match self.it.next() {
            Some(w) => Ok(w),
            None => Err(self.err(format!("{}: expected {what}, found end of line", self.msg))),
        }
    }

    fn num(&mut self, what: &str) -> Result<f64, CarmenError> {
        let w = self.word(what)?;
        w.parse::<f64>().map_err(|_| {
            self.err(format!(
                "{}: expected {what} (a number), found `{}`",
                self.msg,
                shorten(w)
            ))
        })
    }

    fn finite(&mut self, what: &str) -> Result<f64, CarmenError> {
        let v = self.num(what)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.err(format!(
                "{}: expected {what} to be a finite number, found {v}",
                self.msg
            )))
        }
    }

    fn count(&mut self, what: &str, max: usize) -> Result<usize, CarmenError> {
        let w = self.word(what)?;
        let n: usize = w.parse().map_err(|_| {
            self.err(format!(
                "{}: expected {what} (a non-negative integer), found `{}`",
                self.msg,
                shorten(w)
            ))
        })?;
        if n > max {
            return Err(self.err(format!(
                "{}: {what} is {n}, more than the {max} this reader supports",
                self.msg
            )));
        }
        Ok(n)
    }

    /// `n` numbers; ranges may be NaN/inf in the file (they become invalid beams).
    fn nums(&mut self, n: usize, what: &str) -> Result<Vec<f64>, CarmenError> {
        let mut v = Vec::with_capacity(n);
        for i in 0..n {
            let w = self.it.next().ok_or_else(|| {
                self.err(format!(
                    "{}: expected {n} {what}, found end of line after {i}",
                    self.msg
                ))
            })?;
            v.push(w.parse::<f64>().map_err(|_| {
                self.err(format!(
                    "{}: expected {what} #{} (a number), found `{}`",
                    self.msg,
                    i + 1,
                    shorten(w)
                ))
            })?);
        }
        Ok(v)
    }

    fn pose(&mut self, what: &str) -> Result<Pose, CarmenError> {
        let x = self.finite(&format!("{what} x"))?;
        let y = self.finite(&format!("{what} y"))?;
        let t = self.finite(&format!("{what} theta"))?;
        Ok(pose(x, y, t))
    }

    /// `ipc_timestamp ipc_hostname logger_timestamp`; returns the two stamps.
    fn stamps(&mut self) -> Result<(f64, f64), CarmenError> {
        let ipc = self.finite("ipc_timestamp")?;
        self.word("ipc_hostname")?;
        let logger = self.finite("logger_timestamp")?;
        if let Some(extra) = self.it.next() {
            return Err(self.err(format!(
                "{}: expected end of line after logger_timestamp, found `{}`",
                self.msg,
                shorten(extra)
            )));
        }
        Ok((ipc, logger))
    }
}

fn parse_flaser(f: &mut Fields<'_>) -> Result<LaserRecord, CarmenError> {
    f.msg = "FLASER";
    let n = f.count("the number of beams", MAX_BEAMS)?;
    let ranges = f.nums(n, "ranges")?;
    let laser_pose = f.pose("laser pose")?;
    let odom_pose = f.pose("odometry pose")?;
    let (stamp, logger_stamp) = f.stamps()?;
    let fov = std::f64::consts::PI;
    let angle_step = if n > 1 { fov / (n - 1) as f64 } else { 0.0 };
    Ok(LaserRecord {
        stamp,
        logger_stamp,
        start_angle: -fov / 2.0,
        angle_step,
        ranges,
        remissions: Vec::new(),
        laser_pose,
        odom_pose,
    })
}

fn parse_robotlaser1(f: &mut Fields<'_>) -> Result<LaserRecord, CarmenError> {
    f.msg = "ROBOTLASER1";
    f.num("laser_type")?;
    let start_angle = f.finite("start_angle")?;
    f.finite("field_of_view")?;
    let angle_step = f.finite("angular_resolution")?;
    f.num("maximum_range")?;
    f.num("accuracy")?;
    f.num("remission_mode")?;
    let n = f.count("the number of ranges", MAX_BEAMS)?;
    let ranges = f.nums(n, "ranges")?;
    let m = f.count("the number of remissions", MAX_BEAMS)?;
    let remissions = f.nums(m, "remissions")?;
    let laser_pose = f.pose("laser pose")?;
    let odom_pose = f.pose("robot pose")?;
    for what in [
        "laser_tv",
        "laser_rv",
        "forward_safety_dist",
        "side_safety_dist",
        "turn_axis",
    ] {
        f.num(what)?;
    }
    let (stamp, logger_stamp) = f.stamps()?;
    Ok(LaserRecord {
        stamp,
        logger_stamp,
        start_angle,
        angle_step,
        ranges,
        remissions,
        laser_pose,
        odom_pose,
    })
}

fn parse_odom(f: &mut Fields<'_>) -> Result<OdomRecord, CarmenError> {
    f.msg = "ODOM";
    let pose = f.pose("odometry pose")?;
    let tv = f.finite("tv")?;
    let rv = f.finite("rv")?;
    f.num("accel")?;
    let (stamp, _) = f.stamps()?;
    Ok(OdomRecord {
        stamp,
        pose,
        tv,
        rv,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flaser(n: usize) -> String {
        let ranges: Vec<String> = (0..n)
            .map(|i| format!("{}", 1.0 + i as f64 * 0.01))
            .collect();
        format!(
            "FLASER {n} {} 1.0 2.0 0.5 1.1 2.1 0.6 1134864645.90321 nohost 0.1234",
            ranges.join(" ")
        )
    }

    #[test]
    fn flaser_parses_with_angles_and_poses() {
        let r = parse_line(&flaser(361), 1).unwrap().unwrap();
        let Record::Laser(l) = r else {
            panic!("expected a laser record")
        };
        assert_eq!(l.ranges.len(), 361);
        assert!((l.beam_angle(0) + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((l.beam_angle(360) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((l.beam_angle(180)).abs() < 1e-12);
        assert!((l.stamp - 1134864645.90321).abs() < 1e-6);
        assert!((l.laser_pose.translation.x - 1.0).abs() < 1e-12);
        assert!((l.odom_pose.rotation.angle() - 0.6).abs() < 1e-12);
        assert!(l.remissions.is_empty());
    }

    #[test]
    fn robotlaser1_reads_remissions() {
        let line = "ROBOTLASER1 0 -1.5708 3.1416 0.0174 81.9 0.01 1 3 1.0 2.0 81.95 3 0.1 0.9 0.3 \
                    0.1 0.2 0.3 0.0 0.0 0.3 0.5 0.1 1.0 0.5 0.2 12.5 host 0.5";
        let Record::Laser(l) = parse_line(line, 7).unwrap().unwrap() else {
            panic!("expected a laser record")
        };
        assert_eq!(l.ranges, vec![1.0, 2.0, 81.95]);
        assert_eq!(l.remissions, vec![0.1, 0.9, 0.3]);
        assert!((l.angle_step - 0.0174).abs() < 1e-12);
        assert_eq!(l.stamp, 12.5);
        let scan = l.to_scan(0, NO_RETURN_RANGE);
        assert_eq!(scan.beams.len(), 3);
        assert!(scan.beams[0].valid && scan.beams[1].valid && !scan.beams[2].valid);
        assert_eq!(scan.beams[1].intensity, 0.9);
    }

    #[test]
    fn odom_param_neff_and_comments() {
        let text = "# a comment\n\nPARAM robot_frontlaser_offset 0.0 nohost 0\nNEFF 1 2 3\n\
                    ODOM 1.0 2.0 0.1 0.3 0.01 0.0 100.5 host 0.5\n";
        let log = read(text.as_bytes()).unwrap();
        assert_eq!(log.records.len(), 1);
        assert_eq!(log.skipped_lines, 4);
        let Record::Odom(o) = &log.records[0] else {
            panic!("expected odometry")
        };
        assert_eq!(o.stamp, 100.5);
        assert_eq!(o.tv, 0.3);
    }

    fn malformed(text: &str) -> (usize, String) {
        match read(text.as_bytes()) {
            Err(CarmenError::Malformed { line, message }) => (line, message),
            other => panic!("expected a malformed-line error, got {other:?}"),
        }
    }

    #[test]
    fn short_flaser_names_line_and_count() {
        let text = format!("# header\n{}\nFLASER 361 1.0 2.0\n", flaser(3));
        let (line, msg) = malformed(&text);
        assert_eq!(line, 3);
        assert!(
            msg.contains("expected 361 ranges") && msg.contains("after 2"),
            "{msg}"
        );
    }

    #[test]
    fn garbage_is_rejected_with_what_was_expected() {
        let (line, msg) = malformed("FLASER x 1 2\n");
        assert_eq!(line, 1);
        assert!(msg.contains("number of beams"), "{msg}");

        let (_, msg) = malformed("FLASER 2 1.0 abc 0 0 0 0 0 0 1 h 1\n");
        assert!(msg.contains("ranges #2") && msg.contains("abc"), "{msg}");

        let (_, msg) = malformed("\u{1}\u{7f}garbage\n");
        assert!(msg.contains("message name"), "{msg}");

        let (_, msg) = malformed("1.0 2.0 3.0\n");
        assert!(msg.contains("message name"), "{msg}");

        let (_, msg) = malformed("FLASER 99999 1\n");
        assert!(msg.contains("more than"), "{msg}");

        let (_, msg) = malformed("ODOM 1 2 nan 0 0 0 1 h 1\n");
        assert!(msg.contains("finite"), "{msg}");

        let (_, msg) = malformed(&format!("{} extra\n", flaser(2)));
        assert!(msg.contains("end of line"), "{msg}");

        let bytes: &[u8] = b"FLASER 1 \xff\xfe 0 0 0 0 0 0 1 h 1\n";
        assert!(matches!(
            read(bytes),
            Err(CarmenError::Malformed { line: 1, .. })
        ));
    }

    #[test]
    fn nan_and_inf_ranges_become_invalid_beams() {
        let line = "FLASER 4 nan inf -1 2.5 0 0 0 0 0 0 1 h 1";
        let Record::Laser(l) = parse_line(line, 1).unwrap().unwrap() else {
            panic!("expected a laser record")
        };
        let scan = l.to_scan(3, NO_RETURN_RANGE);
        let valid: Vec<bool> = scan.beams.iter().map(|b| b.valid).collect();
        assert_eq!(valid, vec![false, false, false, true]);
        assert_eq!(scan.seq, 3);
    }

    #[test]
    fn missing_file_is_an_io_error() {
        let e = read_file(Path::new("/nonexistent/x.clf")).unwrap_err();
        assert!(matches!(e, CarmenError::Io { .. }));
        assert!(e.to_string().contains("/nonexistent/x.clf"));
    }
}
