//! The scan tracker's local map as a checkpoint section (`icp.keyframes`),
//! so a resumed daemon matches its first scans against the keyframes the
//! crashed one had, in the same frame as the restored map, instead of
//! starting a new local map whose frame carries the resume pose's error.
//!
//! Payload, version 1: [`TrackerState`] in postcard: per keyframe the
//! scanner pose (nalgebra's form: translation, unit complex rotation; f64),
//! then its points ([`sweepline_core::stored::f32_points`]: x, y in the world
//! frame and intensity as f32), their normals' directions
//! ([`sweepline_core::stored::normal_directions`]: f32, `None` where
//! unknown) and their intensity-edge flags (one bit each). At most
//! `MAX_KEYFRAMES` keyframes of at most `MAX_KEYFRAME_POINTS` points.
//! A 40-keyframe window of URG-04LX scans is near 400 kB, the default
//! room's keyframe store (some 400 keyframes) 1.9 MB
//! (micrometres at 100 m are far below the scanner's centimetre noise).

use super::checks::{checked_pose, finite};
use super::Section;
use crate::capacity::MAX_BEAMS;
use crate::icp::TrackerState;

/// Most keyframes a checkpoint may restore: as many as a local map keeps.
pub(crate) const MAX_KEYFRAMES: usize = crate::icp::MAX_KEYFRAMES;
/// Most points one keyframe may hold (one scan's beams).
pub(crate) const MAX_KEYFRAME_POINTS: usize = MAX_BEAMS;

impl Section for TrackerState {
    const NAME: &'static str = "icp.keyframes";
    const VERSION: u16 = 1;

    fn restored(mut self) -> Result<Self, String> {
        let count = self.keyframes.len();
        if count > MAX_KEYFRAMES {
            return Err(format!(
                "{count} keyframes, more than the {MAX_KEYFRAMES} allowed"
            ));
        }
        for (i, k) in self.keyframes.iter_mut().enumerate() {
            k.pose = checked_pose(&format!("keyframe {i}"), &k.pose)?;
            let n = k.points.len();
            if n > MAX_KEYFRAME_POINTS {
                return Err(format!(
                    "keyframe {i} has {n} points, more than the {MAX_KEYFRAME_POINTS} allowed"
                ));
            }
            if k.normals.len() != n || k.edges.len() != n {
                return Err(format!(
                    "keyframe {i} has {n} points but {} normals and {} edge flags",
                    k.normals.len(),
                    k.edges.len()
                ));
            }
            for (p, nv) in k.points.iter().zip(&k.normals) {
                finite(&format!("keyframe {i} point x"), p.x)?;
                finite(&format!("keyframe {i} point y"), p.y)?;
                finite(&format!("keyframe {i} point intensity"), p.intensity)?;
                finite(&format!("keyframe {i} normal direction"), nv.x + nv.y)?;
            }
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector2;

    use super::*;
    use crate::geom::{heading, pose, IPoint};
    use crate::icp::KeyframeState;
    use crate::pipeline::checkpoint::testing::{read, refusal};
    use crate::pipeline::checkpoint::Checkpoint;

    fn state() -> TrackerState {
        let kf = |x: f64, n: usize| KeyframeState {
            pose: pose(x, 0.5, 0.3),
            points: (0..n)
                .map(|i| IPoint::new(x + i as f64 * 0.01, 2.0, 0.4))
                .collect(),
            normals: (0..n)
                .map(|i| {
                    if i % 5 == 0 {
                        Vector2::zeros()
                    } else {
                        Vector2::new(0.6, -0.8)
                    }
                })
                .collect(),
            edges: (0..n).map(|i| i % 7 == 0).collect(),
        };
        TrackerState {
            keyframes: vec![kf(0.0, 50), kf(0.3, 0), kf(0.6, 70)],
        }
    }

    #[test]
    fn keyframes_survive_a_checkpoint() {
        let s = state();
        let mut cp = Checkpoint::new();
        cp.put(&s).unwrap();
        let back: TrackerState = Checkpoint::from_bytes(&cp.to_bytes())
            .unwrap()
            .require()
            .unwrap();
        assert_eq!(back.keyframes.len(), 3);
        for (a, b) in back.keyframes.iter().zip(&s.keyframes) {
            assert_eq!(a.points.len(), b.points.len());
            for (p, q) in a.points.iter().zip(&b.points) {
                assert!(
                    (p.xy() - q.xy()).norm() < 1e-6 && (p.intensity - q.intensity).abs() < 1e-6
                );
            }
            for (n, m) in a.normals.iter().zip(&b.normals) {
                assert!((n - m).norm() < 1e-6, "{n} vs {m}");
            }
            assert_eq!(a.edges, b.edges);
            assert!((a.pose.translation.vector - b.pose.translation.vector).norm() < 1e-12);
            assert!((heading(&a.pose) - heading(&b.pose)).abs() < 1e-12);
        }
    }

    #[test]
    fn hostile_payloads_are_clear_errors() {
        let bytes = crate::pipeline::checkpoint::testing::payload(&state());
        for cut in [0, 3, 4, 20, 40, 100, bytes.len() - 1] {
            assert!(read::<TrackerState>(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let many = TrackerState {
            keyframes: vec![KeyframeState::default(); MAX_KEYFRAMES + 1],
        };
        assert!(refusal(&many).contains("keyframes, more than"));
        let mut big = state();
        let k = &mut big.keyframes[0];
        k.points = vec![IPoint::new(1.0, 1.0, 0.5); MAX_KEYFRAME_POINTS + 1];
        k.normals = vec![Vector2::zeros(); MAX_KEYFRAME_POINTS + 1];
        k.edges = vec![false; MAX_KEYFRAME_POINTS + 1];
        assert!(refusal(&big).contains("more than the 1440 allowed"));
        let mut nan = state();
        nan.keyframes[2].points[3].y = f64::NAN;
        assert!(refusal(&nan).contains("keyframe 2 point y"));
        let mut far = state();
        far.keyframes[0].points[0].x = 1e300; // beyond f32: infinite when read
        assert!(refusal(&far).contains("keyframe 0 point x"));
        let mut uneven = state();
        uneven.keyframes[0].edges.pop();
        assert!(refusal(&uneven).contains("50 points but 50 normals and 49 edge flags"));
        let mut turned = state();
        turned.keyframes[1].pose.translation.x = f64::INFINITY;
        assert!(refusal(&turned).contains("keyframe 1 x"));
        // A keyframe count the bytes cannot back allocates nothing.
        assert!(read::<TrackerState>(&[0xff, 0xff, 0xff, 0xff, 0x0f]).is_err());
    }
}
