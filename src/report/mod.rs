//! Reports: SVG pictures (map, cells, path, histograms) and the latency/CPU
//! budget report.

pub mod budget;
pub mod histogram;

pub use budget::{report_run_dir, write_budget_report, ReportError};
