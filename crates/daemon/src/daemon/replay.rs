//! A recording replayed through the daemon's own localise and map stages:
//! the scans exactly as the stages got them on the robot (or in the
//! simulator), one after the other, with no clock and no wheels. What the
//! running daemon would have made of them, less the timing: no scan is
//! dropped for being late, and nothing drives.

use std::sync::Arc;

use super::messages::{MapMsg, PoseFix, ScanMsg};
use super::stages::{LocaliseStage, MapStage};
use super::{localise_stage, DaemonError, LocaliseEdges, MapFrame, Shared, MAP_MAX_RANGE};
use crate::config::Config;
use crate::geom::Pose;
use crate::pipeline::metrics::LatencyHistogram;
use crate::pipeline::{latest, queue, Overflow, Recv, Rx, Stage, StageCtx};

/// Registered scans the map stage may owe at once (one scan's worth).
const MAP_DEPTH: usize = 8;

/// The localise and map stages, driven by hand.
pub struct Replayer {
    localise: LocaliseStage,
    map: MapStage,
    fixes: Rx<PoseFix>,
    to_map: Rx<MapMsg>,
    _snapshots: Rx<super::messages::MapSnapshot>,
    _scans: crate::pipeline::Tx<ScanMsg>,
    latency: LatencyHistogram,
    shared: Arc<Shared>,
}

impl Replayer {
    /// The stages as `cfg` sets them up, for a robot told it starts at
    /// `start`, mapping into `frame`.
    pub fn new(cfg: &Config, start: Pose, frame: MapFrame) -> Result<Replayer, DaemonError> {
        let shared = Arc::new(Shared::default());
        shared.with_status(|s| s.pose = start);
        let (scans_tx, scans_rx) = latest("scans");
        let (fix_tx, fixes) = latest("pose_fixes");
        let (map_tx, to_map) = queue("registered_scans", MAP_DEPTH, Overflow::RejectNewest);
        let (snap_tx, snapshots) = latest("map_snapshots");
        let edges = LocaliseEdges {
            rx: scans_rx,
            to_control: fix_tx,
            to_map: map_tx,
            tap: None,
        };
        let localise = localise_stage(cfg, start, edges, shared.clone(), false)?;
        // The map stage is handed its messages here, never waits on an edge.
        let (_, idle) = latest("unused");
        let map = MapStage::new(
            frame.grid(),
            idle,
            snap_tx,
            shared.clone(),
            MAP_MAX_RANGE,
            cfg.daemon.contact.same_contact,
        )
        .with_map_kind(&cfg.map, &start)
        .map_err(|e| DaemonError::Config(e.to_string()))?;
        Ok(Replayer {
            localise,
            map,
            fixes,
            to_map,
            _snapshots: snapshots,
            _scans: scans_tx,
            latency: LatencyHistogram::new(),
            shared,
        })
    }

    /// One scan through the localise stage and what it registered into
    /// the map; the pose the localise stage handed on (none: the stage
    /// stopped the run, as the daemon would have).
    pub fn step(&mut self, msg: ScanMsg) -> Option<PoseFix> {
        let mut ctx = StageCtx::offline(&mut self.latency);
        if let Err(e) = self.localise.process(msg, &mut ctx) {
            log::warn!("replay: the localise stage stopped: {e:?}");
            return None;
        }
        while let Recv::Msg(m) = self.to_map.try_recv() {
            let mut ctx = StageCtx::offline(&mut self.latency);
            if let Err(e) = self.map.process(m, &mut ctx) {
                log::warn!("replay: the map stage stopped: {e:?}");
            }
        }
        match self.fixes.try_recv() {
            Recv::Msg(f) => Some(f),
            _ => None,
        }
    }

    /// The state the stages share (status, counters).
    pub fn shared(&self) -> &Arc<Shared> {
        &self.shared
    }

    /// The map as merged so far.
    pub fn grid(&self) -> &crate::grid::Grid {
        &self.map.grid
    }
}
