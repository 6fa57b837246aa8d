//! The run folder's `events.toml`: how often, this run, the daemon stopped
//! or gave way for something in its way or for a fault (the counters the
//! simulator puts in its `summary.md`), so that a run on real hardware
//! leaves the same record. Pure: counters in, text out.

use std::sync::atomic::Ordering;

use super::shared::Shared;
use crate::plan::HomeOutcome;

/// Name of the file in the run folder.
pub(crate) const EVENTS_FILE: &str = "events.toml";

/// The `events.toml` text for the counters in `shared`.
pub(crate) fn events_toml(shared: &Shared) -> String {
    let n = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
    let base = shared.base_health();
    format!(
        "# What the daemon did about things in its way and about faults this run\n\
         # (written by sweepline at the end of the run).\n\n\
         [events]\n\
         # Stops short of something the scan showed straight ahead that the path did not expect (control.guard).\n\
         guard_stops = {}\n\
         # Paths given up for lack of headway (daemon.stuck_after).\n\
         paths_given_up = {}\n\
         # Times the wheels were held for lack of scans (daemon.scan_timeout).\n\
         scan_holds = {}\n\
         # Bumper contact marks taken out to try the floor they walled off.\n\
         marks_taken_out = {}\n\
         # Safety events: bumper, wheel drop, dead-man, link lost.\n\
         safety_events = {}\n\
         # Wheel-base link: frames that failed their check, replies that never\n\
         # came, links lost, times the port was opened (the first open counts),\n\
         # dead-man stops.\n\
         base_checksum_errors = {}\n\
         base_timeouts = {}\n\
         base_link_losses = {}\n\
         base_opens = {}\n\
         base_deadman_stops = {}\n\n\
         [end]\n\
         # How the drive back to the start ended (plan.return_home).\n\
         drive_back = \"{}\"\n",
        n(&shared.guard_stops),
        n(&shared.stuck_paths),
        n(&shared.scan_holds),
        n(&shared.marks_taken_out),
        n(&shared.safety_events),
        base.checksum_errors,
        base.timeouts,
        base.link_losses,
        base.reconnects,
        base.deadman_stops,
        HomeOutcome::describe_run(shared.with_status(|s| s.home_outcome)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_counters_are_written_as_toml_a_person_can_read() {
        let shared = Shared::default();
        shared.guard_stops.store(3, Ordering::Relaxed);
        shared.stuck_paths.store(1, Ordering::Relaxed);
        shared.safety_events.store(2, Ordering::Relaxed);
        let text = events_toml(&shared);
        let v: toml::Value = toml::from_str(&text).unwrap();
        let e = &v["events"];
        assert_eq!(e["guard_stops"].as_integer(), Some(3));
        assert_eq!(e["paths_given_up"].as_integer(), Some(1));
        assert_eq!(e["scan_holds"].as_integer(), Some(0));
        assert_eq!(e["safety_events"].as_integer(), Some(2));
        assert!(text.contains("control.guard"), "{text}");
        assert_eq!(
            v["end"]["drive_back"].as_str(),
            Some("coverage not finished")
        );
        shared.with_status(|s| s.home_outcome = Some(crate::plan::HomeOutcome::Back));
        let v: toml::Value = toml::from_str(&events_toml(&shared)).unwrap();
        assert_eq!(v["end"]["drive_back"].as_str(), Some("back at the start"));
    }
}
