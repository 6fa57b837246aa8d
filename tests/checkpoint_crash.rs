//! `kill -9` in the middle of checkpoint writing: a child process saves
//! checkpoints as fast as it can (resuming from the last one each time, as
//! the daemon does) and is killed with SIGKILL at random moments. After every
//! kill there must be a usable checkpoint, and progress never goes back.

use std::process::Command;
use std::thread::sleep;
use std::time::Duration;

use nalgebra::Point2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sweepline::geom::pose;
use sweepline::grid::Grid;
use sweepline::pipeline::checkpoint::{Checkpoint, CheckpointStore, RunProgress};

const CHILD_ENV: &str = "SWEEPLINE_CKPT_CHILD";

/// The child: not a test on its own (returns at once unless started by the
/// parent test below with the state folder in `SWEEPLINE_CKPT_CHILD`).
#[test]
fn child_writer() {
    let Some(dir) = std::env::var_os(CHILD_ENV) else {
        return;
    };
    let store = CheckpointStore::new(std::path::Path::new(&dir));
    let mut seq = match store.load().expect("a usable checkpoint on restart") {
        Some(l) => l.checkpoint.require::<RunProgress>().unwrap().sequence,
        None => 0,
    };
    let mut grid = Grid::new(Point2::new(0.0, 0.0), 0.05, 400, 400);
    loop {
        seq += 1;
        let x = (seq % 400) as f64 * 0.05;
        grid.integrate_ray(&Point2::new(0.01, 0.01), &Point2::new(x, 19.0), true);
        let mut cp = Checkpoint::new();
        cp.put(&pose(x, 1.0, 0.1)).unwrap();
        cp.put(&grid).unwrap();
        cp.put(&RunProgress {
            sequence: seq,
            elapsed: seq as f64,
            coverage: 0.5,
            scans: seq * 20,
            path_length: 0.0,
            resumes: 0,
        })
        .unwrap();
        store.save(&cp).unwrap();
    }
}

#[test]
fn kill_9_during_saves_always_leaves_a_usable_checkpoint() {
    let dir = std::env::temp_dir().join(format!("sweepline-crash-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let store = CheckpointStore::new(&dir);
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut last_seq = 0;
    let mut progressed = 0;
    for round in 0..10 {
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args(["child_writer", "--exact", "--nocapture", "--test-threads=1"])
            .env(CHILD_ENV, &dir)
            .spawn()
            .unwrap();
        sleep(Duration::from_millis(rng.random_range(150..600)));
        child.kill().unwrap(); // SIGKILL
        let status = child.wait().unwrap();
        assert!(
            !status.success(),
            "round {round}: the child was killed, not finished"
        );
        let loaded = store
            .load()
            .unwrap_or_else(|e| panic!("round {round}: no usable checkpoint after kill -9: {e}"));
        let Some(l) = loaded else {
            assert_eq!(last_seq, 0, "round {round}: checkpoint vanished");
            continue;
        };
        let seq = l.checkpoint.require::<RunProgress>().unwrap().sequence;
        assert!(
            seq >= last_seq,
            "round {round}: progress went back {last_seq} → {seq}"
        );
        if seq > last_seq {
            progressed += 1;
        }
        last_seq = seq;
    }
    assert!(
        progressed >= 5,
        "the writer made progress in most rounds: {progressed}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
