//! The daemon's configuration: one TOML file (`hw/robot.toml` is the documented
//! default), one table per stage. Unknown keys and bad values are errors that
//! name the key.

use std::path::Path;

use serde::{Deserialize, Serialize};

/// Physical robot: footprint, tool and drive limits. Shared by planner,
/// controller, motor link and simulator.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotParams {
    /// Radius of the robot's circular footprint (m); walls are inflated by it.
    pub radius: f64,
    /// Width of the cleaning tool (m); lanes are this far apart at most.
    pub tool_width: f64,
    /// Distance between the wheels' contact points (m).
    pub wheel_base: f64,
    /// Wheel radius (m).
    pub wheel_radius: f64,
    /// Top linear speed (m/s); the paper's robot: 0.226.
    pub max_speed: f64,
    /// Top turn rate (rad/s); the paper's robot: 0.78.
    pub max_turn_rate: f64,
    /// Scanner mounting offset forward of the wheel axle centre (m).
    pub scanner_offset_x: f64,
    /// Scanner mounting offset to the left of the wheel axle centre (m).
    pub scanner_offset_y: f64,
    /// Direction (rad, counter-clockwise from the robot's front) of the
    /// scanner's own front (its 0° beam).
    pub scanner_yaw: f64,
    /// The scanner is mounted upside down: it sweeps clockwise as seen from
    /// above, so its beam angles are mirrored.
    pub scanner_upside_down: bool,
}

impl RobotParams {
    /// The scanner's pose in the robot frame (offsets and yaw); an
    /// upside-down mount mirrors the beams besides (see
    /// [`crate::scan::LaserScan::mirror`]).
    pub fn scanner_mount(&self) -> crate::geom::Pose {
        crate::geom::pose(
            self.scanner_offset_x,
            self.scanner_offset_y,
            self.scanner_yaw,
        )
    }
}

impl Default for RobotParams {
    fn default() -> Self {
        Self {
            radius: 0.17,
            tool_width: 0.30,
            wheel_base: 0.235,
            wheel_radius: 0.036,
            max_speed: 0.226,
            max_turn_rate: 0.78,
            scanner_offset_x: 0.0,
            scanner_offset_y: 0.0,
            scanner_yaw: 0.0,
            scanner_upside_down: false,
        }
    }
}

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
        let r = &self.robot;
        positive("robot.radius", r.radius)?;
        positive("robot.tool_width", r.tool_width)?;
        positive("robot.wheel_base", r.wheel_base)?;
        positive("robot.wheel_radius", r.wheel_radius)?;
        positive("robot.max_speed", r.max_speed)?;
        positive("robot.max_turn_rate", r.max_turn_rate)?;
        for (key, v) in [
            ("robot.scanner_offset_x", r.scanner_offset_x),
            ("robot.scanner_offset_y", r.scanner_offset_y),
        ] {
            if !v.is_finite() {
                return Err(invalid(key, "must be a finite number"));
            }
        }
        let y = r.scanner_yaw;
        if !(y.is_finite() && (-std::f64::consts::PI..=std::f64::consts::PI).contains(&y)) {
            return Err(invalid(
                "robot.scanner_yaw",
                &format!("must be an angle in radians within -pi..=pi, got {y:?}"),
            ));
        }
        self.pipeline.validate()?;
        self.motor.validate()?;
        self.icp.validate()?;
        self.scanner.validate().map_err(|m| {
            // The driver's messages start with the dotted key they are about.
            let (key, rest) = m.split_once(' ').unwrap_or(("scanner", m.as_str()));
            invalid(key, rest)
        })?;
        self.map.validate()?;
        self.daemon.validate()?;
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
        Some((key, rest)) if !key.contains(' ') => invalid(key, rest),
        _ => invalid("config", &m),
    }
}

/// An [`ConfigError::Invalid`] for `key`.
pub fn invalid(key: &str, message: &str) -> ConfigError {
    ConfigError::Invalid {
        key: key.to_string(),
        message: message.to_string(),
    }
}

/// Checks that `v` is finite and > 0.
pub fn positive(key: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            key,
            &format!("must be a finite number > 0, got {v:?}"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_key_is_named() {
        let e = Config::from_toml("[robot]\nradiuss = 0.2\n", "t.toml").unwrap_err();
        assert!(e.to_string().contains("radiuss"), "{e}");
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
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml");
        let cfg = Config::load(Path::new(path)).expect("hw/robot.toml parses");
        assert_eq!(cfg.robot, RobotParams::default());
    }
}
