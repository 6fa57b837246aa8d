//! The scanner mount the daemon refitted from its checks
//! ([`MountRecord`]) as checkpoint section `robot.mount`, so that a run
//! resumed after a crash drives with it at once instead of with the
//! configured one until its own checks refit it again.
//!
//! Payload, version 1: [`MountRecord`] in postcard: the mount configured
//! when it was refitted, then the refitted mount; each a pose in
//! nalgebra's form (x, y in m, robot frame; unit complex rotation), f64.

use serde::{Deserialize, Serialize};

use super::checks::checked_pose;
use super::Section;
use crate::geom::Pose;

/// A refitted scanner mount and the configured one it replaced.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MountRecord {
    /// The mount `[robot]` configured when the checks refitted it.
    pub configured: Pose,
    /// The mount the checks fitted.
    pub refitted: Pose,
}

/// Largest mount offset accepted (m): a scanner on the robot.
const MAX_OFFSET: f64 = 2.0;

impl Section for MountRecord {
    const NAME: &'static str = "robot.mount";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        let mount = |what: &str, m: &Pose| -> Result<Pose, String> {
            let m = checked_pose(what, m)?;
            let (x, y) = (m.translation.x, m.translation.y);
            if x.abs() > MAX_OFFSET || y.abs() > MAX_OFFSET {
                return Err(format!(
                    "{what}: offset ({x}, {y}) m is beyond {MAX_OFFSET} m"
                ));
            }
            Ok(m)
        };
        Ok(Self {
            configured: mount("configured mount", &self.configured)?,
            refitted: mount("refitted mount", &self.refitted)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{heading, pose};
    use crate::pipeline::checkpoint::Checkpoint;

    #[test]
    fn a_refitted_mount_survives_a_checkpoint_and_bad_values_are_refused() {
        let rec = MountRecord {
            configured: pose(0.0, 0.0, 0.0),
            refitted: pose(0.079, 0.04, 0.052),
        };
        let mut cp = Checkpoint::new();
        cp.put(&rec).unwrap();
        let back: MountRecord = Checkpoint::from_bytes(&cp.to_bytes())
            .unwrap()
            .get()
            .unwrap()
            .unwrap();
        assert!(
            (back.refitted.translation.vector - rec.refitted.translation.vector).norm() < 1e-12
        );
        assert!((heading(&back.refitted) - 0.052).abs() < 1e-12);
        assert_eq!(back.configured, rec.configured);
        for bad in [
            MountRecord {
                refitted: pose(3.0, 0.0, 0.0),
                ..rec
            },
            MountRecord {
                configured: pose(f64::NAN, 0.0, 0.0),
                ..rec
            },
        ] {
            // Refused on the way in (put checks by decoding) as on the way out.
            let e = Checkpoint::new().put(&bad).unwrap_err();
            assert!(e.to_string().contains("mount"), "{e}");
        }
    }
}
