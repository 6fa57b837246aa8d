//! Checkpoint container and store on a real file system: round trips of the
//! pipeline's sections, atomic replacement, fallback to the previous copy,
//! and the rule that a corrupted checkpoint never replaces a good one.

use std::path::PathBuf;

use nalgebra::Point2;
use sweepline::geom::{heading, pose, IPoint, Pose};
use sweepline::grid::{CellState, Grid};
use sweepline::pipeline::checkpoint::{
    Checkpoint, CheckpointError, CheckpointStore, RunProgress, Section,
};

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sweepline-ckpt-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A section another module would add: map points.
#[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct MapPoints(Vec<IPoint>);

impl Section for MapPoints {
    const NAME: &'static str = "map.points";
    const VERSION: u16 = 3;
}

fn sample(seq: u64) -> Checkpoint {
    let mut g = Grid::new(Point2::new(-1.0, -2.0), 0.05, 40, 30);
    g.integrate_ray(&Point2::new(0.0, 0.0), &Point2::new(0.7, 0.3), true);
    g.set_state((1, 1), CellState::Occupied);
    let mut cp = Checkpoint::new();
    cp.put(&pose(1.0 + seq as f64, -0.5, 0.3)).unwrap();
    cp.put(&g).unwrap();
    cp.put(&RunProgress {
        sequence: seq,
        elapsed: 12.5 * seq as f64,
        coverage: 0.1 * seq as f64,
        scans: 100 * seq,
        path_length: 3.0,
        resumes: 0,
    })
    .unwrap();
    cp.put(&MapPoints(vec![IPoint::new(0.1, 0.2, 0.9); 5]))
        .unwrap();
    cp
}

#[test]
fn sections_round_trip_exactly() {
    let cp = sample(2);
    let back = Checkpoint::from_bytes(&cp.to_bytes()).unwrap();
    assert_eq!(back, cp);
    let p: Pose = back.require().unwrap();
    assert!((p.translation.x - 3.0).abs() < 1e-12);
    assert!((heading(&p) - 0.3).abs() < 1e-12);
    let g: Grid = back.require().unwrap();
    let orig: Grid = cp.require().unwrap();
    assert_eq!(g.raw_evidence(), orig.raw_evidence());
    assert_eq!((g.width(), g.height()), (40, 30));
    assert_eq!(g.state((1, 1)), CellState::Occupied);
    assert_eq!(back.require::<RunProgress>().unwrap().scans, 200);
    assert_eq!(back.require::<MapPoints>().unwrap().0.len(), 5);
    assert_eq!(
        back.names().collect::<Vec<_>>(),
        vec!["pose", "grid", "progress", "map.points"]
    );
}

#[test]
fn put_replaces_and_refuses_invalid_values() {
    let mut cp = sample(1);
    cp.put(&pose(9.0, 9.0, 0.0)).unwrap();
    assert_eq!(cp.names().count(), 4);
    assert_eq!(cp.require::<Pose>().unwrap().translation.x, 9.0);
    let e = cp.put(&pose(f64::NAN, 0.0, 0.0)).unwrap_err();
    assert!(e.to_string().contains("section `pose`"), "{e}");
    assert!(e.to_string().contains("not a finite number"), "{e}");
    assert_eq!(
        cp.require::<Pose>().unwrap().translation.x,
        9.0,
        "old value kept"
    );
    let e = cp
        .put(&RunProgress {
            coverage: 1.5,
            ..Default::default()
        })
        .unwrap_err();
    assert!(e.to_string().contains("coverage 1.5"), "{e}");
    let empty = Checkpoint::new();
    assert!(matches!(
        empty.require::<Pose>(),
        Err(CheckpointError::Missing(ref n)) if n == "pose"
    ));
    assert!(empty.get::<Pose>().unwrap().is_none());
}

