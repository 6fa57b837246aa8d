//! Resuming a run: loads the newest intact checkpoint of the state folder
//! (the run's progress and pose, and each stage's snapshot: see
//! [`super::snapshot`]) and the crashed daemon's last heartbeat, and says
//! what the restart lost ([`ResumeEntry`]).

use super::snapshot::{LocaliseSnapshot, MapStageSnapshot, PlanStageSnapshot, RunSnapshot};
use super::Resume;
use crate::geom::{heading, pose_error, Pose};
use crate::grid::Grid;
use crate::pipeline::checkpoint::{
    Checkpoint, CheckpointError, CheckpointStore, MountRecord, ProgressMark, ResumeEntry,
    RunFinished, RunProgress, WrittenAt,
};

/// File name of the heartbeat in the state folder: the run's progress and
/// the wall time, rewritten every `pipeline.heartbeat_period` (unsynced).
pub const HEARTBEAT_FILE: &str = "heartbeat.swc";

/// The store of the heartbeat in `state_dir`.
pub fn heartbeat_store(state_dir: &std::path::Path) -> CheckpointStore {
    CheckpointStore::with_name(state_dir, HEARTBEAT_FILE)
}

/// The heartbeat image for `progress` written at `at`.
pub fn heartbeat(progress: &RunProgress, at: WrittenAt) -> Result<Checkpoint, CheckpointError> {
    let mut cp = Checkpoint::new();
    cp.put(progress)?;
    cp.put(&at)?;
    Ok(cp)
}

/// The previous daemon's last sign of life after the checkpoint `cp` of the
/// same run segment, from `heartbeat` if it has one.
fn last_alive(cp: &RunProgress, heartbeat: &CheckpointStore) -> Option<ProgressMark> {
    let hb = match heartbeat.read_current() {
        Ok(hb) => hb?,
        Err(e) => {
            log::warn!("heartbeat unreadable, progress lost is unknown: {e}");
            return None;
        }
    };
    let p = hb.get::<RunProgress>().ok()??;
    let at = hb.get::<WrittenAt>().ok().flatten().map(|w| w.unix);
    let same_segment = p.resumes == cp.resumes && p.sequence >= cp.sequence;
    (same_segment && p.elapsed >= cp.elapsed).then(|| ProgressMark::new(&p, at))
}

/// Loads what the checkpoint in `store` holds to resume from, if anything,
/// with the heartbeat of `heartbeat` for the report. A missing or unusable
/// checkpoint is a fresh start (logged).
pub fn load(store: &CheckpointStore, heartbeat: &CheckpointStore) -> Option<Resume> {
    let l = match store.load() {
        Ok(None) => {
            log::info!("no checkpoint: fresh start");
            return None;
        }
        Ok(Some(l)) => l,
        Err(e) => {
            log::warn!("no usable checkpoint, starting fresh: {e}");
            return None;
        }
    };
    if let Some(why) = &l.fell_back {
        log::warn!("latest checkpoint unusable ({why}); using the previous copy");
    }
    let cp = &l.checkpoint;
    match cp.get::<RunFinished>() {
        Ok(Some(f)) => {
            log::info!(
                "the last run finished its coverage after {:.0} s: starting a new run",
                f.elapsed
            );
            return None;
        }
        Ok(None) => {}
        Err(e) => log::warn!("checkpoint's end-of-run record unreadable ({e}); resuming the run"),
    }
    let (progress, pose, grid) = match (cp.get::<RunProgress>(), cp.get::<Pose>(), cp.get::<Grid>())
    {
        (Ok(Some(progress)), Ok(Some(pose)), Ok(Some(grid))) => (progress, pose, grid),
        (Err(e), _, _) | (_, Err(e), _) | (_, _, Err(e)) => {
            log::warn!("checkpoint unreadable, starting fresh: {e}");
            return None;
        }
        _ => {
            log::info!("checkpoint without map or pose: fresh start");
            return None;
        }
    };
    let written = cp.get::<WrittenAt>().ok().flatten().map(|w| w.unix);
    let alive = last_alive(&progress, heartbeat);
    let entry = ResumeEntry {
        restart: progress.resumes + 1,
        resumed_unix: WrittenAt::now().unix,
        checkpoint: ProgressMark::new(&progress, written),
        last_alive: alive,
        fell_back: l.fell_back.clone(),
    };
    match (entry.checkpoint_age(), entry.coverage_lost()) {
        (Some(age), Some(lost)) => log::info!(
            "checkpoint #{} found: ~{:.1} % covered after {:.0} s, {age:.1} s old at the last \
             heartbeat ({:.1} points of coverage lost); resuming (restart {})",
            progress.sequence,
            progress.coverage * 100.0,
            progress.elapsed,
            lost * 100.0,
            entry.restart
        ),
        _ => log::info!(
            "checkpoint #{} found: ~{:.1} % covered after {:.0} s; resuming (restart {})",
            progress.sequence,
            progress.coverage * 100.0,
            progress.elapsed,
            entry.restart
        ),
    }
    Some(Resume {
        map: MapStageSnapshot::read(cp, grid),
        plan: PlanStageSnapshot::read(cp),
        localise: LocaliseSnapshot::read(cp),
        run: RunSnapshot {
            progress,
            pose,
            finished: None,
        },
        entry,
    })
}

