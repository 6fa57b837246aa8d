//! Clocks the pipeline measures with: the monotonic clock every message is
//! stamped on (so a scan's `t0` can be compared with the wheel command it
//! produced, on any thread), the calling thread's CPU time and the process's
//! CPU time. The readings are `sweepline_io::os`'s (this crate has no
//! `unsafe`): plain `clock_gettime` / `getrusage` calls, no allocation.

use std::time::Duration;

/// A point on the system's monotonic clock (`CLOCK_MONOTONIC`), in nanoseconds.
/// Shared by all threads and by the serial drivers, which stamp the last byte
/// of a scan with it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Stamp(pub u64);

impl Stamp {
    /// The current monotonic time.
    pub fn now() -> Self {
        Stamp(sweepline_io::os::monotonic_nanos())
    }

    /// Time from `earlier` to `self`, zero if `earlier` is later.
    pub fn since(self, earlier: Stamp) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }

    /// This stamp moved `d` later (saturating).
    pub fn after(self, d: Duration) -> Stamp {
        Stamp(
            self.0
                .saturating_add(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)),
        )
    }
}

/// CPU time consumed so far by the calling thread (`CLOCK_THREAD_CPUTIME_ID`).
/// A real syscall (not vDSO): call it once per stage iteration, not per beam.
pub fn thread_cpu_time() -> Duration {
    sweepline_io::os::thread_cpu_time()
}

/// CPU time (user + system) consumed so far by the whole process
/// (`getrusage(RUSAGE_SELF)`), all threads included.
pub fn process_cpu_time() -> Duration {
    sweepline_io::os::process_cpu_time()
}

/// Number of CPU cores this process may run on (1 when unknown).
pub fn core_count() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_never_goes_back() {
        let a = Stamp::now();
        let b = Stamp::now();
        assert!(b >= a);
        assert_eq!(a.since(b), Duration::ZERO);
        assert_eq!(Stamp(5).since(Stamp(9)), Duration::ZERO);
        assert_eq!(Stamp(5).after(Duration::from_nanos(3)), Stamp(8));
        assert_eq!(
            Stamp(u64::MAX).after(Duration::from_secs(1)),
            Stamp(u64::MAX)
        );
    }

    #[test]
    fn cpu_clocks_and_cores_answer() {
        // The readings themselves are tested in `sweepline_io::os`.
        assert!(thread_cpu_time() > Duration::ZERO);
        assert!(process_cpu_time() > Duration::ZERO);
        assert!(core_count() >= 1);
    }
}
