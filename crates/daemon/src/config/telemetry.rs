//! The `[live]` and `[record]` tables: what `sweepline run` serves to a
//! live viewer and keeps on disk (the `sweepline-live` crate does both;
//! these are its settings as plain data).

use serde::{Deserialize, Serialize};

use crate::param_check::{invalid, ParamError};

/// The `[live]` table.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct LiveParams {
    /// `host:port` the live view listens on; empty: no live view.
    pub bind: String,
}

/// The `[record]` table.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordParams {
    /// Record the run (into `recordings/` of the state folder).
    pub enabled: bool,
    /// The topics recorded; empty: all.
    pub channels: Vec<String>,
    /// Size of one file before the next is started (MiB).
    pub file_mib: f64,
    /// Size of all recordings kept; the oldest files go beyond it (MiB).
    pub max_mib: f64,
}

impl Default for RecordParams {
    fn default() -> Self {
        Self {
            enabled: true,
            channels: Vec::new(),
            file_mib: 64.0,
            max_mib: 1024.0,
        }
    }
}

impl LiveParams {
    /// Checks the address.
    pub fn validate(&self) -> Result<(), ParamError> {
        if self.bind.is_empty()
            || self
                .bind
                .rsplit_once(':')
                .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok())
        {
            Ok(())
        } else {
            Err(invalid(
                "live.bind",
                &format!(
                    "must be HOST:PORT (e.g. 127.0.0.1:8765) or empty, got {:?}",
                    self.bind
                ),
            ))
        }
    }
}

impl RecordParams {
    /// Checks the sizes and topics.
    pub fn validate(&self) -> Result<(), ParamError> {
        let f = self.file_mib;
        if !(f.is_finite() && (1.0..=4096.0).contains(&f)) {
            return Err(invalid(
                "record.file_mib",
                &format!("must be a number of MiB in 1..=4096, got {f:?}"),
            ));
        }
        let m = self.max_mib;
        if !(m.is_finite() && m >= f && m <= 1024.0 * 1024.0) {
            return Err(invalid(
                "record.max_mib",
                &format!(
                    "must be at least record.file_mib ({f}) and at most 1048576 MiB, got {m:?}"
                ),
            ));
        }
        if let Some(c) = self.channels.iter().find(|c| !c.starts_with('/')) {
            return Err(invalid(
                "record.channels",
                &format!("topics start with `/` (e.g. \"/scan\"), got {c:?}"),
            ));
        }
        Ok(())
    }
}
