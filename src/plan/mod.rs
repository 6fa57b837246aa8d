//! Coverage planning: lanes inside a cell, the order of cells, and transit
//! paths between them.

/// Coverage planner settings.
/// Loaded from the `[plan]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlanParams {}
