//! The daemon's own settings: the `[daemon]` table (how the control loop
//! gives a path up, where bumper contacts are marked).

use serde::{Deserialize, Serialize};

use super::contact::ContactParams;
use super::stuck::STUCK_AFTER;
use crate::config::{invalid, ConfigError};

/// Longest `daemon.stuck_after` accepted (clock s).
pub const MAX_STUCK_AFTER: f64 = 3600.0;

/// The `[daemon]` table.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DaemonParams {
    /// Clock seconds without headway after which the control stage gives a
    /// path up (see [`super::stuck::ProgressWatch`]).
    pub stuck_after: f64,
    /// Bumper contact marks.
    pub contact: ContactParams,
}

impl Default for DaemonParams {
    fn default() -> Self {
        Self {
            stuck_after: STUCK_AFTER,
            contact: ContactParams::default(),
        }
    }
}

impl DaemonParams {
    /// Checks every value's range; the error names the dotted key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let s = self.stuck_after;
        if !(s.is_finite() && (1.0..=MAX_STUCK_AFTER).contains(&s)) {
            return Err(invalid(
                "daemon.stuck_after",
                &format!("must be a finite number of seconds in 1..={MAX_STUCK_AFTER}, got {s:?}"),
            ));
        }
        self.contact.validate()
    }
}
