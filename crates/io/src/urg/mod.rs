//! The URG scanner driver: owns a port (anything `Read + Write`), runs the
//! SCIP codec, opens robustly, streams scans, syncs clocks, and recovers from
//! timeouts, garbage and a vanished device.
//!
//! * [`session`]: one open connection, synchronous: robust open (LF, QT,
//!   SCIP 1.1 switch, TM-mode escape, stream drain), PP/VV/II once, TM clock
//!   sync, MD streaming, scan decoding and stamping.
//! * [`driver`]: the scanner stage: a reader thread running sessions with
//!   the recovery ladder (timeout → QT and restart; repeated failures → RS and
//!   re-open; device gone → wait for the path, re-open with back-off), scans
//!   into a bounded newest-wins channel.
//! * [`fill`]: a SCIP scan reply as the daemon's `LaserScan`.
//! * [`health`]: lock-free counters for the rest of the daemon.
//! * `timesync`: clock offset/drift estimation, dropped-scan detection.
//! * [`picture`]: an SVG of one scan (for `sweepline probe --svg`).

pub mod driver;
pub mod fill;
pub mod health;
pub mod picture;
pub mod session;
pub(crate) mod timesync;

pub use crate::clock::{Clock, ManualClock, MonotonicClock, ScaledClock};
pub use driver::{UrgDriver, UrgScan};
pub use fill::fill_laser_scan;
pub use health::{HealthSnapshot, UrgHealth};
pub use session::{SessionInfo, UrgError, UrgSession};

/// Scanner driver settings.
/// Loaded from the `[scanner]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct UrgParams {
    /// Device path of the scanner (a udev symlink survives replugging).
    pub port: String,
    /// Bit rate requested on open (ignored by USB-CDC and ptys).
    pub baud: u32,
    /// Adjacent steps merged into one value (1 = full resolution, max 99).
    pub cluster: u8,
    /// Scans skipped between transmitted ones (0-9): interval = (skip+1) periods.
    pub skip: u8,
    /// Experimental: URG-04LX `FF` intensity mode (or ME on models that have
    /// it); only used when the sensor's MODL supports it.
    pub intensity: bool,
    /// The raw intensity a matt light wall (painted plaster) gives at 1 m
    /// head-on: intensities are divided by it before matching, so that
    /// `icp.intensity_weight` and `icp.intensity_edge` mean the same on
    /// every model (about 2900 on a UTM-30LX, fitted to a real scan; the
    /// emulator's URG-04LX is given the same: docs/scanner.md#intensities).
    pub intensity_unit: f64,
    /// Capacity of the scan channel; when full the oldest scan is dropped.
    pub queue: usize,
    /// How long to wait for the reply to a command (s). A URG handles
    /// commands once per revolution, so a reply can take a whole scan
    /// period (100 ms on the URG-04LX): keep this well above it.
    pub reply_timeout: f64,
    /// A scan is overdue after this many expected scan intervals.
    pub scan_timeout_periods: f64,
    /// Consecutive failures after which the sensor is reset (RS) and re-opened.
    pub failures_before_reset: u32,
    /// First wait before re-opening a vanished device (s); doubles each try.
    pub reconnect_min: f64,
    /// Longest wait between re-open attempts (s).
    pub reconnect_max: f64,
    /// TM1 round trips per clock sync (0 = no TM sync; stamps use arrival time).
    pub time_sync_samples: u32,
    /// Re-sync the clock every this many seconds while streaming (0 = only on open).
    pub resync_interval: f64,
    /// Accept the known VV/II checksum quirks of some firmware (counted).
    pub lenient_info: bool,
    /// Longest single wait in a port read (s): how often a blocked read
    /// checks for shutdown (reads otherwise sleep until their deadline).
    pub poll: f64,
    /// When the sensor answers neither QT nor RS, reboot it (RB twice).
    pub reboot_last_resort: bool,
    /// How long a rebooting sensor is left alone before talking to it (s).
    pub reboot_wait: f64,
}

impl Default for UrgParams {
    fn default() -> Self {
        Self {
            port: "/dev/sweepline-urg".to_string(),
            baud: 115_200,
            cluster: 1,
            skip: 0,
            intensity: false,
            intensity_unit: 2918.0,
            queue: 4,
            reply_timeout: 0.5,
            scan_timeout_periods: 4.0,
            failures_before_reset: 3,
            reconnect_min: 0.1,
            reconnect_max: 2.0,
            time_sync_samples: 10,
            resync_interval: 0.0,
            lenient_info: true,
            poll: 0.05,
            reboot_last_resort: true,
            reboot_wait: 2.0,
        }
    }
}

impl UrgParams {
    /// Checks every value's range; the error names the key.
    pub fn validate(&self) -> Result<(), String> {
        let pos = |k: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!(
                    "scanner.{k} must be a positive number of seconds, got {v}"
                ))
            }
        };
        if self.port.is_empty() {
            return Err("scanner.port must name a device".into());
        }
        if !(1..=99).contains(&self.cluster) {
            return Err(format!(
                "scanner.cluster must be 1..=99, got {}",
                self.cluster
            ));
        }
        if self.skip > 9 {
            return Err(format!("scanner.skip must be 0..=9, got {}", self.skip));
        }
        if self.queue == 0 {
            return Err("scanner.queue must be at least 1".into());
        }
        pos("reply_timeout", self.reply_timeout)?;
        pos("reconnect_min", self.reconnect_min)?;
        pos("reconnect_max", self.reconnect_max)?;
        pos("poll", self.poll)?;
        pos("reboot_wait", self.reboot_wait)?;
        if !(self.intensity_unit.is_finite() && self.intensity_unit > 0.0) {
            return Err(format!(
                "scanner.intensity_unit must be a positive number, got {}",
                self.intensity_unit
            ));
        }
        if !(self.scan_timeout_periods.is_finite() && self.scan_timeout_periods >= 1.5) {
            return Err(format!(
                "scanner.scan_timeout_periods must be at least 1.5, got {}",
                self.scan_timeout_periods
            ));
        }
        if self.failures_before_reset == 0 {
            return Err("scanner.failures_before_reset must be at least 1".into());
        }
        if !(self.resync_interval.is_finite() && self.resync_interval >= 0.0) {
            return Err("scanner.resync_interval must be >= 0".into());
        }
        Ok(())
    }
}

/// What a two-character status code means in a scan stream or any reply.
pub(crate) fn status_meaning(code: [u8; 2]) -> &'static str {
    crate::scip::StatusCode(code).meaning(crate::scip::CommandKind::Md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_params_are_valid_and_bad_ones_name_their_key() {
        assert_eq!(UrgParams::default().validate(), Ok(()));
        let bad = [
            UrgParams {
                cluster: 0,
                ..Default::default()
            },
            UrgParams {
                skip: 10,
                ..Default::default()
            },
            UrgParams {
                queue: 0,
                ..Default::default()
            },
            UrgParams {
                reply_timeout: -1.0,
                ..Default::default()
            },
            UrgParams {
                scan_timeout_periods: 1.0,
                ..Default::default()
            },
            UrgParams {
                port: String::new(),
                ..Default::default()
            },
        ];
        for p in bad {
            let e = p.validate().unwrap_err();
            assert!(e.starts_with("scanner."), "{e}");
        }
    }
}
