//! What the emulated laser sees. A [`Scene`] answers, for a time and a set of
//! beam angles, one [`Echo`] per beam. The simulator implements it on its
//! worlds (with the robot's pose at that time); this file ships two small
//! scenes: a rectangular room with per-wall reflectivity and range noise, and
//! the replay of one fixed recorded scan.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// What one beam returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Echo {
    /// A surface at `range` metres of reflectivity `reflectivity`, seen at
    /// `cos_incidence` from its normal.
    Hit {
        /// Range (m).
        range: f64,
        /// The surface's reflectivity, 0 (black) to 1 (retro-reflector).
        reflectivity: f64,
        /// Cosine of the angle between the beam and the surface normal (1
        /// head-on, towards 0 edge-on): the sensor works out from both how
        /// strong the echo is and what intensity it reports.
        cos_incidence: f64,
    },
    /// Nothing within the sensor's range.
    NoReturn,
    /// The sensor's own error code for this beam (below DMIN on the wire).
    Error(u32),
}

/// A world the emulated scanner looks into.
pub trait Scene: Send {
    /// Fills `out[i]` with the echo of the beam at `angles[i]` (rad, sensor
    /// frame, counter-clockwise, 0 = front), measured at time
    /// `t + i × step_time` (s, emulator clock): the sensor sweeps its beams
    /// one after the other, so a moving sensor sees each from where it is
    /// then.
    fn sample(&mut self, t: f64, step_time: f64, angles: &[f64], out: &mut [Echo]);
}

/// An axis-aligned rectangular room seen from a fixed sensor pose.
#[derive(Clone, Debug)]
pub struct RectRoom {
    /// Room extent along x (m), walls at x = 0 and x = width.
    pub width: f64,
    /// Room extent along y (m), walls at y = 0 and y = depth.
    pub depth: f64,
    /// Sensor position (m) and heading (rad) in the room.
    pub pose: (f64, f64, f64),
    /// Reflectivity of the walls at x = width, y = depth, x = 0, y = 0.
    pub reflectivity: [f64; 4],
    /// Standard deviation of the Gaussian range noise (m); 0 = exact.
    pub noise: f64,
    /// Stretches of wall that differ from the rest (doorways, dark panels).
    pub patches: Vec<WallPatch>,
    rng: ChaCha8Rng,
}

/// A stretch of one wall of a [`RectRoom`] with its own surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallPatch {
    /// Which wall, numbered as [`RectRoom::reflectivity`].
    pub wall: usize,
    /// Where it starts and ends along the wall (m): the x coordinate on the
    /// walls y = 0 and y = depth, the y coordinate on the others.
    pub span: (f64, f64),
    /// Its reflectivity; `None` is an opening (a doorway onto a corridor
    /// longer than any scanner reaches).
    pub reflectivity: Option<f64>,
}

