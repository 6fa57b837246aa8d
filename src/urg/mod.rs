//! The URG scanner driver: owns a port (anything `Read + Write`), runs the
//! SCIP codec, opens robustly, streams scans, syncs clocks, and recovers from
//! timeouts, garbage and a vanished device.

/// Scanner driver settings.
/// Loaded from the `[scanner]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct UrgParams {}
