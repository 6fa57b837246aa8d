//! The status message (`/sweepline/status`, JSON): what the two-second
//! status line says and more, for a Plot or Raw Messages panel.

use std::sync::atomic::Ordering;

use sweepline_daemon::daemon::Shared;
use sweepline_io::urg::UrgHealth;

/// The JSON schema of [`crate::topics::STATUS`].
pub(crate) const SCHEMA: &str = r#"{"type":"object","title":"sweepline.Status","properties":{
"time":{"type":"number","description":"daemon clock (s)"},
"task":{"type":"string","description":"what the planner is doing, in words"},
"covered_m2":{"type":"number"},"path_length_m":{"type":"number"},
"localised":{"type":"boolean"},"lost":{"type":"boolean"},
"scans":{"type":"integer"},"unmatched_scans":{"type":"integer"},"relocalisations":{"type":"integer"},
"pose":{"type":"array","items":{"type":"number"},"description":"x m, y m, heading rad (map)"},
"safety_events":{"type":"integer"},
"scanner_link":{"type":"object"},"base_link":{"type":"object"},
"cpu_percent":{"type":"number","description":"process CPU per second of robot time, % of one core"},
"end_to_end_p99_ms":{"type":"number"},
"stages":{"type":"array","items":{"type":"object","properties":{
"name":{"type":"string"},"p50_ms":{"type":"number"},"p99_ms":{"type":"number"},"cpu_s":{"type":"number"}}}}}}"#;

#[derive(serde::Serialize)]
struct Status<'a> {
    time: f64,
    task: &'a str,
    covered_m2: f64,
    path_length_m: f64,
    localised: bool,
    lost: bool,
    scans: u64,
    unmatched_scans: u64,
    relocalisations: u64,
    pose: [f64; 3],
    safety_events: u64,
    scanner_link: Option<ScannerLink>,
    base_link: BaseLink,
    cpu_percent: Option<f64>,
    end_to_end_p99_ms: Option<f64>,
    stages: Vec<Stage<'a>>,
}

/// The scanner link's counters.
#[derive(serde::Serialize)]
struct ScannerLink {
    scans: u64,
    checksum_errors: u64,
    timeouts: u64,
    dropped_scans: u64,
    restarts: u64,
}

/// The wheel base's link counters.
#[derive(serde::Serialize)]
struct BaseLink {
    sent: u64,
    received: u64,
    checksum_errors: u64,
    timeouts: u64,
    link_losses: u64,
}

/// One stage's latency and CPU.
#[derive(serde::Serialize)]
struct Stage<'a> {
    name: &'a str,
    p50_ms: f64,
    p99_ms: f64,
    cpu_s: f64,
}

/// Writes the status of `shared` (and the scanner link `urg`) at `now` as
/// JSON into `out`.
pub(crate) fn write(
    shared: &Shared,
    urg: Option<&UrgHealth>,
    now: f64,
    out: &mut Vec<u8>,
) -> serde_json::Result<()> {
    let base = shared.base_health();
    let (task, covered, path, localised, scans, fallbacks, pose) = shared.with_status(|s| {
        (
            s.task.clone(),
            s.covered_area,
            s.path_length,
            s.localised,
            s.scans,
            s.fallbacks,
            s.pose,
        )
    });
    let metrics = shared.metrics.lock().ok().and_then(|m| m.clone());
    let status = Status {
        time: now,
        task: &task,
        covered_m2: covered,
        path_length_m: path,
        localised,
        lost: shared.lost.load(Ordering::Relaxed),
        scans,
        unmatched_scans: fallbacks,
        relocalisations: shared.relocalisations.load(Ordering::Relaxed),
        pose: [
            pose.translation.vector.x,
            pose.translation.vector.y,
            pose.rotation.angle(),
        ],
        safety_events: shared.safety_events.load(Ordering::Relaxed),
        scanner_link: urg.map(|u| {
            let h = u.snapshot();
            ScannerLink {
                scans: h.scans,
                checksum_errors: h.checksum_errors,
                timeouts: h.timeouts,
                dropped_scans: h.dropped_scans,
                restarts: h.restarts,
            }
        }),
        base_link: BaseLink {
            sent: base.sent,
            received: base.received,
            checksum_errors: base.checksum_errors,
            timeouts: base.timeouts,
            link_losses: base.link_losses,
        },
        cpu_percent: metrics.as_ref().map(|m| 100.0 * m.real_time_share()),
        end_to_end_p99_ms: metrics
            .as_ref()
            .and_then(|m| m.stages.iter().map(|s| s.end_to_end_q.p99).reduce(f64::max))
            .map(|v| v * 1e3),
        stages: metrics
            .as_ref()
            .map(|m| {
                m.stages
                    .iter()
                    .map(|s| Stage {
                        name: &s.name,
                        p50_ms: s.latency_q.p50 * 1e3,
                        p99_ms: s.latency_q.p99 * 1e3,
                        cpu_s: s.cpu,
                    })
                    .collect()
            })
            .unwrap_or_default(),
    };
    serde_json::to_writer(out, &status)
}
