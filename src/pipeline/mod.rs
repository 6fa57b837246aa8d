//! The real-time pipeline: one thread per stage, bounded channels,
//! newest-wins hand-over, budgets, metrics and the systemd watchdog.

/// Pipeline budgets and rates.
/// Loaded from the `[pipeline]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineParams {}
