//! The scan tracker's local map as a checkpoint section (`icp.keyframes`),
//! so a resumed daemon matches its first scans against the keyframes the
//! crashed one had, in the same frame as the restored map, instead of
//! starting a new local map whose frame carries the resume pose's error.
//!
//! Payload, version 1 (little-endian): keyframe count u32 (at most
//! [`MAX_KEYFRAMES`]); per keyframe the scanner pose (x, y, heading: f64),
//! the point count u64 (at most [`MAX_KEYFRAME_POINTS`]) and per point x, y
//! (world frame, m), intensity and the surface normal's direction (rad), all
//! f32 and finite, then a flag byte: bit 0 intensity edge, bit 1 normal
//! known (a zero normal otherwise); other bits must be clear. Singles keep
//! a 40-keyframe window of URG-04LX scans near 400 kB (micrometres at 100 m
//! are far below the scanner's centimetre noise).

use nalgebra::Vector2;

use super::{CheckpointError, Decoder, Encoder, Section};
use crate::capacity::MAX_BEAMS;
use crate::geom::{heading, pose, IPoint};
use crate::icp::{KeyframeState, TrackerState};

/// Most keyframes a checkpoint may restore.
pub const MAX_KEYFRAMES: usize = 64;
/// Most points one keyframe may hold (one scan's beams).
pub const MAX_KEYFRAME_POINTS: usize = MAX_BEAMS;
/// Bytes of one encoded point.
const POINT_BYTES: usize = 4 * 4 + 1;
/// Flag bit: the point is on an intensity edge.
const EDGE: u8 = 1;
/// Flag bit: the point's normal is known.
const NORMAL: u8 = 2;

impl Section for TrackerState {
    const NAME: &'static str = "icp.keyframes";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        e.u32(self.keyframes.len() as u32);
        for k in &self.keyframes {
            e.f64(k.pose.translation.x);
            e.f64(k.pose.translation.y);
            e.f64(heading(&k.pose));
            let n = k.points.len().min(k.normals.len()).min(k.edges.len());
            e.len(n);
            for i in 0..n {
                let (p, nv) = (&k.points[i], &k.normals[i]);
                let known = nv.norm_squared() > 0.0;
                e.f32(p.x);
                e.f32(p.y);
                e.f32(p.intensity);
                e.f32(if known { nv.y.atan2(nv.x) } else { 0.0 });
                e.u8((u8::from(k.edges[i]) * EDGE) | (u8::from(known) * NORMAL));
            }
        }
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let count = d.u32()? as usize;
        if count > MAX_KEYFRAMES {
            return Err(d.error(format!(
                "{count} keyframes, more than the {MAX_KEYFRAMES} allowed"
            )));
        }
        let mut keyframes = Vec::with_capacity(count.min(d.remaining() / 32));
        for _ in 0..count {
            let x = d.finite("keyframe x")?;
            let y = d.finite("keyframe y")?;
            let theta = d.finite("keyframe heading")?;
            let n = d.len(POINT_BYTES)?;
            if n > MAX_KEYFRAME_POINTS {
                return Err(d.error(format!(
                    "a keyframe of {n} points, more than the {MAX_KEYFRAME_POINTS} allowed"
                )));
            }
            let mut k = KeyframeState {
                pose: pose(x, y, theta),
                points: Vec::with_capacity(n),
                normals: Vec::with_capacity(n),
                edges: Vec::with_capacity(n),
            };
            for _ in 0..n {
                let px = d.finite_f32("point x")?;
                let py = d.finite_f32("point y")?;
                let pi = d.finite_f32("point intensity")?;
                let a = d.finite_f32("normal direction")?;
                let flags = d.u8()?;
                if flags & !(EDGE | NORMAL) != 0 {
                    return Err(d.error(format!("point flags {flags:#04x} have unknown bits")));
                }
                k.points.push(IPoint::new(px, py, pi));
                k.normals.push(if flags & NORMAL != 0 {
                    Vector2::new(a.cos(), a.sin())
                } else {
                    Vector2::zeros()
                });
                k.edges.push(flags & EDGE != 0);
            }
            keyframes.push(k);
        }
        Ok(Self { keyframes })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
        let mut e = Encoder::new();
        state().encode(&mut e);
        let bytes = e.into_bytes();
        for cut in [0, 3, 4, 20, 40, 100, bytes.len() - 1] {
            let r = TrackerState::decode(&mut Decoder::new(TrackerState::NAME, &bytes[..cut]));
            assert!(r.is_err(), "cut at {cut}");
        }
        let err = |b: &[u8]| {
            TrackerState::decode(&mut Decoder::new(TrackerState::NAME, b))
                .unwrap_err()
                .to_string()
        };
        let mut e = Encoder::new();
        e.u32(65);
        assert!(err(&e.into_bytes()).contains("keyframes, more than"));
        let mut e = Encoder::new();
        e.u32(1);
        e.f64(0.0);
        e.f64(0.0);
        e.f64(0.0);
        e.u64(u64::MAX);
        assert!(err(&e.into_bytes()).contains("cannot fit"));
        let mut e = Encoder::new();
        e.u32(1);
        e.f64(0.0);
        e.f64(f64::NAN);
        assert!(err(&e.into_bytes()).contains("keyframe y"));
        let mut e = Encoder::new();
        e.u32(1);
        for _ in 0..3 {
            e.f64(0.0);
        }
        e.u64(1);
        for _ in 0..4 {
            e.f32(0.0);
        }
        e.u8(4);
        assert!(err(&e.into_bytes()).contains("unknown bits"));
    }
}