impl RectRoom {
    /// A room of `width` × `depth` metres with the sensor at `pose`, noise
    /// drawn from a generator seeded with `seed`.
    pub fn new(width: f64, depth: f64, pose: (f64, f64, f64), seed: u64) -> Self {
        Self {
            width,
            depth,
            pose,
            reflectivity: [0.8, 0.5, 0.3, 0.6],
            noise: 0.0,
            patches: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// The default bench room: 4 × 3 m, sensor at (1.5, 1.2) facing +x, so
    /// the front wall is 2.5 m away; 5 mm noise. Like the office of the
    /// real capture it has places a URG-04LX cannot measure: a 0.9 m
    /// doorway in the left wall (x 2.6-3.5 m) and a black panel (reflectivity
    /// 0.03) at the left end of the front wall (y 2.2-3 m, 2.7-3.1 m away),
    /// about 12 % of the scan in all.
    pub fn bench(seed: u64) -> Self {
        let mut r = Self::new(4.0, 3.0, (1.5, 1.2, 0.0), seed);
        r.noise = 0.005;
        r.patches = vec![
            WallPatch {
                wall: 1,
                span: (2.6, 3.5),
                reflectivity: None,
            },
            WallPatch {
                wall: 0,
                span: (2.2, 3.0),
                reflectivity: Some(0.03),
            },
        ];
        r
    }

    /// The surface of `wall` at `along` metres along it.
    fn surface(&self, wall: usize, along: f64) -> Option<f64> {
        let patch = self
            .patches
            .iter()
            .find(|p| p.wall == wall && (p.span.0..=p.span.1).contains(&along));
        match patch {
            Some(p) => p.reflectivity,
            None => self.reflectivity.get(wall).copied(),
        }
    }

    /// The exact (noise-free) echo of one beam.
    pub fn trace(&self, angle: f64) -> Echo {
        let (x, y, th) = self.pose;
        let inside = (0.0..=self.width).contains(&x) && (0.0..=self.depth).contains(&y);
        if !(inside && self.width > 0.0 && self.depth > 0.0) {
            return Echo::NoReturn;
        }
        let (dy, dx) = (th + angle).sin_cos();
        let mut best = (f64::INFINITY, 0usize);
        let mut consider = |t: f64, wall: usize| {
            if t.is_finite() && t > 0.0 && t < best.0 {
                best = (t, wall);
            }
        };
        if dx > 1e-12 {
            consider((self.width - x) / dx, 0);
        } else if dx < -1e-12 {
            consider(-x / dx, 2);
        }
        if dy > 1e-12 {
            consider((self.depth - y) / dy, 1);
        } else if dy < -1e-12 {
            consider(-y / dy, 3);
        }
        if !best.0.is_finite() {
            return Echo::NoReturn;
        }
        let (range, wall) = best;
        // Walls 0 and 2 face x, 1 and 3 face y: cos(incidence) is the
        // beam's component along the wall's normal.
        let (along, cos) = if wall % 2 == 0 {
            (y + range * dy, dx.abs())
        } else {
            (x + range * dx, dy.abs())
        };
        match self.surface(wall, along) {
            Some(r) => Echo::Hit {
                range,
                reflectivity: r,
                cos_incidence: cos,
            },
            None => Echo::NoReturn,
        }
    }
}

impl Scene for RectRoom {
    fn sample(&mut self, _t: f64, _step_time: f64, angles: &[f64], out: &mut [Echo]) {
        for (a, o) in angles.iter().zip(out.iter_mut()) {
            *o = match self.trace(*a) {
                Echo::Hit {
                    range,
                    reflectivity,
                    cos_incidence,
                } => {
                    let n = if self.noise > 0.0 {
                        // Box-Muller from two uniforms: deterministic per seed.
                        let u1: f64 = self.rng.random_range(f64::EPSILON..1.0);
                        let u2: f64 = self.rng.random();
                        self.noise * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
                    } else {
                        0.0
                    };
                    Echo::Hit {
                        range: (range + n).max(0.0),
                        reflectivity,
                        cos_incidence,
                    }
                }
                e => e,
            };
        }
    }
}

/// Replays one recorded scan forever: each beam gets the recorded value of
/// the nearest recorded step.
#[derive(Clone, Debug)]
pub struct ReplayScan {
    first_angle: f64,
    step_angle: f64,
    values: Vec<Echo>,
}

impl ReplayScan {
    /// A recorded scan: `values[k]` was measured at angle
    /// `first_angle + k · step_angle`.
    pub fn new(first_angle: f64, step_angle: f64, values: Vec<Echo>) -> Self {
        Self {
            first_angle,
            step_angle,
            values,
        }
    }

    /// The number of recorded beams.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether no beam was recorded.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
}

impl Scene for ReplayScan {
    fn sample(&mut self, _t: f64, _step_time: f64, angles: &[f64], out: &mut [Echo]) {
        for (a, o) in angles.iter().zip(out.iter_mut()) {
            let k = ((a - self.first_angle) / self.step_angle).round();
            *o = if k >= 0.0 && (k as usize) < self.values.len() && self.step_angle != 0.0 {
                self.values[k as usize]
            } else {
                Echo::NoReturn
            };
        }
    }
}

/// Why a recorded scan could not be loaded for replay.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The capture file could not be read.
    #[error("cannot read capture {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A record header or length runs past the end of the file.
    #[error("capture is truncated at byte {0} (records are u32 s, u32 us, u32 length, bytes)")]
    Truncated(usize),
    /// The sensor's PP reply is not in the capture.
    #[error("capture holds no PP reply (needed for the step angles)")]
    NoParams,
    /// No scan reply decodes in the capture.
    #[error("capture holds no valid scan reply")]
    NoScan,
}

/// Concatenates the payloads of a byte capture in the hokuyoaist log format
/// (records of big-endian u32 seconds, u32 microseconds, u32 length, bytes).
pub fn capture_stream(file: &[u8]) -> Result<Vec<u8>, ReplayError> {
    let mut out = Vec::with_capacity(file.len());
    let mut i = 0;
    while i < file.len() {
        let head = file.get(i..i + 12).ok_or(ReplayError::Truncated(i))?;
        let len = u32::from_be_bytes([head[8], head[9], head[10], head[11]]) as usize;
        let body = file
            .get(i + 12..i + 12 + len)
            .ok_or(ReplayError::Truncated(i))?;
        out.extend_from_slice(body);
        i += 12 + len;
    }
    Ok(out)
}

impl ReplayScan {
    /// The first scan in a sensor's reply stream (e.g. the `.logr` side of a
    /// capture, see [`capture_stream`]), with angles from the PP reply in
    /// the same stream. Error codes replay as the same codes; intensities,
    /// when recorded, set the reflectivity.
    pub(crate) fn from_reply_stream(bytes: &[u8]) -> Result<Self, ReplayError> {
        use crate::scip::{Decoder, DecoderOptions, Event, Reading, ReplyBody};
        let mut dec = Decoder::new(DecoderOptions { lenient_kv: true });
        let mut params = None;
        let mut rest = bytes;
        while !rest.is_empty() {
            let (used, ev) = dec.feed(rest);
            rest = &rest[used..];
            let Some(Event::Reply(raw)) = ev else {
                continue;
            };
            let Ok(reply) = raw.decode() else { continue };
            match reply.body {
                ReplyBody::Params(p) => params = Some(p),
                ReplyBody::Scan(scan) => {
                    let p = params.as_ref().ok_or(ReplayError::NoParams)?;
                    let group = f64::from(scan.request.cluster.group());
                    let first =
                        p.angle_of_step(f64::from(scan.request.start) + (group - 1.0) / 2.0);
                    let values = scan
                        .readings(p)
                        .map(|(v, r)| match r {
                            Reading::Range(mm) => {
                                let range = f64::from(mm) / 1000.0;
                                Echo::Hit {
                                    range,
                                    // The recorded intensity, head-on.
                                    reflectivity: v.intensity.map_or(0.5, |i| {
                                        super::intensity::reflectivity_of(f64::from(i), range)
                                    }),
                                    cos_incidence: 1.0,
                                }
                            }
                            Reading::Error(e) => Echo::Error(e.code),
                            Reading::BeyondMax(_) => Echo::NoReturn,
                        })
                        .collect();
                    return Ok(ReplayScan::new(first, p.step_angle() * group, values));
                }
                _ => {}
            }
        }
        Err(ReplayError::NoScan)
    }

