//! A recording read back: the scans as the localise stage got them, the
//! simulator's truth and the map frame's place in the world, for
//! `sweepline replay run.mcap` and its scoring.
//!
//! A recording cut short (the daemon killed, the disk full) reads up to
//! its last whole chunk: [`Recording::complete`] says whether the file
//! ended as a writer closes it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use foxglove::Decode;
use mcap::read::{LinearReader, MessageStream, Options};
use mcap::records::Record;
use sweepline_daemon::daemon::taps::{OdometryRecord, ScanRecord};

use crate::geom::Pose;
use crate::topics;

/// The metadata record mapping message times to the daemon's clock
/// (keys `start`: the daemon clock's seconds, `wall_ns`: the Unix time in
/// nanoseconds it was mapped to).
pub const CLOCK: &str = "clock";

/// Why a recording cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not an MCAP file, or broken before its first message.
    #[error("{path}: not a readable MCAP file: {why}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// A message cannot be decoded.
    #[error("{path}: message {index} on {topic}: {why}")]
    Message {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Its index among the file's messages.
        index: usize,
        /// Why.
        why: String,
    },
}

/// One channel of a recording.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChannelSummary {
    /// The schema's name (empty: none).
    pub schema: String,
    /// The messages' encoding.
    pub encoding: String,
    /// Messages on it.
    pub messages: usize,
    /// Its log times never went backwards.
    pub ordered: bool,
    /// Log time of its last message (ns).
    last: u64,
}

/// What a recording holds.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// Every scan the localise stage was handed, in order.
    pub scans: Vec<ScanRecord>,
    /// Every wheel odometry reading, in order.
    pub odometry: Vec<OdometryRecord>,
    /// The simulator's true poses (daemon-clock s, world frame).
    pub truth: Vec<(f64, Pose)>,
    /// The map frame in the world (`sim` only).
    pub map_to_world: Option<Pose>,
    /// What the daemon was started with (none: not recorded, or unreadable:
    /// the error).
    pub setup: Option<Result<Setup, String>>,
    /// Per topic: schema, encoding, count and order.
    pub channels: BTreeMap<String, ChannelSummary>,
    /// The file ends as a closed recording does (else it was cut short
    /// and read up to its last whole chunk).
    pub complete: bool,
}

impl Recording {
    /// Reads the recording at `path`.
    pub fn read(path: &Path) -> Result<Recording, RecordingError> {
        let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mcap_err = |why: String| RecordingError::Mcap {
            path: path.to_path_buf(),
            why,
        };
        if !bytes.starts_with(mcap::MAGIC) {
            return Err(mcap_err(
                "it does not start with the MCAP magic bytes".into(),
            ));
        }
        let mut rec = Recording::default();
        let metadata = read_metadata(&bytes, &mut rec.complete).map_err(mcap_err)?;
        let clock = metadata
            .get(CLOCK)
            .and_then(|m| Some((num(m, "start")?, num(m, "wall_ns")?)));
        rec.map_to_world = metadata.get(topics::MAP_TO_WORLD).and_then(|m| {
            Some(crate::geom::pose(
                num(m, "x")?,
                num(m, "y")?,
                num(m, "theta")?,
            ))
        });
        rec.setup = metadata.get(SETUP).map(Setup::from_metadata);
        let stream = MessageStream::new_with_options(&bytes, Options::IgnoreEndMagic.into())
            .map_err(|e| mcap_err(e.to_string()))?;
        for (index, msg) in stream.enumerate() {
            let Ok(msg) = msg else {
                // A cut-short file: everything before the cut is kept.
                rec.complete = false;
                break;
            };
            let topic = msg.channel.topic.as_str();
            let bad = |why: String| RecordingError::Message {
                path: path.to_path_buf(),
                topic: topic.to_string(),
                index,
                why,
            };
            let entry = rec
                .channels
                .entry(topic.to_string())
                .or_insert_with(|| ChannelSummary {
                    schema: msg
                        .channel
                        .schema
                        .as_ref()
                        .map(|s| s.name.clone())
                        .unwrap_or_default(),
                    encoding: msg.channel.message_encoding.clone(),
                    ordered: true,
                    ..Default::default()
                });
            entry.messages += 1;
            entry.ordered &= msg.log_time >= entry.last;
            entry.last = msg.log_time;
            match topic {
                topics::SCAN_INPUT => {
                    let mut s: ScanRecord =
                        serde_json::from_slice(&msg.data).map_err(|e| bad(e.to_string()))?;
                    if s.angles.is_empty() {
                        // The same angles as the scan before.
                        let prev = rec.scans.last().ok_or_else(|| {
                            bad("the first scan of the file has no beam angles".into())
                        })?;
                        s.angles.clone_from(&prev.angles);
                    }
                    rec.scans.push(s);
                }
                topics::ODOMETRY_INPUT => {
                    rec.odometry
                        .push(serde_json::from_slice(&msg.data).map_err(|e| bad(e.to_string()))?);
                }
                topics::TRUTH => {
                    let p = foxglove::schemas::PoseInFrame::decode(&msg.data[..])
                        .map_err(|e| bad(e.to_string()))?;
                    let (start, wall_ns) = clock.ok_or_else(|| {
                        bad("no `clock` metadata to place the truth in time".into())
                    })?;
                    let t = start + (msg.log_time as f64 - wall_ns) * 1e-9;
                    rec.truth.push((t, planar(&p.pose.unwrap_or_default())));
                }
                _ => {}
            }
        }
        Ok(rec)
    }
}

