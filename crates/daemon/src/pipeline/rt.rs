//! Optional real-time scheduling of the scan-path threads: a stage named in
//! `pipeline.realtime_stages` asks the OS for `SCHED_FIFO` at
//! `pipeline.realtime_priority` when its thread starts. Off by default; an
//! unprivileged process is refused (EPERM) and keeps normal scheduling, with
//! one log line saying how to allow it.

use std::io;

/// Applies `priority` to the calling thread of stage `stage` and logs the
/// outcome: granted, or refused with what to do about it. The call is
/// [`sweepline_io::os::set_thread_fifo`], tested there.
pub fn apply(stage: &str, priority: u8) {
    match sweepline_io::os::set_thread_fifo(i32::from(priority)) {
        Ok(()) => log::info!("stage {stage}: real-time scheduling SCHED_FIFO priority {priority}"),
        Err(e) if e.kind() == io::ErrorKind::PermissionDenied => log::warn!(
            "stage {stage}: the OS refused real-time priority {priority} (EPERM: the process \
             needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at least {priority}, e.g. \
             LimitRTPRIO={priority} in the service unit); running with normal scheduling"
        ),
        Err(e) => log::warn!(
            "stage {stage}: real-time priority {priority} not applied ({e}); running with \
             normal scheduling"
        ),
    }
}
