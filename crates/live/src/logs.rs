//! The daemon's log lines for the live view and the recording: a logger
//! that hands every record to the console logger as before and, while a
//! telemetry thread listens, a copy of each line at `info` or above to it.
//!
//! Lines are copied into a bounded queue per listener and dropped when it
//! is full: a log line never waits for the live view.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use crossbeam_channel::{Receiver, Sender};
use log::{LevelFilter, Log, Metadata, Record};

/// Lines a listener holds before it drops.
const DEPTH: usize = 256;

/// One log line.
#[derive(Clone, Debug)]
pub struct LogLine {
    /// Its level.
    pub level: log::Level,
    /// The module that logged it.
    pub target: String,
    /// The message.
    pub message: String,
    /// Source file and line, where known.
    pub file: String,
    /// Source line.
    pub line: u32,
}

/// The listeners: an id each, to leave again.
static LISTENERS: Mutex<Vec<(u64, Sender<LogLine>)>> = Mutex::new(Vec::new());
static NEXT_ID: AtomicU64 = AtomicU64::new(0);

/// A telemetry thread's place among the listeners; leaves on drop.
pub struct Listener {
    id: u64,
    /// The lines.
    pub rx: Receiver<LogLine>,
}

impl Listener {
    /// Starts listening.
    pub fn join() -> Listener {
        let (tx, rx) = crossbeam_channel::bounded(DEPTH);
        let id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut l) = LISTENERS.lock() {
            l.push((id, tx));
        }
        Listener { id, rx }
    }
}

impl Drop for Listener {
    fn drop(&mut self) {
        if let Ok(mut l) = LISTENERS.lock() {
            l.retain(|(id, _)| *id != self.id);
        }
    }
}

/// The logger: the console's, and a copy to the listeners.
struct Tee {
    inner: Option<Box<dyn Log>>,
}

impl Log for Tee {
    fn enabled(&self, m: &Metadata<'_>) -> bool {
        m.level() <= log::Level::Info || self.inner.as_ref().is_some_and(|i| i.enabled(m))
    }

    fn log(&self, record: &Record<'_>) {
        if let Some(i) = &self.inner {
            if i.enabled(record.metadata()) {
                i.log(record);
            }
        }
        if record.level() > log::Level::Info {
            return;
        }
        let Ok(listeners) = LISTENERS.lock() else {
            return;
        };
        if listeners.is_empty() {
            return;
        }
        let line = LogLine {
            level: record.level(),
            target: record.target().to_string(),
            message: record.args().to_string(),
            file: record.file().unwrap_or_default().to_string(),
            line: record.line().unwrap_or(0),
        };
        for (_, tx) in listeners.iter() {
            let _ = tx.try_send(line.clone());
        }
    }

    fn flush(&self) {
        if let Some(i) = &self.inner {
            i.flush();
        }
    }
}

/// Installs the logger: `console` as configured (its filter `level`), plus
/// the copy for the live view. Fails when a logger is already installed.
pub fn install(console: Box<dyn Log>, level: LevelFilter) -> Result<(), log::SetLoggerError> {
    log::set_boxed_logger(Box::new(Tee {
        inner: Some(console),
    }))?;
    log::set_max_level(level.max(LevelFilter::Info));
    Ok(())
}

/// Installs the logger without a console (tests): only the copy. Does
/// nothing when a logger is already installed.
pub fn install_quiet() {
    if log::set_boxed_logger(Box::new(Tee { inner: None })).is_ok() {
        log::set_max_level(LevelFilter::Info);
    }
}
