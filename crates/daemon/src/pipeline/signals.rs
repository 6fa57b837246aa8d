//! SIGTERM / SIGINT / SIGHUP forwarded into the supervisor's event channel
//! (signal-hook's self-pipe iterator on its own thread), so shutdown goes
//! through the same `select!` as every other event and runs in order.

use std::thread::JoinHandle;

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use signal_hook::iterator::{Handle, Signals};

use super::supervisor::Control;

/// Forwards termination signals to a supervisor until dropped.
pub struct SignalForwarder {
    handle: Handle,
    thread: Option<JoinHandle<()>>,
}

impl SignalForwarder {
    /// Installs handlers for SIGTERM, SIGINT and SIGHUP and starts the thread
    /// that forwards each one to `control` as a stop request.
    pub fn install(control: Control) -> std::io::Result<Self> {
        let mut signals = Signals::new([SIGTERM, SIGINT, SIGHUP])?;
        let handle = signals.handle();
        let thread = std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || {
                for sig in signals.forever() {
                    control.signal(sig);
                }
            })?;
        Ok(Self {
            handle,
            thread: Some(thread),
        })
    }
}

impl Drop for SignalForwarder {
    fn drop(&mut self) {
        self.handle.close();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Name of a signal number for messages.
pub(crate) fn signal_name(sig: i32) -> &'static str {
    match sig {
        SIGTERM => "SIGTERM",
        SIGINT => "SIGINT",
        SIGHUP => "SIGHUP",
        _ => "signal",
    }
}
