//! The map stage: registered scans and bumper contacts merged into the evidence
//! grid.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Point2;

use super::gone;
use crate::daemon::contact::ContactMark;
use crate::daemon::messages::{MapMsg, MapSnapshot};
use crate::daemon::shared::Shared;
use crate::daemon::snapshot::MapStageSnapshot;
use crate::geom::Pose;
use crate::grid::Grid;
use crate::map::{MapError, MapKind, MapParams, PaperGrid};
use crate::pipeline::checkpoint::{ContactArc, ContactArcs};
use crate::pipeline::{Poll, Recv, Rx, Stage, StageCtx, StageFault, Tx};

/// The map stage: merges registered scans into the explored-area grid and
/// publishes immutable `Arc` snapshots for the planner.
pub struct MapStage {
    /// The map.
    pub grid: Grid,
    /// Registered scans and bumper contacts in.
    pub rx: Rx<MapMsg>,
    /// Snapshots out (newest wins).
    pub tx: Tx<MapSnapshot>,
    /// Shared state.
    pub shared: Arc<Shared>,
    /// Longest range merged (m); farther echoes are too uncertain.
    pub max_range: f64,
    /// Bumper contacts: obstacles the scanner cannot see, kept occupied
    /// even when later rays pass over them.
    pub contacts: Vec<ContactMark>,
    /// Contacts that were new (not a repeat of a marked one).
    pub(crate) new_contacts: u64,
    /// A contact this close to a marked one is a repeat of it (m).
    pub same_contact: f64,
    /// Requests to take a mark out handled (see [`MapSnapshot::retired`]).
    pub(crate) retired: u64,
    /// The grid as last handed to the planner (none before the first
    /// scan of a fresh run), for the snapshot.
    published: Option<Arc<Grid>>,
    /// [`Self::contacts`] as the checkpoint stores them, rebuilt when they
    /// change (none before the first), for the snapshot.
    arcs: Option<Arc<ContactArcs>>,
    /// `[map] kind = "paper"`: the paper's map, which [`Self::grid`] is
    /// rendered from after every scan (see [`PaperGrid`]).
    paper: Option<PaperGrid>,
}

/// The checkpoint section of contact `marks`.
pub fn contact_arcs(marks: &[ContactMark]) -> ContactArcs {
    ContactArcs {
        arcs: marks.iter().map(ContactArc::from).collect(),
    }
}

impl MapStage {
    /// A map stage starting on `grid` without contact marks (see
    /// [`Self::restore`] for a resumed run).
    pub fn new(
        grid: Grid,
        rx: Rx<MapMsg>,
        tx: Tx<MapSnapshot>,
        shared: Arc<Shared>,
        max_range: f64,
        same_contact: f64,
    ) -> Self {
        Self {
            grid,
            rx,
            tx,
            shared,
            max_range,
            contacts: Vec::new(),
            new_contacts: 0,
            same_contact,
            retired: 0,
            published: None,
            arcs: None,
            paper: None,
        }
    }

    /// Plans on the map `params.kind` names: for `paper`, registered scans
    /// go into the paper's map, starting at `start` over this stage's grid.
    pub fn with_map_kind(mut self, params: &MapParams, start: &Pose) -> Result<Self, MapError> {
        if params.kind == MapKind::Paper {
            self.paper = Some(PaperGrid::new(params.clone(), *start, self.grid.clone())?);
        }
        Ok(self)
    }

    /// What a restart needs of this stage: the grid as last handed to the
    /// planner and the contact marks.
    pub fn snapshot(&self) -> MapStageSnapshot {
        MapStageSnapshot {
            grid: self.published.clone(),
            contacts: self.arcs.clone(),
        }
    }

    /// Hands [`Self::snapshot`] to the checkpoint and to the stages that
    /// read the map or the marks (through the live status).
    fn publish(&self) {
        let snapshot = self.snapshot();
        self.shared.with_status(|s| s.map = snapshot);
    }

