//! The shared gmapping map of the lab_ipa building (`map.pgm`) loaded as a
//! user would: through a map_server YAML naming the image, with the values
//! of the shared metadata. Used by `tests/coverage_ros_map.rs` and
//! `benches/plan_update.rs`.

use std::path::{Path, PathBuf};

/// The map image, relative to the shared folder.
pub const MAP: &str = "maps/ipa_coverage_planning_test_maps/map.pgm";

/// Writes `dir/name`, a map_server YAML naming `image` by its absolute path
/// (the YAML lives elsewhere), creating `dir`; returns the YAML's path.
pub fn write_yaml(dir: &Path, name: &str, image: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).expect("create the map YAML's folder");
    let p = dir.join(name);
    std::fs::write(
        &p,
        format!(
            "image: {}\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
            image.display()
        ),
    )
    .expect("write the map YAML");
    p
}
