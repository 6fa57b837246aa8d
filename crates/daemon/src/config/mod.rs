//! The daemon's configuration: one TOML file (`hw/robot.toml` is the documented
//! default), one table per stage. Unknown keys and bad values are errors that
//! name the key.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::param_check::{invalid, ParamError};

mod telemetry;
pub use telemetry::{LiveParams, RecordParams};

pub use crate::robot::RobotParams;

/// The whole configuration file.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// The robot's body and drive limits.
    pub robot: RobotParams,
    /// Scanner driver.
    pub scanner: crate::urg::UrgParams,
    /// Wheel-base link.
    pub motor: crate::motor::MotorParams,
    /// Scan matcher.
    pub icp: crate::icp::IcpParams,
    /// Map.
    pub map: crate::map::MapParams,
    /// Cell decomposition.
    pub decomp: crate::decomp::DecompParams,
    /// Coverage planner.
    pub plan: crate::plan::PlanParams,
    /// Path follower.
    pub control: crate::control::ControlParams,
    /// Pipeline budgets.
    pub pipeline: crate::pipeline::PipelineParams,
    /// The daemon's own settings (giving paths up, bumper contact marks).
    pub daemon: crate::daemon::DaemonParams,
    /// The live view of `sweepline run`.
    pub live: LiveParams,
    /// The recording of `sweepline run`.
    pub record: RecordParams,
}

