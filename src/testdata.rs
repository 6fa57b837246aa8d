//! Locating the shared real data (`../shared/` beside the checkout: laser logs,
//! SCIP captures, floor plans) for tests, benches and tools. The data is never
//! copied into this repository.

use std::path::PathBuf;

/// The shared data folder: `$SWEEPLINE_SHARED` if set, else `../shared` next to
/// the crate root.
pub fn shared_dir() -> PathBuf {
    match std::env::var_os("SWEEPLINE_SHARED") {
        Some(p) => PathBuf::from(p),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"),
    }
}

/// The path of `rel` inside this repository (`hw/worlds/paper.world`...),
/// the same for tests of this crate and for the benchmarks' package.
pub fn repo_file(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The path of `rel` inside the shared folder, if it exists.
pub fn shared_file(rel: &str) -> Option<PathBuf> {
    let p = shared_dir().join(rel);
    p.exists().then_some(p)
}

/// True when running under CI (`CI=true`), where missing shared data is a failure.
pub fn under_ci() -> bool {
    std::env::var("CI")
        .map(|v| v == "true" || v == "1")
        .unwrap_or(false)
}

/// In a test: the path of a shared data file, or, when it is missing, one line
/// saying so and an early `return` (skip). Under `CI=true` a missing file fails
/// the test instead.
#[macro_export]
macro_rules! require_shared {
    ($rel:expr) => {
        match $crate::testdata::shared_file($rel) {
            Some(p) => p,
            None => {
                if $crate::testdata::under_ci() {
                    panic!(
                        "shared data {} is missing under CI (looked in {})",
                        $rel,
                        $crate::testdata::shared_dir().display()
                    );
                }
                eprintln!(
                    "skipped: shared data {} not found in {}",
                    $rel,
                    $crate::testdata::shared_dir().display()
                );
                return;
            }
        }
    };
}
