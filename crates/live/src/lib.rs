//! sweepline's live view and recorder.
//!
//! The daemon hands copies of its scans and poses to a telemetry thread
//! through taps (edges that drop copies, never scans, when this thread
//! falls behind); the thread also reads the shared live status (map,
//! cells, path, counters) at the rates a person needs. It logs everything
//! onto Foxglove channels with the SDK's well-known schemas, and the
//! SDK's sinks take it from there:
//!
//! * [`telemetry`]: the thread, writing `run.mcap` (small zstd chunks,
//!   flushed every second, so a killed daemon leaves a readable file) and
//!   serving the live view;
//! * [`server`]: the Foxglove WebSocket server, reachable under both
//!   subprotocol names;
//! * [`recording`]: a recording read back (scans as the localise stage got
//!   them, the simulator's truth) for `sweepline replay run.mcap`;
//! * [`logs`]: the daemon's log lines, copied to the telemetry thread;
//! * [`topics`]: the channel names and what each carries.
//!
//! It sits on `sweepline-daemon` and below the simulator and the command
//! line.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

use sweepline_core::{decomp, geom, grid};

mod channels;
mod convert;
pub mod logs;
pub mod recorder;
pub mod recording;
pub mod server;
mod status;
pub mod telemetry;
pub mod topics;

pub use recorder::RecordTo;

/// The priority of the threads beside the scan path (telemetry, live view):
/// woken by a scan, they do not preempt the stage that handed it over.
const BACKGROUND_NICE: i32 = 10;

/// Lowers the calling thread to [`BACKGROUND_NICE`].
fn background() {
    if let Err(e) = sweepline_io::os::set_thread_nice(BACKGROUND_NICE) {
        log::debug!("cannot lower the priority of a telemetry thread: {e}");
    }
}
pub use recording::{Recording, RecordingError};
pub use telemetry::{Telemetry, TelemetryError, TelemetryOptions, TelemetryStats};