    /// `ReplayScan::from_reply_stream` of a capture file's read side.
    pub fn from_capture_file(path: &std::path::Path) -> Result<Self, ReplayError> {
        let file = std::fs::read(path).map_err(|source| ReplayError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_reply_stream(&capture_stream(&file)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn room_distances_and_walls() {
        let r = RectRoom::bench(1);
        assert_eq!(
            r.trace(0.0),
            Echo::Hit {
                range: 2.5,
                reflectivity: 0.8,
                cos_incidence: 1.0
            }
        );
        match r.trace(FRAC_PI_2) {
            Echo::Hit {
                range,
                reflectivity,
                ..
            } => {
                assert!((range - 1.8).abs() < 1e-9);
                assert_eq!(reflectivity, 0.5);
            }
            e => panic!("{e:?}"),
        }
        let outside = RectRoom::new(1.0, 1.0, (5.0, 5.0, 0.0), 0);
        assert_eq!(outside.trace(0.0), Echo::NoReturn);
    }

    #[test]
    fn noise_is_seeded() {
        let angles = [0.0, 0.5, 1.0];
        let mut a = [Echo::NoReturn; 3];
        let mut b = [Echo::NoReturn; 3];
        RectRoom::bench(7).sample(0.0, 0.0, &angles, &mut a);
        RectRoom::bench(7).sample(0.0, 0.0, &angles, &mut b);
        assert_eq!(a, b);
        let Echo::Hit { range, .. } = a[0] else {
            panic!()
        };
        assert!((range - 2.5).abs() < 0.05);
    }

    #[test]
    fn truncated_capture_is_a_typed_error() {
        let e = capture_stream(&[0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 9, 1]).unwrap_err();
        assert!(matches!(e, ReplayError::Truncated(0)), "{e}");
        assert!(matches!(
            ReplayScan::from_reply_stream(b"garbage\n\n"),
            Err(ReplayError::NoScan)
        ));
        assert!(matches!(
            ReplayScan::from_capture_file(std::path::Path::new("/nonexistent.logr")),
            Err(ReplayError::Io { .. })
        ));
    }

    #[test]
    fn replay_picks_nearest_step() {
        let mut s = ReplayScan::new(
            -1.0,
            0.5,
            vec![
                Echo::Error(7),
                Echo::NoReturn,
                Echo::Hit {
                    range: 1.0,
                    reflectivity: 0.1,
                    cos_incidence: 1.0,
                },
            ],
        );
        let mut out = [Echo::NoReturn; 3];
        s.sample(0.0, 0.0, &[-1.1, 0.05, 9.0], &mut out);
        assert_eq!(out[0], Echo::Error(7));
        assert!(matches!(out[1], Echo::Hit { .. }));
        assert_eq!(out[2], Echo::NoReturn);
    }
}
