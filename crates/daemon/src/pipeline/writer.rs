//! The state writer: a background thread that puts the supervisor's files
//! (checkpoints and heartbeats) on disk, so that a slow disk never holds up
//! supervision.
//!
//! Why a thread: an `fsync`, or even a rename over an existing file, can
//! block for a long time when the disk is busy (0.4-0.8 s measured on this
//! project's CI machine's ext4 under load; seconds on an SD card). Done on
//! the supervisor thread, that delays the stall checks, the status line and
//! the systemd watchdog pets (`WatchdogSec=2s` in the shipped unit: pets
//! every second) by as much, and every checkpoint and heartbeat after it.
//!
//! Each kind of file has one slot, newest wins: a job submitted while an
//! older one of the same kind still waits replaces it (counted as
//! superseded): only the newest checkpoint matters. Jobs of different kinds
//! are written in the order they became pending. Nothing here is on the
//! scan path; a job is a boxed closure (the supervisor allocates it once per
//! period).

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::Instant;

/// A write: returns what went wrong, in words, for the log.
pub(crate) type Job = Box<dyn FnOnce() -> Result<(), String> + Send>;

/// Errors of one kind logged before the writer goes quiet about them.
const ERRORS_LOGGED: u64 = 3;

/// What one kind of file's writes came to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WriteStats {
    /// Jobs written (successfully or not).
    pub done: u64,
    /// Jobs that returned an error.
    pub failed: u64,
    /// Jobs replaced by a newer one of the same kind before they were
    /// started.
    pub superseded: u64,
    /// The longest write (wall seconds).
    pub slowest: f64,
}

/// One kind of file: its pending job and its figures.
struct Slot {
    kind: &'static str,
    pending: Option<Job>,
    stats: WriteStats,
}

/// What the thread and its handle share.
#[derive(Default)]
struct Inner {
    slots: Vec<Slot>,
    /// Slot indices with a pending job, oldest first.
    order: VecDeque<usize>,
    closed: bool,
}

struct State {
    inner: Mutex<Inner>,
    wake: Condvar,
}

fn lock(state: &State) -> MutexGuard<'_, Inner> {
    // A panicking job is caught below, so the lock is only poisoned by a bug
    // here; the data stays consistent either way (plain counters and jobs).
    state.inner.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The background writer (see the module docs). Dropping it writes what is
/// pending and joins the thread, as [`StateWriter::finish`] does.
pub struct StateWriter {
    state: Arc<State>,
    thread: Option<JoinHandle<()>>,
}

impl StateWriter {
    /// Starts the writer thread, named `name` (as `top` and the report's
    /// per-thread CPU show it). When no thread can be started the writer
    /// starts finished: every job is then written at once by its caller,
    /// with the same figures and error log.
    pub fn spawn(name: &str) -> Self {
        let state = Arc::new(State {
            inner: Mutex::new(Inner::default()),
            wake: Condvar::new(),
        });
        let s = Arc::clone(&state);
        let thread = std::thread::Builder::new()
            .name(name.to_string())
            .spawn(move || run(&s))
            .inspect_err(|e| {
                log::warn!("{name}: no thread ({e}); files are written by the caller");
                lock(&state).closed = true;
            })
            .ok();
        Self { state, thread }
    }

    /// Queues `job` as the newest write of `kind`, replacing one of that
    /// kind not yet started. After [`StateWriter::finish`] the job runs
    /// here, on the caller's thread.
    pub(crate) fn submit(&self, kind: &'static str, job: Job) {
        let mut g = lock(&self.state);
        if g.closed {
            drop(g);
            let r = timed(job);
            let mut g = lock(&self.state);
            let i = slot_of(&mut g, kind);
            note(&mut g, i, r);
            return;
        }
        let i = slot_of(&mut g, kind);
        if g.slots[i].pending.replace(job).is_some() {
            g.slots[i].stats.superseded += 1;
        } else {
            g.order.push_back(i);
        }
        drop(g);
        self.state.wake.notify_one();
    }

    /// The figures of `kind` so far (zero if none was submitted).
    pub fn stats(&self, kind: &str) -> WriteStats {
        lock(&self.state)
            .slots
            .iter()
            .find(|s| s.kind == kind)
            .map(|s| s.stats.clone())
            .unwrap_or_default()
    }