/// The number under `key` of a metadata record.
fn num(m: &BTreeMap<String, String>, key: &str) -> Option<f64> {
    m.get(key)?.parse().ok()
}

/// The file's metadata records by name, and whether it ends with a footer.
fn read_metadata(
    bytes: &[u8],
    complete: &mut bool,
) -> Result<BTreeMap<String, BTreeMap<String, String>>, String> {
    let reader = LinearReader::new_with_options(bytes, Options::IgnoreEndMagic.into())
        .map_err(|e| e.to_string())?;
    let mut out = BTreeMap::new();
    *complete = false;
    for record in reader {
        match record {
            Ok(Record::Metadata(m)) => {
                out.insert(m.name, m.metadata);
            }
            Ok(Record::Footer(_)) => *complete = true,
            Ok(_) => {}
            Err(_) => break,
        }
    }
    Ok(out)
}

/// A 3D pose on the floor as a planar one.
pub(crate) fn planar(p: &foxglove::schemas::Pose) -> Pose {
    let v = p.position.unwrap_or_default();
    let q = p.orientation.unwrap_or_default();
    let theta = 2.0 * q.z.atan2(q.w);
    crate::geom::pose(v.x, v.y, theta)
}

/// The metadata record of the run's setup: keys `config` (the daemon's
/// configuration as JSON), `start` and `map_frame` (numbers separated by
/// spaces).
pub const SETUP: &str = "setup";

/// What the daemon was started with, so that a replay starts the same way.
#[derive(Clone, Debug)]
pub struct Setup {
    /// The configuration.
    pub config: sweepline_daemon::config::Config,
    /// The robot pose the daemon was told it starts at (map frame).
    pub start: Pose,
    /// The extent of the map.
    pub frame: sweepline_daemon::daemon::MapFrame,
}

impl Setup {
    /// As a metadata record.
    pub fn to_metadata(&self) -> Result<BTreeMap<String, String>, String> {
        let s = &self.start;
        let f = &self.frame;
        Ok([
            (
                "config".to_string(),
                serde_json::to_string(&self.config).map_err(|e| e.to_string())?,
            ),
            (
                "start".to_string(),
                format!(
                    "{} {} {}",
                    s.translation.vector.x,
                    s.translation.vector.y,
                    s.rotation.angle()
                ),
            ),
            (
                "map_frame".to_string(),
                format!(
                    "{} {} {} {} {}",
                    f.origin.x, f.origin.y, f.resolution, f.width, f.height
                ),
            ),
        ]
        .into_iter()
        .collect())
    }