/// Why a configuration could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read config {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The TOML is malformed, has an unknown key or a value of the wrong type.
    #[error("config {path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message, naming the key and line.
        message: String,
    },
    /// A value parsed but is out of its allowed range.
    #[error("config key `{key}`: {message}")]
    Invalid {
        /// Dotted key, e.g. `robot.radius`.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

/// Largest configuration file accepted (bytes); the shipped one is ~5 KB.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// Longest excerpt of the offending line or parser message put in an error.
const MAX_EXCERPT: usize = 120;

/// `s` cut to at most `max` bytes on a character boundary, with `…` if cut.
fn excerpt(s: &str, max: usize) -> String {
    if s.len() <= max {
        return s.to_string();
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}…", &s[..end])
}

/// A one-line parse error: line, column, the parser's message and an excerpt
/// of the offending line (which shows the key), whatever the input's size.
fn parse_error(text: &str, origin: &str, e: &toml::de::Error) -> ConfigError {
    let msg = excerpt(
        e.message().trim().replace('\n', " ").as_str(),
        3 * MAX_EXCERPT,
    );
    let message = match e.span() {
        Some(span) => {
            let mut start = span.start.min(text.len());
            while !text.is_char_boundary(start) {
                start -= 1;
            }
            let before = &text[..start];
            let line = before.matches('\n').count() + 1;
            let line_start = before.rfind('\n').map_or(0, |i| i + 1);
            let column = text[line_start..start].chars().count() + 1;
            let line_text = text[line_start..].lines().next().unwrap_or("").trim();
            format!(
                "line {line}, column {column}: {msg} (at `{}`)",
                excerpt(line_text, MAX_EXCERPT)
            )
        }
        None => msg,
    };
    ConfigError::Parse {
        path: origin.to_string(),
        message,
    }
}

impl Config {
    /// Parses a configuration from TOML text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let cfg: Config = toml::from_str(text).map_err(|e| parse_error(text, origin, &e))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Reads and parses a configuration file (at most [`MAX_CONFIG_BYTES`],
    /// UTF-8).
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        use std::io::Read;
        let io = |source| ConfigError::Io {
            path: path.display().to_string(),
            source,
        };
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .map_err(io)?
            .take(MAX_CONFIG_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        if bytes.len() as u64 > MAX_CONFIG_BYTES {
            return Err(ConfigError::Parse {
                path: path.display().to_string(),
                message: format!("larger than {MAX_CONFIG_BYTES} bytes: not a config file"),
            });
        }
        let text = String::from_utf8(bytes).map_err(|e| ConfigError::Parse {
            path: path.display().to_string(),
            message: format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        })?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// Checks value ranges that the types alone cannot express.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.robot.validate()?;
        self.pipeline.validate()?;
        self.motor.validate()?;
        self.icp.validate()?;
        self.scanner.validate().map_err(|m| {
            // The driver's messages start with the dotted key they are about.
            let (key, rest) = m.split_once(' ').unwrap_or(("scanner", m.as_str()));
            ConfigError::from(invalid(key, rest))
        })?;
        self.map.validate()?;
        self.daemon.validate()?;
        self.live.validate()?;
        self.record.validate()?;
        // The algorithm tables check themselves when their stage is built;
        // checked here too, so that `run --check-config` refuses what `run`,
        // `sim` and `coverage` would refuse.
        self.decomp.validate().map_err(keyed)?;
        self.control.validate().map_err(keyed)?;
        self.plan.validate().map_err(keyed)?;
        crate::plan::lane_geometry(&self.plan, &self.robot).map_err(keyed)?;
        Ok(())
    }
}

/// An [`ConfigError::Invalid`] from an error whose message starts with the
/// dotted key it is about (`plan.lane_overlap: ...`).
fn keyed(e: impl std::fmt::Display) -> ConfigError {
    let m = e.to_string();
    match m.split_once(": ") {
        Some((key, rest)) if !key.contains(' ') => invalid(key, rest).into(),
        _ => invalid("config", &m).into(),
    }
}

impl From<ParamError> for ConfigError {
    fn from(e: ParamError) -> Self {
        ConfigError::Invalid {
            key: e.key,
            message: e.message,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped configuration, `hw/robot.toml`.
    fn shipped() -> Config {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../hw/robot.toml");
        Config::load(&path).expect("hw/robot.toml parses")
    }

    #[test]
    fn shipped_scanner_table_matches_the_defaults() {
        let cfg = shipped();
        assert_eq!(cfg.scanner, crate::urg::UrgParams::default());
        let e = Config::from_toml("[scanner]\nclusterr = 2\n", "t").unwrap_err();
        assert!(e.to_string().contains("clusterr"), "{e}");
    }

    #[test]
    fn shipped_motor_table_is_the_default() {
        let cfg = shipped();
        assert_eq!(cfg.motor, crate::motor::MotorParams::default());
    }

    #[test]
    fn shipped_icp_table_is_the_default_and_valid() {
        let cfg = shipped();
        // The robot tracks against a room-scale keyframe window (a larger
        // local map than the corridor-log default), chosen from a keyframe
        // store; the local search is off (a lost robot is searched for
        // over the whole map with its wheels held instead: `daemon.lost_after`);
        // everything else is the default.
        assert_eq!(
            cfg.icp,
            crate::icp::IcpParams {
                keyframe_distance: 0.5,
                keyframe_window: 40,
                keyframe_store: 2000,
                search: crate::icp::SearchParams {
                    window: 0.0,
                    window_angle: 0.0,
                    ..crate::icp::SearchParams::default()
                },
                ..crate::icp::IcpParams::default()
            }
        );
        cfg.icp.validate().unwrap();
    }

    #[test]
    fn metric_and_prior_parse_from_toml() {
        let cfg = Config::from_toml(
            "[icp]\nmetric = \"point_to_point\"\nprior = \"constant_velocity\"\n",
            "t",
        )
        .unwrap();
        assert_eq!(cfg.icp.metric, crate::icp::Metric::PointToPoint);
        assert_eq!(cfg.icp.prior, crate::icp::Prior::ConstantVelocity);
        assert!(Config::from_toml("[icp]\nmetric = \"plane\"\n", "t").is_err());
    }

    #[test]
    fn shipped_map_table_equals_defaults() {
        let cfg = shipped();
        assert_eq!(cfg.map, crate::map::MapParams::default());
    }

    #[test]
    fn config_file_checks_the_map_table() {
        let e = Config::from_toml("[map]\nmerge_distance = -0.1\n", "t.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("map.merge_distance"), "{e}");
    }

    #[test]
    fn shipped_plan_and_control_tables_are_the_defaults() {
        let cfg = shipped();
        assert_eq!(cfg.plan, crate::plan::PlanParams::default());
        assert_eq!(cfg.control, crate::control::ControlParams::default());
    }

    #[test]
    fn unknown_key_is_named() {
        let e = Config::from_toml("[robot]\nradiuss = 0.2\n", "t.toml").unwrap_err();
        assert!(e.to_string().contains("radiuss"), "{e}");
    }

    #[test]
    fn the_map_kind_is_grid_or_paper() {
        let cfg = Config::from_toml("[map]\nkind = \"paper\"\n", "t.toml").unwrap();
        assert_eq!(cfg.map.kind, crate::map::MapKind::Paper);
        let e = Config::from_toml("[map]\nkind = \"points\"\n", "t.toml").unwrap_err();
        let e = e.to_string();
        assert!(
            e.contains("points") && e.contains("`grid` or `paper`"),
            "{e}"
        );
    }

    #[test]
    fn bad_value_is_named() {
        let e = Config::from_toml("[robot]\nradius = -1.0\n", "t.toml").unwrap_err();
        assert!(e.to_string().contains("robot.radius"), "{e}");
    }

    #[test]
    fn a_scanner_mount_is_checked_and_gives_the_scanner_pose() {
        for bad in [
            "scanner_yaw = 4.0",
            "scanner_yaw = nan",
            "scanner_offset_y = inf",
        ] {
            let e = Config::from_toml(&format!("[robot]\n{bad}\n"), "t.toml").unwrap_err();
            let key = bad.split(' ').next().unwrap();
            assert!(
                e.to_string().contains(&format!("robot.{key}")),
                "{bad}: {e}"
            );
        }
        let cfg = Config::from_toml(
            "[robot]\nscanner_offset_x = 0.1\nscanner_offset_y = -0.05\nscanner_yaw = 1.5\n",
            "t.toml",
        )
        .unwrap();
        let m = cfg.robot.scanner_mount();
        assert!((m.translation.x - 0.1).abs() < 1e-12 && (m.translation.y + 0.05).abs() < 1e-12);
        assert!((m.rotation.angle() - 1.5).abs() < 1e-12);
    }

    #[test]
    fn shipped_default_config_parses() {
        let cfg = shipped();
        assert_eq!(cfg.robot, RobotParams::default());
    }
}