#[test]
fn a_newer_section_version_is_refused_by_name() {
    #[derive(serde::Serialize, serde::Deserialize)]
    struct PoseV2(f64, f64, f64);
    impl Section for PoseV2 {
        const NAME: &'static str = "pose";
        const VERSION: u16 = 2;
    }
    let mut cp = Checkpoint::new();
    cp.put(&PoseV2(0.0, 0.0, 0.0)).unwrap();
    let e = cp.get::<Pose>().unwrap_err();
    assert!(e.to_string().contains("`pose` has version 2"), "{e}");
}

#[test]
fn store_saves_atomically_and_keeps_the_previous_copy() {
    let dir = temp_dir("save");
    let store = CheckpointStore::new(&dir);
    assert!(
        store.load().unwrap().is_none(),
        "fresh start: no checkpoint"
    );
    store.save(&sample(1)).unwrap();
    store.save(&sample(2)).unwrap();
    let l = store.load().unwrap().unwrap();
    assert!(l.fell_back.is_none());
    assert_eq!(l.checkpoint, sample(2));
    assert_eq!(Checkpoint::read(&store.prev_path()).unwrap(), sample(1));
    // A leftover tmp file from a crash mid-write does not matter.
    std::fs::write(dir.join("checkpoint.swc.tmp"), b"half a checkpo").unwrap();
    assert_eq!(store.load().unwrap().unwrap().checkpoint, sample(2));
    store.save(&sample(3)).unwrap();
    assert_eq!(store.load().unwrap().unwrap().checkpoint, sample(3));
    assert!(!dir.join("checkpoint.swc.tmp").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_corrupted_checkpoint_never_replaces_a_good_one() {
    let dir = temp_dir("corrupt");
    let store = CheckpointStore::new(&dir);
    store.save(&sample(1)).unwrap();
    store.save(&sample(2)).unwrap();

    // The current file is damaged on disk (one flipped byte).
    let mut bytes = std::fs::read(store.path()).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(store.path(), &bytes).unwrap();
    let l = store.load().unwrap().unwrap();
    assert_eq!(l.checkpoint, sample(1), "falls back to the previous copy");
    assert!(l.fell_back.unwrap().contains("corrupted"));

    // Saving now must not rotate the damaged file over the good previous one.
    store.save(&sample(3)).unwrap();
    assert_eq!(Checkpoint::read(&store.prev_path()).unwrap(), sample(1));
    assert_eq!(store.load().unwrap().unwrap().checkpoint, sample(3));
    assert!(
        dir.join("checkpoint.swc.bad").exists(),
        "kept for a post-mortem"
    );

    // Truncated current (crash of a careless writer) → previous copy.
    store.save(&sample(4)).unwrap();
    let cur = std::fs::read(store.path()).unwrap();
    std::fs::write(store.path(), &cur[..cur.len() - 7]).unwrap();
    assert_eq!(store.load().unwrap().unwrap().checkpoint, sample(3));

    // Both damaged: a clear error naming both reasons, no panic.
    std::fs::write(store.prev_path(), b"garbage").unwrap();
    let e = store.load().unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("no usable checkpoint"), "{msg}");
    assert!(
        msg.contains("corrupted") && msg.contains("bad magic"),
        "{msg}"
    );

    // An invalid value never even reaches a file: the good files stay.
    let mut bad = sample(5);
    assert!(bad.put(&pose(0.0, f64::INFINITY, 0.0)).is_err());
    store.save(&bad).unwrap(); // the pose section kept its valid value
    assert_eq!(store.load().unwrap().unwrap().checkpoint, sample(5));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn save_into_an_unwritable_place_is_a_clear_error() {
    let dir = temp_dir("unwritable");
    let file = dir.join("not-a-dir");
    std::fs::write(&file, b"x").unwrap();
    let store = CheckpointStore::new(&file.join("sub"));
    let e = store.save(&sample(1)).unwrap_err();
    assert!(e.to_string().contains("not-a-dir"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
