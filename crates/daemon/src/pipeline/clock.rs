//! Clocks the pipeline measures with: the monotonic clock every message is
//! stamped on (so a scan's `t0` can be compared with the wheel command it
//! produced, on any thread), the calling thread's CPU time and the process's
//! CPU time. All are plain `clock_gettime` / `getrusage` calls: no allocation.

use std::time::Duration;

/// A point on the system's monotonic clock (`CLOCK_MONOTONIC`), in nanoseconds.
/// Shared by all threads and by the serial drivers, which stamp the last byte
/// of a scan with it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Stamp(pub u64);

impl Stamp {
    /// The current monotonic time.
    pub fn now() -> Self {
        Stamp(read_clock(libc::CLOCK_MONOTONIC))
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

fn read_clock(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; clock_gettime only writes it.
    let rc = unsafe { libc::clock_gettime(clock, &mut ts) };
    if rc != 0 {
        return 0;
    }
    (ts.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(ts.tv_nsec as u64)
}

/// CPU time consumed so far by the calling thread (`CLOCK_THREAD_CPUTIME_ID`).
/// A real syscall (not vDSO): call it once per stage iteration, not per beam.
pub fn thread_cpu_time() -> Duration {
    Duration::from_nanos(read_clock(libc::CLOCK_THREAD_CPUTIME_ID))
}

/// CPU time (user + system) consumed so far by the whole process
/// (`getrusage(RUSAGE_SELF)`), all threads included.
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
    fn busy_thread_accumulates_cpu_time() {
        let before = thread_cpu_time();
        let p0 = process_cpu_time();
        let mut x = 0u64;
        let t = std::time::Instant::now();
        while t.elapsed() < Duration::from_millis(30) {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        let used = thread_cpu_time() - before;
        assert!(used > Duration::from_millis(1), "thread cpu {used:?}");
        assert!(process_cpu_time() > p0);
        assert!(core_count() >= 1);
    }
}