    /// From a metadata record.
    pub fn from_metadata(m: &BTreeMap<String, String>) -> Result<Setup, String> {
        let get = |k: &str| m.get(k).ok_or_else(|| format!("setup: no `{k}`"));
        let nums = |k: &str, n: usize| -> Result<Vec<f64>, String> {
            let v: Vec<f64> = get(k)?
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|e| format!("setup: `{k}`: {e}"))?;
            if v.len() == n && v.iter().all(|x| x.is_finite()) {
                Ok(v)
            } else {
                Err(format!("setup: `{k}` needs {n} finite numbers"))
            }
        };
        let config: sweepline_daemon::config::Config =
            serde_json::from_str(get("config")?).map_err(|e| format!("setup: config: {e}"))?;
        config
            .validate()
            .map_err(|e| format!("setup: config: {e}"))?;
        let s = nums("start", 3)?;
        let f = nums("map_frame", 5)?;
        Ok(Setup {
            config,
            start: crate::geom::pose(s[0], s[1], s[2]),
            frame: sweepline_daemon::daemon::MapFrame {
                origin: nalgebra::Point2::new(f[0], f[1]),
                resolution: f[2],
                width: f[3] as usize,
                height: f[4] as usize,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A missing file, an empty one and garbage each give an error that
    /// names the file; none panics.
    #[test]
    fn what_is_not_a_recording_is_a_clear_error() {
        let dir = std::env::temp_dir().join(format!("sweepline-badrec-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("missing.mcap");
        assert!(matches!(
            Recording::read(&missing),
            Err(RecordingError::Io { .. })
        ));
        let mut x = 7u32;
        let garbage: Vec<u8> = (0..4096)
            .map(|_| {
                x = x.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                (x >> 24) as u8
            })
            .collect();
        for (name, bytes) in [("empty.mcap", Vec::new()), ("garbage.mcap", garbage)] {
            let p = dir.join(name);
            std::fs::write(&p, bytes).unwrap();
            let e = Recording::read(&p).unwrap_err();
            assert!(matches!(e, RecordingError::Mcap { .. }), "{name}: {e}");
            assert!(e.to_string().contains(name), "{e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// An MCAP file at `path` with `setup` metadata (if given) and the
    /// JSON scan inputs `scans`.
    fn write_recording(path: &Path, setup: Option<BTreeMap<String, String>>, scans: &[&str]) {
        write_topic(path, setup, topics::SCAN_INPUT, scans);
    }

    /// An MCAP file at `path` with `setup` metadata (if given) and the
    /// JSON documents `docs` on `topic`.
    fn write_topic(
        path: &Path,
        setup: Option<BTreeMap<String, String>>,
        topic: &str,
        docs: &[&str],
    ) {
        let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        let mut w = mcap::Writer::new(file).unwrap();
        if let Some(m) = setup {
            w.write_metadata(&mcap::records::Metadata {
                name: SETUP.into(),
                metadata: m,
            })
            .unwrap();
        }
        let schema = w
            .add_schema("sweepline.ScanInput", "jsonschema", b"{}")
            .unwrap();
        let ch = w
            .add_channel(schema, topic, "json", &BTreeMap::new())
            .unwrap();
        for (i, doc) in docs.iter().enumerate() {
            let header = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: i as u32,
                log_time: i as u64,
                publish_time: i as u64,
            };
            w.write_to_known_channel(&header, doc.as_bytes()).unwrap();
        }
        w.finish().unwrap();
    }

    /// A scan input of `n` beams, with angles or without.
    fn scan_json(n: usize, angles: bool) -> String {
        let mut r = ScanRecord {
            seq: 3,
            ranges: vec![1.0; n],
            intensities: vec![0.0; n],
            raw: vec![1000; n],
            ..Default::default()
        };
        if angles {
            r.angles = vec![0.0; n];
        }
        serde_json::to_string(&r).unwrap()
    }

    /// Broken messages and metadata in a well-formed file: each is an error
    /// that names the file, the topic and the message (or the setup key),
    /// and a record whose arrays disagree is refused when it is used.
    #[test]
    fn bad_messages_and_metadata_are_clear_errors() {
        let dir = std::env::temp_dir().join(format!("sweepline-badmsg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = scan_json(4, true);
        let no_angles = scan_json(4, false);
        let cases: [(&str, Vec<&str>, &[&str]); 3] = [
            (
                "json.mcap",
                vec![good.as_str(), "{\"stamp\": [1, 2"],
                &["json.mcap", "scan_input", "1"],
            ),
            (
                "type.mcap",
                vec!["{\"stamp\": \"noon\"}"],
                &["scan_input", "0"],
            ),
            ("angles.mcap", vec![no_angles.as_str()], &["no beam angles"]),
        ];
        for (name, msgs, wants) in &cases {
            let p = dir.join(name);
            write_recording(&p, None, msgs);
            let e = Recording::read(&p).unwrap_err();
            assert!(matches!(e, RecordingError::Message { .. }), "{name}: {e}");
            for w in *wants {
                assert!(e.to_string().contains(w), "{name}: want {w:?} in {e}");
            }
        }
        // A wheel odometry reading that is not one.
        let p = dir.join("odometry.mcap");
        write_topic(&p, None, topics::ODOMETRY_INPUT, &["{\"t0\": \"soon\"}"]);
        let e = Recording::read(&p).unwrap_err();
        assert!(matches!(e, RecordingError::Message { .. }), "{e}");
        assert!(e.to_string().contains("odometry_input"), "{e}");
        // The arrays disagree: read, but refused when turned back into a scan.
        let p = dir.join("shape.mcap");
        let mut r: ScanRecord = serde_json::from_str(&good).unwrap();
        r.intensities.pop();
        let uneven = serde_json::to_string(&r).unwrap();
        write_recording(&p, None, &[&uneven]);
        let rec = Recording::read(&p).unwrap();
        let e = rec.scans[0].to_tap().unwrap_err();
        assert!(e.to_string().contains("3 intensities"), "{e}");
        // A setup that is not one: the recording reads, the setup is the error.
        let robot = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../hw/robot.toml");
        let shipped = sweepline_daemon::config::Config::load(&robot).unwrap();
        for (key, value, want) in [
            ("config", "{not json", "setup: config"),
            ("start", "1 2", "setup: `start` needs 3"),
        ] {
            let mut m: BTreeMap<String, String> = [
                ("config", serde_json::to_string(&shipped).unwrap()),
                ("start", "0 0 0".to_string()),
                ("map_frame", "0 0 0.05 10 10".to_string()),
            ]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
            m.insert(key.into(), value.into());
            let p = dir.join("setup.mcap");
            write_recording(&p, Some(m), &[&good]);
            let rec = Recording::read(&p).unwrap();
            let e = rec.setup.unwrap().unwrap_err();
            assert!(e.contains(want), "{key}: want {want:?} in {e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
