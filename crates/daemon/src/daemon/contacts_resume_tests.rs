//! Bumper contact marks survive a restart (tests of the map stage, the
//! checkpoint and the resume path together): they are checkpointed in the
//! `daemon.contacts` section, the resume path loads them, and the map stage
//! marks them again so that the rays of later scans cannot clear them. The
//! places where marks were taken out (`daemon.contacts_tried`) are loaded
//! too, so a resumed run does not try them again.

use std::sync::Arc;

use crate::daemon::contact::{ContactMark, ContactParams, Known};
use crate::daemon::messages::MapMsg;
use crate::daemon::resume::{heartbeat_store, load};
use crate::daemon::stages::{contact_arcs, MapStage};
use crate::daemon::{MapStageSnapshot, Shared};
use crate::geom::pose;
use crate::grid::{CellState, Grid};
use crate::motor::{Sides, WheelSpeeds};
use crate::pipeline::checkpoint::{Checkpoint, CheckpointStore, RunProgress, TriedPlaces};
use crate::pipeline::{latest, queue, Overflow};
use crate::scan::{Beam, LaserScan};
use nalgebra::Point2;

struct TempDir(std::path::PathBuf);
impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn temp_dir(tag: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("sweepline-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TempDir(d)
}

/// A 4 m square room seen as free floor.
fn free_room() -> Grid {
    let mut g = Grid::new(Point2::new(0.0, 0.0), 0.05, 80, 80);
    for y in 0..80 {
        for x in 0..80 {
            g.set_state((x, y), CellState::Free);
        }
    }
    g
}

/// A head-on contact 0.18 m ahead of a robot at (2, 2) facing +x.
fn mark() -> ContactMark {
    ContactMark::estimate(
        &ContactParams::default(),
        &pose(2.0, 2.0, 0.0),
        Some(Sides {
            left: true,
            right: true,
        }),
        WheelSpeeds::from_body(0.2, 0.0, 0.235),
        0.17,
        0.235,
        Known::default(),
    )
}

/// A fan of beams from (1, 2) along +x, ending 2.5 m away: every ray crosses
/// the contact.
fn scan_through_the_contact() -> MapMsg {
    let mut scan = LaserScan::default();
    for k in 0..=20 {
        let _ = scan.beams.push(Beam {
            angle: -0.02 + 0.002 * f64::from(k),
            range: 2.5,
            intensity: 0.0,
            valid: true,
        });
    }
    MapMsg::Scan {
        pose: pose(1.0, 2.0, 0.0),
        scan,
    }
}

/// A map stage restored from `snapshot`, as a resumed run's is.
fn map_stage(snapshot: MapStageSnapshot) -> MapStage {
    let (_tx, rx) = queue("registered_scans", 8, Overflow::DropOldest);
    let (snap_tx, _snap_rx) = latest("map_snapshots");
    let mut stage = MapStage::new(
        Grid::new(Point2::new(0.0, 0.0), 0.05, 1, 1),
        rx,
        snap_tx,
        Arc::new(Shared::default()),
        5.0,
        ContactParams::default().same_contact,
    );
    stage.restore(snapshot);
    stage
}

/// The map stage's snapshot of `grid` with the contact marks `contacts`.
fn snapshot(grid: Grid, contacts: &[ContactMark]) -> MapStageSnapshot {
    MapStageSnapshot {
        grid: Some(Arc::new(grid)),
        contacts: (!contacts.is_empty()).then(|| Arc::new(contact_arcs(contacts))),
    }
}

fn occupied_at(g: &Grid, p: Point2<f64>) -> bool {
    g.state(g.cell_of(&p).unwrap()) == CellState::Occupied
}

#[test]
fn contact_marks_are_restored_and_rays_cannot_clear_them() {
    let m = mark();
    assert!((m.at - Point2::new(2.18, 2.0)).norm() < 1e-9, "{:?}", m.at);

    // The crashed run's checkpoint: a map whose rays had already cleared the
    // contact (it was written into the grid only), and the marks.
    let dir = temp_dir("contacts");
    let store = CheckpointStore::new(&dir.0);
    let mut cp = Checkpoint::new();
    cp.put(&RunProgress {
        sequence: 3,
        elapsed: 30.0,
        coverage: 0.2,
        ..RunProgress::default()
    })
    .unwrap();
    cp.put(&pose(1.0, 2.0, 0.0)).unwrap();
    cp.put(&free_room()).unwrap();
    cp.put(&contact_arcs(&[m])).unwrap();
    let tried = vec![Point2::new(1.1, 2.27)];
    cp.put(&TriedPlaces {
        places: tried.clone(),
    })
    .unwrap();
    store.save(&cp).unwrap();

    let r = load(&store, &heartbeat_store(&dir.0)).expect("resumes");
    let marks: Vec<ContactMark> = r
        .map
        .contacts
        .as_ref()
        .unwrap()
        .arcs
        .iter()
        .map(|&a| a.into())
        .collect();
    assert_eq!(marks, vec![m]);
    let places = r.plan.contacts_tried.as_ref().map(|t| t.places.clone());
    assert_eq!(places, Some(tried), "places where marks were tried");
    let grid = Grid::clone(r.map.grid.as_ref().unwrap());
    assert!(!occupied_at(&grid, m.at), "the saved grid had lost it");

    // The resumed map stage marks it at once and keeps it through rays.
    let mut stage = map_stage(r.map.clone());
    assert!(occupied_at(&stage.grid, m.at));
    for _ in 0..50 {
        stage.merge(scan_through_the_contact());
    }
    assert!(occupied_at(&stage.grid, m.at));
    // The scan does reach the wall behind it (the rays ran through).
    assert!(occupied_at(&stage.grid, Point2::new(3.5, 2.0)));

    // Without the restored list the same rays clear a mark the grid held.
    let mut marked = grid.clone();
    marked.set_state(marked.cell_of(&m.at).unwrap(), CellState::Occupied);
    let mut bare = map_stage(snapshot(marked, &[]));
    for _ in 0..50 {
        bare.merge(scan_through_the_contact());
    }
    assert!(
        !occupied_at(&bare.grid, m.at),
        "rays clear an unlisted mark"
    );
}

#[test]
fn a_checkpoint_without_marks_resumes_with_none() {
    let dir = temp_dir("no-contacts");
    let store = CheckpointStore::new(&dir.0);
    let mut cp = Checkpoint::new();
    cp.put(&RunProgress::default()).unwrap();
    cp.put(&pose(1.0, 2.0, 0.0)).unwrap();
    cp.put(&free_room()).unwrap();
    store.save(&cp).unwrap();
    let r = load(&store, &heartbeat_store(&dir.0)).expect("resumes");
    assert!(r.map.contacts.is_none());
    assert!(r.plan.contacts_tried.is_none());
}

#[test]
fn a_mark_taken_out_is_unknown_then_cleared_by_rays_and_left_out_of_the_checkpoint() {
    let m = mark();
    let other = ContactMark {
        at: Point2::new(1.0, 3.0),
        ..m
    };
    let mut stage = map_stage(snapshot(free_room(), &[m, other]));
    assert!(occupied_at(&stage.grid, m.at));
    // A request for a point a centimetre off the mark (within same_contact).
    stage.merge(MapMsg::Retire(m.at + nalgebra::Vector2::new(0.01, 0.0)));
    assert_eq!(stage.retired, 1);
    assert_eq!(stage.contacts, vec![other]);
    assert_eq!(
        stage.grid.state(stage.grid.cell_of(&m.at).unwrap()),
        CellState::Unknown
    );
    assert!(occupied_at(&stage.grid, other.at));
    // What the checkpoint saves (the shared contact list) has only the other.
    let saved = stage.snapshot().contacts.unwrap();
    let published = stage.shared.with_status(|s| s.map.contacts.clone());
    assert_eq!(published, Some(saved.clone()));
    assert_eq!(saved.arcs.len(), 1);
    assert_eq!(ContactMark::from(saved.arcs[0]), other);
    // Rays now clear the place: the planner may send the robot through it.
    for _ in 0..3 {
        stage.merge(scan_through_the_contact());
    }
    assert_eq!(
        stage.grid.state(stage.grid.cell_of(&m.at).unwrap()),
        CellState::Free
    );
    // A request far from every mark changes nothing but the count.
    stage.merge(MapMsg::Retire(Point2::new(3.0, 0.5)));
    assert_eq!(stage.retired, 2);
    assert_eq!(stage.contacts, vec![other]);
}
