//! The scanner stage: the URG driver's scans, stamped and paired with odometry.

use std::sync::Arc;
use std::time::Duration;

use super::gone;
use crate::daemon::messages::ScanMsg;
use crate::daemon::shared::Shared;
use crate::pipeline::clock::Stamp;
use crate::pipeline::{Poll, Stage, StageCtx, StageFault, Tx};
use crate::urg::UrgDriver;

/// The scanner stage: forwards the URG driver's scans (the driver runs its
/// own reader thread and channel), stamped on arrival and paired with the
/// odometry at the scan's time.
pub struct ScannerStage {
    /// The driver; taken on stop to send QT and join its thread.
    pub driver: Option<UrgDriver>,
    /// Scans out (newest wins).
    pub tx: Tx<ScanMsg>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// The scanner is mounted upside down: its scans are mirrored.
    pub upside_down: bool,
    /// A copy of every scan for the recorder and the live view (oldest
    /// kept when full: a stalled reader loses copies, never a scan).
    pub tap: Option<Tx<crate::daemon::TapScan>>,
}

impl Stage for ScannerStage {
    type Work = crate::urg::UrgScan;

    fn wait(&mut self, timeout: Duration) -> Poll<Self::Work> {
        let Some(d) = &self.driver else {
            return Poll::Done;
        };
        match d.scans().recv_timeout(timeout) {
            Ok(s) => Poll::Work(s),
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => Poll::Idle,
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => Poll::Done,
        }
    }

    fn process(&mut self, mut work: Self::Work, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        let t0 = Stamp::now();
        if self.upside_down {
            work.scan.mirror();
        }
        // The velocity while the beams were swept: over the window ending
        // at the last beam, or at the newest odometry reading.
        let scan = &work.scan;
        let last = scan.beam_time(scan.beams.len().saturating_sub(1));
        let sweep_end = scan.stamp + scan.first_beam_time.max(last);
        let odom = self.shared.odom.for_scan(scan.stamp, sweep_end);
        let sensor = self
            .tap
            .as_ref()
            .map(|_| crate::daemon::SensorScan::of(&work));
        let msg = ScanMsg {
            t0,
            stamp: work.scan.stamp,
            odom: odom.pose,
            odom_current: odom.current,
            interval: work.interval,
            motion: odom.motion,
            scan: work.scan,
        };
        if let (Some(tap), Some(sensor)) = (&self.tap, sensor) {
            let _ = tap.send(crate::daemon::TapScan {
                msg: msg.clone(),
                sensor,
            });
        }
        ctx.hand_off();
        self.tx
            .send(msg)
            .map_or_else(|_| gone(&self.shared, "localise"), |_| Ok(()))
    }

    fn on_stop(&mut self) {
        if let Some(d) = self.driver.take() {
            d.shutdown();
        }
    }
}
