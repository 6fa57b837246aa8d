//! Optional real-time scheduling of the scan-path threads: a stage named in
//! `pipeline.realtime_stages` asks the OS for `SCHED_FIFO` at
//! `pipeline.realtime_priority` when its thread starts. Off by default; an
//! unprivileged process is refused (EPERM) and keeps normal scheduling, with
//! one log line saying how to allow it.

use std::io;

/// Puts the calling thread under `SCHED_FIFO` at `priority` (1..=99).
pub(crate) fn set_fifo(priority: i32) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: pthread_self() names the calling thread, which is alive for the
    // whole call; `param` is a valid sched_param that outlives the call.
    let rc = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::from_raw_os_error(rc))
    }
}

/// The calling thread's scheduling policy and priority.
pub fn current() -> io::Result<(i32, i32)> {
    let mut policy = 0;
    let mut param = libc::sched_param { sched_priority: 0 };
    // SAFETY: as in `set_fifo`; both out-pointers are valid for writes.
    let rc = unsafe { libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param) };
    if rc == 0 {
        Ok((policy, param.sched_priority))
    } else {
        Err(io::Error::from_raw_os_error(rc))
    }
}

/// Applies `priority` to the calling thread of stage `stage` and logs the
/// outcome: granted, or refused with what to do about it.
pub fn apply(stage: &str, priority: u8) {
    match set_fifo(i32::from(priority)) {
        Ok(()) => log::info!("stage {stage}: real-time scheduling SCHED_FIFO priority {priority}"),
        Err(e) if e.raw_os_error() == Some(libc::EPERM) => log::warn!(
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifo_is_granted_or_refused_cleanly() {
        let r = std::thread::spawn(|| {
            let before = current().unwrap();
            let r = set_fifo(1);
            (before, r.map_err(|e| e.raw_os_error()), current().unwrap())
        })
        .join()
        .unwrap();
        let (before, result, after) = r;
        match result {
            Ok(()) => assert_eq!(after, (libc::SCHED_FIFO, 1)),
            Err(code) => {
                assert_eq!(code, Some(libc::EPERM));
                assert_eq!(after, before, "a refusal leaves the thread as it was");
            }
        }
        // An invalid priority is an error, never a panic.
        let bad = std::thread::spawn(|| set_fifo(1000).is_err())
            .join()
            .unwrap();
        assert!(bad);
    }
}
