//! Path following for a differential drive within the robot's speed limits.

/// Path follower settings.
/// Loaded from the `[control]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlParams {}
