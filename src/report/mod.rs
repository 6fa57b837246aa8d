//! Reports: SVG pictures (map, cells, path, histograms) and the latency/CPU
//! budget report.

pub mod budget;
pub mod histogram;
pub mod run_folder;

pub use budget::{report_run_dir, write_budget_report, ReportError};
pub use run_folder::RunFolderHooks;