    /// Picks up a resumed run: the restored grid, with the restored
    /// contact marks marked in it at once (the checkpointed grid may have
    /// lost them to later rays).
    pub fn restore(&mut self, snapshot: MapStageSnapshot) {
        if let Some(g) = &snapshot.grid {
            self.grid = Grid::clone(g);
        }
        self.contacts = snapshot
            .contacts
            .as_deref()
            .map(|c| c.arcs.iter().map(|&a| a.into()).collect())
            .unwrap_or_default();
        if !self.contacts.is_empty() {
            log::info!(
                "resume: {} bumper contact mark(s) restored",
                self.contacts.len()
            );
        }
        self.published = snapshot.grid;
        self.arcs = snapshot.contacts;
        self.restart_paper_map();
        self.publish();
        self.mark_contacts();
    }

    /// A resumed run's paper map starts over on the restored grid: the
    /// checkpoint holds the grid, not the points and segments, which the
    /// next scans bring back.
    fn restart_paper_map(&mut self) {
        let Some(pg) = &self.paper else {
            return;
        };
        let (params, pose) = (pg.map().params().clone(), pg.map().pose());
        match PaperGrid::new(params, pose, self.grid.clone()) {
            Ok(p) => self.paper = Some(p),
            Err(e) => log::warn!("resume: the paper map keeps its empty grid: {e}"),
        }
    }

    /// The contact marks changed: the snapshot gets the new list.
    fn contacts_changed(&mut self) {
        self.arcs = Some(Arc::new(contact_arcs(&self.contacts)));
        self.publish();
    }

    /// Merges a registered scan or a bumper contact into the grid; the
    /// contact marks are occupied again afterwards, whatever the rays
    /// crossed.
    pub fn merge(&mut self, msg: MapMsg) {
        match msg {
            MapMsg::Scan { pose: p, scan } => match &mut self.paper {
                Some(pg) => match pg.merge(&scan, &p) {
                    Ok(_) => pg.render_into(&mut self.grid),
                    Err(e) => log::warn!("map: scan not merged into the paper map: {e}"),
                },
                None => {
                    let o: Point2<f64> = p.translation.vector.into();
                    for b in scan.beams.iter() {
                        if !(b.valid && b.range.is_finite() && b.angle.is_finite()) {
                            continue;
                        }
                        let r = b.range.min(self.max_range);
                        let (s, c) = b.angle.sin_cos();
                        let end = p * Point2::new(r * c, r * s);
                        self.grid.integrate_ray(&o, &end, r >= b.range);
                    }
                }
            },
            MapMsg::Contact(mark) => {
                if !self
                    .contacts
                    .iter()
                    .any(|c| c.same_as(&mark, self.same_contact))
                {
                    self.contacts.push(mark);
                    self.new_contacts += 1;
                    self.contacts_changed();
                }
            }
            MapMsg::Retire(at) => {
                self.retired += 1;
                let (gone, kept): (Vec<ContactMark>, Vec<ContactMark>) = self
                    .contacts
                    .iter()
                    .partition(|c| (c.at - at).norm() <= self.same_contact);
                if !gone.is_empty() {
                    self.contacts = kept;
                    self.shared.marks_taken_out.fetch_add(1, Ordering::Relaxed);
                    // Unknown, not free: a mark beside a wall must not open
                    // a hole in it; the next scan sees what is there.
                    for c in &gone {
                        set_arc(&mut self.grid, c, crate::grid::CellState::Unknown);
                    }
                    self.contacts_changed();
                    log::info!(
                        "map: contact mark at ({:.2}, {:.2}) m taken out; {} mark(s) left",
                        at.x,
                        at.y,
                        self.contacts.len()
                    );
                }
            }
        }
        self.mark_contacts();
    }

    fn mark_contacts(&mut self) {
        for c in &self.contacts {
            set_arc(&mut self.grid, c, crate::grid::CellState::Occupied);
        }
    }
}

/// Sets every cell of `grid` the arc of `mark` lies in to `state`.
fn set_arc(grid: &mut Grid, mark: &ContactMark, state: crate::grid::CellState) {
    for cell in mark.cells(grid) {
        grid.set_state(cell, state);
    }
}

