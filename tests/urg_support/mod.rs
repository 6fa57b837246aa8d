//! Shared rig for the URG integration tests: an emulated URG-04LX on a real
//! pty (in-process thread), the real driver opening its symlink exactly as a
//! device, and the bookkeeping that proves no good scan was lost or
//! duplicated.

#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use sweepline::serial::DeviceConnector;
use sweepline::sim::urg_emu::{
    EmuLog, Emulator, EmulatorConfig, Faults, Model, RectRoom, SentScan,
};
use sweepline::urg::{ScaledClock, UrgDriver, UrgParams, UrgScan};

/// How much faster than real time the tests run the sensor.
pub const RATE: f64 = 4.0;

/// A running emulator + driver pair.
pub struct Rig {
    pub emu: Emulator,
    pub driver: Option<UrgDriver>,
    pub clock: Arc<ScaledClock>,
    pub link: PathBuf,
    pub dir: PathBuf,
}

/// A fresh folder for one test's symlink.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sweepline-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Driver settings for tests: quick back-off, generous timeouts.
pub fn test_params() -> UrgParams {
    UrgParams {
        reconnect_min: 0.05,
        reconnect_max: 0.4,
        queue: 256,
        ..UrgParams::default()
    }
}

/// Starts the emulator with `faults` (and SCIP 1.1 boot if asked), then the
/// driver on its symlink.
pub fn rig(name: &str, faults: &str, scip1: bool, params: UrgParams) -> Rig {
    let cfg = EmulatorConfig {
        model: Model::Urg04lx,
        scip1_boot: scip1,
        faults: faults.parse::<Faults>().unwrap(),
        seed: 42,
        ..EmulatorConfig::default()
    };
    rig_cfg(name, cfg, RATE, params)
}

/// Starts the emulator as `cfg` says (its link is set here) on a clock
/// running `rate` times real time, then the driver on its symlink.
pub fn rig_cfg(name: &str, mut cfg: EmulatorConfig, rate: f64, params: UrgParams) -> Rig {
    let dir = temp_dir(name);
    let link = dir.join("urg");
    let clock = Arc::new(ScaledClock::new(rate));
    cfg.link = Some(link.clone());
    let emu = Emulator::spawn(cfg, Box::new(RectRoom::bench(3)), clock.clone()).unwrap();
    let driver =
        UrgDriver::start(Box::new(DeviceConnector::new(&link)), params, clock.clone()).unwrap();
    Rig {
        emu,
        driver: Some(driver),
        clock,
        link,
        dir,
    }
}

impl Rig {
    /// The driver.
    pub fn driver(&self) -> &UrgDriver {
        self.driver.as_ref().unwrap()
    }

    /// Collects scans until `n` arrived or `secs` of real time passed.
    pub fn collect(&self, n: usize, secs: f64) -> Vec<UrgScan> {
        let end = Instant::now() + Duration::from_secs_f64(secs);
        let mut v = Vec::new();
        while v.len() < n {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            if let Ok(s) = self.driver().scans().recv_timeout(left) {
                v.push(s);
            }
        }
        v
    }

    /// Stops the driver (QT) and returns the emulator's log.
    pub fn finish(mut self) -> EmuLog {
        if let Some(d) = self.driver.take() {
            d.shutdown();
        }
        std::thread::sleep(Duration::from_millis(50));
        let log = self.emu.log();
        let _ = std::fs::remove_dir_all(&self.dir);
        log
    }
}

/// Checks that every delivered scan is exactly one the emulator sent
/// (in order, no duplicates), and that every sent scan up to the last
/// delivered one was delivered unless the emulator corrupted it or replaced
/// it by an error status. Returns (delivered, corrupted-in-window).
pub fn check_no_loss(log: &EmuLog, got: &[UrgScan]) -> (usize, usize) {
    assert!(!got.is_empty(), "no scans delivered");
    let sent: Vec<SentScan> = log.sent.iter().copied().collect();
    let mut i = 0;
    let mut corrupted = 0;
    for (k, g) in got.iter().enumerate() {
        // Skip sent scans the driver rightly did not deliver.
        loop {
            assert!(
                i < sent.len(),
                "delivered scan #{k} (stamp {}) was never sent",
                g.raw_stamp
            );
            let s = sent[i];
            if s.stamp == g.raw_stamp && s.fault.is_none_or(|f| f.delivered()) {
                break;
            }
            assert!(
                s.fault.is_some_and(|f| !f.delivered()),
                "good scan {} (stamp {}, boot {}) was lost; next delivered stamp {}",
                s.index,
                s.stamp,
                s.boot,
                g.raw_stamp
            );
            if s.fault.is_some_and(|f| f.corrupts()) {
                corrupted += 1;
            }
            i += 1;
        }
        i += 1;
    }
    (got.len(), corrupted)
}

/// Timestamp gaps the emulator itself made (scans it never sent), within
/// one boot, over the scans up to index `upto`.
pub fn sent_gaps(log: &EmuLog, period_ms: u32, upto: u64) -> u64 {
    let mut gaps = 0;
    let v: Vec<_> = log.sent.iter().filter(|s| s.index <= upto).collect();
    for w in v.windows(2) {
        if w[0].boot == w[1].boot {
            let d = w[1].true_ms - w[0].true_ms;
            let periods = (d as f64 / f64::from(period_ms)).round() as u64;
            gaps += periods.saturating_sub(1);
        }
    }
    gaps
}