/// The scanner mount a resumed run drives with: the one refitted before
/// the checkpoint while `[robot]` still configures the mount it was
/// refitted from, else the configured one (the configuration changed since
/// the checkpoint, e.g. to the values the run folder's `mount.toml` gave:
/// it wins).
pub(crate) fn resumed_mount(configured: Pose, record: Option<&MountRecord>) -> Pose {
    let Some(r) = record else {
        return configured;
    };
    let (moved, turned) = pose_error(&r.configured, &configured);
    let same = moved < 1e-6 && turned.abs() < 1e-6;
    if same {
        log::info!(
            "resume: driving with the scanner mount refitted before the checkpoint: ({:.3}, {:.3}) m, {:+.2}°",
            r.refitted.translation.x,
            r.refitted.translation.y,
            heading(&r.refitted).to_degrees()
        );
        r.refitted
    } else {
        log::info!(
            "resume: the configured scanner mount changed since the checkpoint; driving with the configured one"
        );
        configured
    }
}

/// Whether the offset of the mount a run drives with came from the offset
/// check (before a checkpoint) rather than from `[robot]`: a yaw refitted
/// later then turns that offset back, as it does within one run (an
/// offset fitted under a wrong yaw is turned by the error).
pub(crate) fn offset_was_fitted(configured: &Pose, driving: &Pose) -> bool {
    (driving.translation.vector - configured.translation.vector).norm() > 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::pipeline::checkpoint::Section;
    use crate::plan::HomePlace;

    /// A `run.finished` payload whose run time is not a number.
    #[derive(serde::Serialize, serde::Deserialize)]
    struct BadFinished(f64);

    impl Section for BadFinished {
        const NAME: &'static str = "run.finished";
        const VERSION: u16 = 1;
    }

    /// A `plan.home` payload whose start is not a number.
    #[derive(serde::Serialize, serde::Deserialize)]
    struct BadHome(f64, f64, f64);

    impl Section for BadHome {
        const NAME: &'static str = "plan.home";
        const VERSION: u16 = 1;
    }

    #[test]
    fn the_start_is_resumed_a_missing_or_bad_record_still_resumes_and_a_finished_run_does_not() {
        let dir =
            std::env::temp_dir().join(format!("sweepline-resume-home-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let store = CheckpointStore::new(&dir);
        let beat = heartbeat_store(&dir);
        let home = HomePlace {
            x: 0.5,
            y: 0.4,
            heading: 0.2,
        };
        for case in ["with", "without", "bad"] {
            let mut cp = Checkpoint::new();
            cp.put(&RunProgress::default()).unwrap();
            cp.put(&pose(2.0, 1.0, 0.0)).unwrap();
            cp.put(&Grid::new(nalgebra::Point2::new(0.0, 0.0), 0.05, 20, 20))
                .unwrap();
            match case {
                "with" => cp.put(&home).unwrap(),
                "bad" => cp.put(&BadHome(f64::NAN, f64::NAN, f64::NAN)).unwrap(),
                _ => {}
            }
            store.save(&cp).unwrap();
            let r = load(&store, &beat).unwrap_or_else(|| panic!("{case}: not resumed"));
            let want = (case == "with").then_some(home);
            assert_eq!(r.plan.planner.home, want, "{case}");
            // The same run finished: the next start is a new run.
            let mut fin = cp.clone();
            fin.put(&RunFinished { elapsed: 700.0 }).unwrap();
            store.save(&fin).unwrap();
            assert!(
                load(&store, &beat).is_none(),
                "{case}: a finished run resumed"
            );
            // An unreadable end-of-run record: resumed (nothing is lost).
            cp.put(&BadFinished(f64::NAN)).unwrap();
            store.save(&cp).unwrap();
            assert!(load(&store, &beat).is_some(), "{case}: bad record");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_refitted_mount_is_resumed_only_while_the_configuration_is_unchanged() {
        let configured = pose(0.0, 0.0, 0.0);
        let rec = MountRecord {
            configured,
            refitted: pose(0.08, 0.04, 0.05),
        };
        assert_eq!(resumed_mount(configured, None), configured);
        assert_eq!(resumed_mount(configured, Some(&rec)), rec.refitted);
        // The configuration now says where the scanner is (e.g. from
        // mount.toml): it wins.
        let fixed = pose(0.079, 0.04, 0.052);
        assert_eq!(resumed_mount(fixed, Some(&rec)), fixed);
    }

    #[test]
    fn a_resumed_offset_counts_as_fitted_only_where_it_left_the_configured_one() {
        let configured = pose(0.1, 0.0, 0.0);
        // Only the yaw was refitted: the offset is still the configured one.
        assert!(!offset_was_fitted(&configured, &pose(0.1, 0.0, 0.05)));
        assert!(offset_was_fitted(&configured, &pose(0.14, 0.02, 0.05)));
        assert!(!offset_was_fitted(&configured, &configured));
    }
}
