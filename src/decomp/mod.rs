//! Adaptive (online) boustrophedon cell decomposition with virtual edges and
//! cell inheritance.
pub mod cell;

pub use cell::{Adjacency, Cell, CellId, CellStatus, Decomposition};

/// Cell decomposition settings.
/// Loaded from the `[decomp]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DecompParams {}
