//! Intensity-ICP scan registration (pure, deterministic, allocation-free in
//! steady state).

/// Scan matcher settings.
/// Loaded from the `[icp]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct IcpParams {}
