//! The online map: sparse point map with the paper's merging rule, line
//! features, segment correction, and the explored-area grid.

/// Mapping settings.
/// Loaded from the `[map]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MapParams {}
