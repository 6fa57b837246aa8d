//! A local map for scan-to-map matching: the last few registered scans
//! (keyframes) in the world frame, merged into one [`Reference`].
//!
//! Keyframe storage is recycled (the oldest keyframe's buffers take the
//! newest one's points), so only the k-d tree build allocates, once per new
//! keyframe. The mapping layer's point map can replace this: any `&[IPoint]`
//! can be a [`Reference`].

use std::collections::VecDeque;

use nalgebra::Vector2;

use super::reference::{edge_after, ordered_normal};
use super::{IcpError, IcpParams, Reference};
use crate::capacity::MAX_BEAMS;
use crate::geom::{IPoint, Pose};

/// One registered scan in the world frame.
#[derive(Clone, Debug, Default)]
struct Keyframe {
    pose: Pose,
    points: Vec<IPoint>,
    normals: Vec<Vector2<f64>>,
    edges: Vec<bool>,
}

/// One keyframe as plain data, for a checkpoint: the scanner pose it was
/// taken from and its points in the world frame, with their surface normals
/// (world frame; zero = unknown) and intensity-edge flags, index for index.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KeyframeState {
    /// Scanner pose of the keyframe (world frame).
    pub pose: Pose,
    /// Points, world frame (stored in single precision).
    #[serde(with = "crate::stored::f32_points")]
    pub points: Vec<IPoint>,
    /// Unit surface normal of each point (world frame), zero when unknown
    /// (stored as a single-precision direction).
    #[serde(with = "crate::stored::normal_directions")]
    pub normals: Vec<Vector2<f64>>,
    /// Whether an intensity edge lies between each point and the next one.
    #[serde(with = "crate::stored::bits")]
    pub edges: Vec<bool>,
}

/// A sliding window of keyframes and the reference built from them.
#[derive(Debug)]
pub struct KeyframeMap {
    window: usize,
    keyframes: VecDeque<Keyframe>,
    spare: Option<Keyframe>,
    merged: Vec<IPoint>,
    merged_normals: Vec<Vector2<f64>>,
    merged_edges: Vec<bool>,
    reference: Reference,
}

impl KeyframeMap {
    /// An empty map keeping at most `params.keyframe_window` keyframes.
    pub fn new(params: &IcpParams) -> Self {
        let window = params.keyframe_window.max(1);
        Self {
            window,
            keyframes: VecDeque::with_capacity(window + 1),
            spare: None,
            merged: Vec::with_capacity(window * MAX_BEAMS),
            merged_normals: Vec::with_capacity(window * MAX_BEAMS),
            merged_edges: Vec::with_capacity(window * MAX_BEAMS),
            reference: Reference::new(),
        }
    }

    /// Number of keyframes held.
    pub fn len(&self) -> usize {
        self.keyframes.len()
    }

    /// True before the first keyframe.
    pub fn is_empty(&self) -> bool {
        self.keyframes.is_empty()
    }

    /// The pose of the newest keyframe.
    pub fn last_pose(&self) -> Option<Pose> {
        self.keyframes.back().map(|k| k.pose)
    }

    /// The reference to match against (all keyframes merged).
    pub fn reference(&self) -> &Reference {
        &self.reference
    }

    /// Adds a scan (sensor frame points, in beam order) seen from `pose` and
    /// rebuilds the reference. Normals are estimated per scan from beam-order
    /// neighbours. Drops the oldest keyframe beyond the window.
    pub fn insert(
        &mut self,
        pose: &Pose,
        points: &[IPoint],
        params: &IcpParams,
    ) -> Result<(), IcpError> {
        let mut kf = if self.keyframes.len() >= self.window {
            self.keyframes.pop_front().unwrap_or_default()
        } else {
            self.spare.take().unwrap_or_default()
        };
        kf.pose = *pose;
        kf.points.clear();
        kf.normals.clear();
        kf.edges.clear();
        let rot = pose.rotation;
        for (i, p) in points.iter().enumerate() {
            let n = ordered_normal(points, i, params);
            kf.points.push(p.transformed(pose));
            kf.normals.push(rot * n);
            kf.edges.push(edge_after(points, i, params).is_some());
        }
        self.keyframes.push_back(kf);
        self.rebuild_reference(params)
    }

    /// Merges every keyframe's points, normals and edges into one list (the
    /// buffers are reused) and rebuilds the reference from it.
    fn rebuild_reference(&mut self, params: &IcpParams) -> Result<(), IcpError> {
        self.merged.clear();
        self.merged_normals.clear();
        self.merged_edges.clear();
        for k in &self.keyframes {
            self.merged.extend_from_slice(&k.points);
            self.merged_normals.extend_from_slice(&k.normals);
            self.merged_edges.extend_from_slice(&k.edges);
        }
        self.reference.rebuild_with_normals(
            &self.merged,
            &self.merged_normals,
            &self.merged_edges,
            params,
        )
    }

    /// The keyframes, oldest first, as plain data (allocates: for
    /// checkpoints, once per new keyframe at most).
    pub(crate) fn export(&self) -> Vec<KeyframeState> {
        self.keyframes
            .iter()
            .map(|k| KeyframeState {
                pose: k.pose,
                points: k.points.clone(),
                normals: k.normals.clone(),
                edges: k.edges.clone(),
            })
            .collect()
    }

    /// Replaces the keyframes by `keyframes` (oldest first; only the newest
    /// `keyframe_window` are kept, each read up to its shortest list) and
    /// rebuilds the reference. On error (e.g. too few usable points) the
    /// map is left empty.
    pub fn restore(
        &mut self,
        keyframes: &[KeyframeState],
        params: &IcpParams,
    ) -> Result<(), IcpError> {
        self.clear();
        let skip = keyframes.len().saturating_sub(self.window);
        for k in &keyframes[skip..] {
            let n = k.points.len().min(k.normals.len()).min(k.edges.len());
            let mut kf = self.spare.take().unwrap_or_default();
            kf.pose = k.pose;
            kf.points.clear();
            kf.points.extend_from_slice(&k.points[..n]);
            kf.normals.clear();
            kf.normals.extend_from_slice(&k.normals[..n]);
            kf.edges.clear();
            kf.edges.extend_from_slice(&k.edges[..n]);
            self.keyframes.push_back(kf);
        }
        let r = self.rebuild_reference(params);
        if r.is_err() {
            self.clear();
        }
        r
    }

    /// Forgets every keyframe (e.g. after the robot was carried away).
    pub fn clear(&mut self) {
        if let Some(k) = self.keyframes.pop_back() {
            self.spare = Some(k);
        }
        self.keyframes.clear();
    }

    /// All keyframe points, world frame (for pictures).
    pub fn points(&self) -> impl Iterator<Item = &IPoint> {
        self.keyframes.iter().flat_map(|k| k.points.iter())
    }
}