impl Stage for MapStage {
    type Work = MapMsg;

    fn wait(&mut self, timeout: Duration) -> Poll<MapMsg> {
        match self.rx.recv_timeout(timeout) {
            Recv::Msg(m) => Poll::Work(m),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }

    fn process(&mut self, msg: MapMsg, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        self.merge(msg);
        let snap = Arc::new(self.grid.clone());
        self.published = Some(snap.clone());
        self.publish();
        let msg = MapSnapshot {
            grid: snap,
            contacts: self.new_contacts,
            retired: self.retired,
        };
        ctx.hand_off();
        self.tx
            .send(msg)
            .map_or_else(|_| gone(&self.shared, "plan"), |_| Ok(()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::daemon::snapshot::MapStageSnapshot;
    use crate::geom::pose;
    use crate::grid::CellState;
    use crate::pipeline::{latest, queue, Overflow};
    use crate::scan::LaserScan;

    /// A 1° scan from `(x, y)`, heading 0, of the room `[0, 4] × [0, 3]`.
    fn room_scan(x: f64, y: f64) -> LaserScan {
        let room = crate::icp::synth::room(4.0, 3.0, 1.0);
        crate::icp::synth::laser_scan(&room, &Point2::new(x, y), 360)
    }

    fn stage(kind: MapKind) -> MapStage {
        let (_tx, rx) = queue("registered_scans", 8, Overflow::DropOldest);
        let (snap_tx, _snap_rx) = latest("map_snapshots");
        let grid = Grid::new(Point2::new(-0.475, -0.475), 0.05, 100, 80);
        let params = MapParams {
            kind,
            ..MapParams::default()
        };
        MapStage::new(grid, rx, snap_tx, Arc::new(Shared::default()), 5.6, 0.1)
            .with_map_kind(&params, &pose(2.0, 1.5, 0.0))
            .unwrap()
    }

    #[test]
    fn the_paper_kind_plans_on_the_paper_map_and_keeps_a_resumed_grid() {
        let mut s = stage(MapKind::Paper);
        assert!(s.paper.is_some());
        // A resumed run: the checkpointed grid holds a wall the new run
        // has not seen yet (outside the room the scans see).
        let mut restored = s.grid.clone();
        let behind = restored.cell_of(&Point2::new(4.3, 3.3)).unwrap();
        restored.set_state(behind, CellState::Occupied);
        s.restore(MapStageSnapshot {
            grid: Some(Arc::new(restored)),
            contacts: None,
        });
        for k in 0..6 {
            let x = 1.8 + 0.08 * f64::from(k);
            s.merge(MapMsg::Scan {
                pose: pose(x, 1.5, 0.0),
                scan: room_scan(x, 1.5),
            });
        }
        let pg = s.paper.as_ref().unwrap();
        assert_eq!(pg.tally().scans, 6);
        assert!(pg.map().snapshot().walls.len() >= 4);
        assert_eq!(
            s.grid.state(behind),
            CellState::Occupied,
            "the resumed grid's wall"
        );
        let at = |x: f64, y: f64| s.grid.state(s.grid.cell_of(&Point2::new(x, y)).unwrap());
        assert_eq!(at(2.0, 1.5), CellState::Free);
        assert_eq!(at(4.01, 1.5), CellState::Occupied);
        // A pose the map refuses is logged, not merged, and nothing breaks.
        s.merge(MapMsg::Scan {
            pose: pose(f64::NAN, 1.5, 0.0),
            scan: room_scan(2.0, 1.5),
        });
        assert_eq!(s.paper.as_ref().unwrap().tally().scans, 6);
    }

    #[test]
    fn the_grid_kind_keeps_no_paper_map() {
        let mut s = stage(MapKind::Grid);
        assert!(s.paper.is_none());
        s.merge(MapMsg::Scan {
            pose: pose(2.0, 1.5, 0.0),
            scan: room_scan(2.0, 1.5),
        });
        let c = s.grid.cell_of(&Point2::new(2.0, 1.5)).unwrap();
        assert_eq!(s.grid.state(c), CellState::Free);
    }
}
