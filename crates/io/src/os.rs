//! The operating-system calls the rest of sweepline needs outside the
//! drivers: the monotonic clock, thread and process CPU time, real-time
//! scheduling and the kernel's clock ticks. Each is a safe wrapper around
//! one call, so that this crate stays the only one with `unsafe` (the
//! others forbid it).
//!
//! None of them allocates: the clock and CPU-time reads run once per stage
//! iteration on the scan path.
//!
//! The clocks and the clock ticks are `rustix`'s (safe, typed). Two calls
//! stay on `libc`, which rustix does not cover: `getrusage` and
//! `pthread_setschedparam` / `pthread_getschedparam` (rustix has no
//! thread scheduling policy calls).

use std::io;
use std::time::Duration;

/// `SCHED_FIFO`, the policy [`thread_scheduling`] reports for a thread that
/// [`set_thread_fifo`] was granted.
pub const SCHED_FIFO: i32 = libc::SCHED_FIFO;

/// Reads `clock` in nanoseconds.
fn read_clock(clock: rustix::time::ClockId) -> u64 {
    let ts = rustix::time::clock_gettime(clock);
    (ts.tv_sec.max(0) as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(ts.tv_nsec.max(0) as u64)
}

/// Nanoseconds on the system's monotonic clock (`CLOCK_MONOTONIC`, origin
/// at boot): one clock shared by every thread and process, so stamps taken
/// on different threads compare. A vDSO read, no syscall on Linux.
pub fn monotonic_nanos() -> u64 {
    read_clock(rustix::time::ClockId::Monotonic)
}

/// CPU time consumed so far by the calling thread
/// (`CLOCK_THREAD_CPUTIME_ID`), for the per-stage CPU budgets. A real
/// syscall (not vDSO): call it once per stage iteration, not per beam.
pub fn thread_cpu_time() -> Duration {
    Duration::from_nanos(read_clock(rustix::time::ClockId::ThreadCPUTime))
}

/// CPU time (user + system) consumed so far by the whole process, all
/// threads included (`getrusage(RUSAGE_SELF)`); zero if the call fails.
pub fn process_cpu_time() -> Duration {
    // SAFETY: an all-zero rusage is a valid value of this plain C struct.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `ru` is valid and writable; getrusage only writes it.
    let rc = unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut ru) };
    if rc != 0 {
        return Duration::ZERO;
    }
    let tv = |t: libc::timeval| {
        Duration::from_secs(t.tv_sec.max(0) as u64) + Duration::from_micros(t.tv_usec.max(0) as u64)
    };
    tv(ru.ru_utime) + tv(ru.ru_stime)
}

/// Puts the calling thread under `SCHED_FIFO` at `priority` (1..=99), so a
/// scan-path stage is not preempted by ordinary work. An unprivileged
/// process is refused with [`io::ErrorKind::PermissionDenied`] (EPERM) and
/// the thread keeps its scheduling; an out-of-range priority is an error.
pub fn set_thread_fifo(priority: i32) -> io::Result<()> {
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

/// Lowers the calling thread's priority to `nice` (0..=19; higher is
/// lower): for work beside the scan path (the recorder, the live view),
/// which then neither preempts a stage when it is woken nor competes with
/// the stages for a busy core. Needs no privilege.
pub fn set_thread_nice(nice: i32) -> io::Result<()> {
    if !(0..=19).contains(&nice) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("nice {nice} outside 0..=19"),
        ));
    }
    // SAFETY: gettid has no preconditions; setpriority with PRIO_PROCESS and
    // a thread id changes only that thread on Linux, and takes no pointers.
    let rc = unsafe {
        let tid = libc::gettid();
        libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, nice)
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// The calling thread's scheduling policy (e.g. [`SCHED_FIFO`]) and
/// priority, to check what [`set_thread_fifo`] left in place.
pub fn thread_scheduling() -> io::Result<(i32, i32)> {
    let mut policy = 0;
    let mut param = libc::sched_param { sched_priority: 0 };
    // SAFETY: as in `set_thread_fifo`; both out-pointers are valid for writes.
    let rc = unsafe { libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param) };
    if rc == 0 {
        Ok((policy, param.sched_priority))
    } else {
        Err(io::Error::from_raw_os_error(rc))
    }
}

/// The kernel's clock ticks per second (`sysconf(_SC_CLK_TCK)`), the unit
/// of the CPU times in `/proc/*/stat`; `None` when the system does not say.
pub fn clock_ticks_per_second() -> Option<u64> {
    Some(rustix::param::clock_ticks_per_second()).filter(|&t| t > 0)
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_thread_lowers_its_own_priority_only() {
        let nice = std::thread::spawn(|| {
            super::set_thread_nice(7).unwrap();
            // SAFETY: as in set_thread_nice.
            unsafe { libc::getpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t) }
        })
        .join()
        .unwrap();
        assert_eq!(nice, 7);
        // SAFETY: as above, for this thread.
        let mine = unsafe { libc::getpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t) };
        assert_ne!(mine, 7);
        assert!(super::set_thread_nice(20).is_err());
    }

    use super::*;

    #[test]
    fn clocks_move_forward() {
        let a = monotonic_nanos();
        let b = monotonic_nanos();
        assert!(a > 0 && b >= a);
        let before = thread_cpu_time();
        let p0 = process_cpu_time();
        let mut x = 0u64;
        let t = std::time::Instant::now();
        while t.elapsed() < Duration::from_millis(30) {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        assert!(thread_cpu_time() - before > Duration::from_millis(1));
        assert!(process_cpu_time() > p0);
        assert!(clock_ticks_per_second().is_some());
    }

    #[test]
    fn fifo_is_granted_or_refused_cleanly() {
        let (before, result, after) = std::thread::spawn(|| {
            let before = thread_scheduling().unwrap();
            let r = set_thread_fifo(1);
            (
                before,
                r.map_err(|e| e.kind()),
                thread_scheduling().unwrap(),
            )
        })
        .join()
        .unwrap();
        match result {
            Ok(()) => assert_eq!(after, (SCHED_FIFO, 1)),
            Err(kind) => {
                assert_eq!(kind, io::ErrorKind::PermissionDenied);
                assert_eq!(after, before, "a refusal leaves the thread as it was");
            }
        }
        let bad = std::thread::spawn(|| set_thread_fifo(1000).is_err())
            .join()
            .unwrap();
        assert!(bad);
    }
}
