//! systemd notifications (`sd_notify` protocol): `READY=1`, `WATCHDOG=1`,
//! `STATUS=…`, `STOPPING=1`. Without `NOTIFY_SOCKET` (not started by systemd)
//! every call is a silent no-op, so the same daemon runs from a shell.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use sd_notify::NotifyState;

/// Sends notifications to the service manager and counts failures.
#[derive(Debug, Clone, Default)]
pub struct Notifier {
    errors: Arc<AtomicU64>,
}

impl Notifier {
    /// A notifier for the socket named by `NOTIFY_SOCKET` at each call.
    pub fn new() -> Self {
        Self::default()
    }

    fn send(&self, state: &[NotifyState<'_>]) -> bool {
        match sd_notify::notify(state) {
            Ok(()) => true,
            Err(e) => {
                let n = self.errors.fetch_add(1, Ordering::Relaxed) + 1;
                if n <= 3 {
                    log::warn!("sd_notify failed: {e}");
                }
                false
            }
        }
    }

    /// `READY=1`: start-up is complete (devices answered).
    pub fn ready(&self) -> bool {
        self.send(&[NotifyState::Ready])
    }

    /// `WATCHDOG=1`: every stage is alive.
    pub fn watchdog(&self) -> bool {
        self.send(&[NotifyState::Watchdog])
    }

    /// `STATUS=<text>`: one line shown by `systemctl status`.
    pub fn status(&self, text: &str) -> bool {
        self.send(&[NotifyState::Status(text)])
    }

    /// `STOPPING=1`: shutdown has begun.
    pub fn stopping(&self) -> bool {
        self.send(&[NotifyState::Stopping])
    }

    /// Notifications that failed so far.
    pub fn errors(&self) -> u64 {
        self.errors.load(Ordering::Relaxed)
    }
}

/// The watchdog period systemd asked for (`WATCHDOG_USEC` for this PID), or
/// `fallback` seconds when not set (0 = no watchdog).
pub fn watchdog_period(fallback: f64) -> Option<Duration> {
    sd_notify::watchdog_enabled().or_else(|| {
        (fallback.is_finite() && fallback > 0.0).then(|| Duration::from_secs_f64(fallback))
    })
}
