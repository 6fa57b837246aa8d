//! Reports: SVG pictures (map, cells, path, histograms), the latency/CPU
//! budget report and what a run's restarts lost.

pub mod budget;
pub mod histogram;
pub mod resume;
pub mod run_folder;

pub use budget::{report_run_dir, write_budget_report, ReportError};
pub use run_folder::RunFolderHooks;
