//! The six stages of the data path, each a [`crate::pipeline::Stage`] run on
//! its own thread by the pipeline: scanner, localise, map, plan, control,
//! motor. Every stage reads time only through the injected clock; edge waits
//! are converted to wall time with [`crate::clock::Clock::to_wall`].

mod control;
mod localise;
mod map;
mod motor;
mod plan;
mod scanner;

pub use control::{ControlStage, ControlWork};
pub(crate) use localise::Lost;
pub use localise::{deskew, pins_the_pose, LocaliseStage, CHECK_INFORMATION_FACTOR};
pub use map::{contact_arcs, MapStage};
pub use motor::{MotorStage, MotorWork};
pub use plan::{MarkProbe, PlanStage};
pub use scanner::ScannerStage;

use std::sync::atomic::Ordering;
use std::time::Duration;

use crate::clock::SharedClock;
use crate::daemon::shared::Shared;
use crate::pipeline::StageFault;

/// The fault of a send to a stage that has gone: expected while shutting
/// down, fatal otherwise.
fn gone(shared: &Shared, what: &str) -> Result<(), StageFault> {
    if shared.halt.load(Ordering::Relaxed) {
        Ok(())
    } else {
        Err(StageFault::Fatal(format!("the {what} stage is gone")))
    }
}

/// Wall time from clock time `now` until clock time `at`, at most `cap`:
/// the OS wait for a deadline on the injected clock.
fn wall_until(clock: &SharedClock, now: f64, at: f64, cap: Duration) -> Duration {
    clock.to_wall((at - now).max(0.0)).min(cap)
}