    /// Writes everything pending, then stops the thread. Later submissions
    /// are written at once on the caller's thread (the final checkpoint of
    /// a shutdown).
    pub fn finish(&mut self) {
        lock(&self.state).closed = true;
        self.state.wake.notify_one();
        if let Some(t) = self.thread.take() {
            if t.join().is_err() {
                log::error!("state writer: the thread panicked");
            }
        }
    }
}

impl Drop for StateWriter {
    fn drop(&mut self) {
        self.finish();
    }
}

/// The index of `kind`'s slot, made on first use.
fn slot_of(g: &mut Inner, kind: &'static str) -> usize {
    if let Some(i) = g.slots.iter().position(|s| s.kind == kind) {
        return i;
    }
    g.slots.push(Slot {
        kind,
        pending: None,
        stats: WriteStats::default(),
    });
    g.slots.len() - 1
}

/// Runs `job`, catching a panic as an error, and times it (wall seconds).
fn timed(job: Job) -> (Result<(), String>, f64) {
    let t = Instant::now();
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(job))
        .unwrap_or_else(|_| Err("the write panicked".into()));
    (r, t.elapsed().as_secs_f64())
}

/// Counts one finished job of slot `i` and logs its error (the first few).
fn note(g: &mut Inner, i: usize, (r, secs): (Result<(), String>, f64)) {
    let s = &mut g.slots[i];
    s.stats.done += 1;
    s.stats.slowest = s.stats.slowest.max(secs);
    if let Err(e) = r {
        s.stats.failed += 1;
        if s.stats.failed <= ERRORS_LOGGED {
            log::warn!("{} not written: {e}", s.kind);
        }
    }
}

/// The thread: takes the oldest pending job, writes it outside the lock,
/// until closed with nothing pending.
fn run(state: &State) {
    let mut g = lock(state);
    loop {
        if let Some(i) = g.order.pop_front() {
            let Some(job) = g.slots[i].pending.take() else {
                continue;
            };
            drop(g);
            let r = timed(job);
            g = lock(state);
            note(&mut g, i, r);
        } else if g.closed {
            return;
        } else {
            g = state.wake.wait(g).unwrap_or_else(PoisonError::into_inner);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::mpsc;

    #[test]
    fn a_newer_job_replaces_a_waiting_one_and_finish_writes_what_is_pending() {
        let mut w = StateWriter::spawn("test-writer");
        let written = Arc::new(AtomicU64::new(0));
        // A slow first job holds the thread while three more of one kind
        // arrive: the two older of them are superseded.
        let (go, wait) = mpsc::channel::<()>();
        w.submit(
            "checkpoint",
            Box::new(move || {
                let _ = wait.recv();
                Ok(())
            }),
        );
        // Until the thread took the first job, a second would supersede it.
        while lock(&w.state).slots[0].pending.is_some() {
            std::thread::yield_now();
        }
        for n in 1..=3 {
            let written = Arc::clone(&written);
            w.submit(
                "checkpoint",
                Box::new(move || {
                    written.store(n, Ordering::SeqCst);
                    Ok(())
                }),
            );
        }
        w.submit("heartbeat", Box::new(|| Err("disk full".into())));
        go.send(()).unwrap();
        w.finish();
        assert_eq!(
            written.load(Ordering::SeqCst),
            3,
            "the newest one is written"
        );
        let c = w.stats("checkpoint");
        assert_eq!((c.done, c.superseded, c.failed), (2, 2, 0));
        let h = w.stats("heartbeat");
        assert_eq!((h.done, h.failed), (1, 1));
        // After finish: written at once, on this thread.
        w.submit("checkpoint", Box::new(|| Ok(())));
        assert_eq!(w.stats("checkpoint").done, 3);
        assert_eq!(w.stats("metrics"), WriteStats::default());
    }

    #[test]
    fn a_panicking_job_is_an_error_and_the_writer_goes_on() {
        let mut w = StateWriter::spawn("test-writer");
        w.submit("checkpoint", Box::new(|| panic!("boom")));
        let ok = Arc::new(AtomicU64::new(0));
        let o = Arc::clone(&ok);
        w.submit(
            "heartbeat",
            Box::new(move || {
                o.store(1, Ordering::SeqCst);
                Ok(())
            }),
        );
        w.finish();
        assert_eq!(w.stats("checkpoint").failed, 1);
        assert_eq!(ok.load(Ordering::SeqCst), 1);
    }
}
