//! A local map for scan-to-map matching: registered scans (keyframes) in
//! the world frame, a few of them merged into one [`Reference`].
//!
//! Two ways to choose them (`icp.keyframe_store`):
//! * **sliding window** (0): the last `keyframe_window` keyframes, a new one
//!   after `keyframe_distance` of travel or `keyframe_angle` of turn. Every
//!   keyframe inherits the pose's error, and the errors add up: over 150 m
//!   of lanes in a 16 m corridor the heading drifted 0.7-1.9°.
//! * **keyframe store** (> 0): up to `keyframe_store` keyframes kept where
//!   they were taken; a new one only where none lies within
//!   `keyframe_distance` and `keyframe_angle` (new ground or a new view);
//!   the reference is the `keyframe_window` keyframes nearest the robot,
//!   chosen again as it moves. Coming back, the robot is matched against
//!   the walls it mapped first, and the error stops adding up.
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

/// How many metres of travel a radian of heading counts as when keyframes
/// are ranked by nearness: two views from one place a quarter turn apart
/// share less than two views half a metre apart.
const METRES_PER_RADIAN: f64 = 0.6;

/// Keyframes and the reference built from some of them.
#[derive(Debug)]
pub struct KeyframeMap {
    window: usize,
    /// 0: sliding window; else the most keyframes kept.
    store: usize,
    keyframes: VecDeque<Keyframe>,
    spare: Option<Keyframe>,
    /// Store mode: indices of the keyframes in the reference, ascending.
    selected: Vec<usize>,
    /// Work buffer of the selection: (nearness, index).
    ranked: Vec<(f64, usize)>,
    /// Pose the selection was last made at.
    selected_at: Option<Pose>,
    merged: Vec<IPoint>,
    merged_normals: Vec<Vector2<f64>>,
    merged_edges: Vec<bool>,
    reference: Reference,
}

impl KeyframeMap {
    /// An empty map: a sliding window of `params.keyframe_window` keyframes,
    /// or a store of `params.keyframe_store` (see the module doc).
    pub fn new(params: &IcpParams) -> Self {
        let window = params.keyframe_window.max(1);
        let store = if params.keyframe_store > 0 {
            params.keyframe_store.max(window)
        } else {
            0
        };
        Self {
            window,
            store,
            keyframes: VecDeque::with_capacity(store.max(window) + 1),
            spare: None,
            selected: Vec::with_capacity(window),
            ranked: Vec::with_capacity(store),
            selected_at: None,
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

    /// Whether a scan matched at `pose` should become a keyframe: it lies
    /// `keyframe_distance` or `keyframe_angle` from the newest keyframe
    /// (sliding window) or from every stored one (store).
    pub(crate) fn due(&self, pose: &Pose, params: &IcpParams) -> bool {
        let far = |k: &Keyframe| {
            let d = k.pose.inverse() * pose;
            d.translation.vector.norm() >= params.keyframe_distance
                || d.rotation.angle().abs() >= params.keyframe_angle
        };
        if self.store == 0 {
            self.keyframes.back().is_none_or(far)
        } else {
            self.keyframes.iter().all(far)
        }
    }

    /// Store mode: chooses the `keyframe_window` keyframes nearest `pose`
    /// and rebuilds the reference if they changed; does nothing until the
    /// robot has moved half a `keyframe_distance` (or turned half a
    /// `keyframe_angle`) since the last choice. True when it rebuilt.
    pub(crate) fn follow(&mut self, pose: &Pose, params: &IcpParams) -> Result<bool, IcpError> {
        if self.store == 0 || self.keyframes.is_empty() {
            return Ok(false);
        }
        if let Some(at) = self.selected_at {
            let d = at.inverse() * pose;
            if d.translation.vector.norm() < 0.5 * params.keyframe_distance
                && d.rotation.angle().abs() < 0.5 * params.keyframe_angle
            {
                return Ok(false);
            }
        }
        if !self.select(pose, false) {
            return Ok(false);
        }
        self.rebuild_reference(params).map(|()| true)
    }

    /// Store mode: sets `selected` to the `window` keyframes nearest `pose`;
    /// true when that changed the selection. Unless `force`d, a choice that
    /// differs from the current one in fewer than a quarter of its
    /// keyframes is not taken: each rebuild costs a k-d tree over 40
    /// keyframes (about 3 ms), and one keyframe more or less changes little.
    fn select(&mut self, pose: &Pose, force: bool) -> bool {
        self.selected_at = Some(*pose);
        self.ranked.clear();
        for (i, k) in self.keyframes.iter().enumerate() {
            let d = k.pose.inverse() * pose;
            let near = d.translation.vector.norm() + METRES_PER_RADIAN * d.rotation.angle().abs();
            self.ranked.push((near, i));
        }
        let n = self.window.min(self.ranked.len());
        if n < self.ranked.len() {
            self.ranked
                .select_nth_unstable_by(n - 1, |a, b| a.0.total_cmp(&b.0));
        }
        self.ranked.truncate(n);
        self.ranked.sort_unstable_by_key(|r| r.1);
        let new = self
            .ranked
            .iter()
            .filter(|r| self.selected.binary_search(&r.1).is_err())
            .count();
        let take = if force {
            new > 0 || self.ranked.len() != self.selected.len()
        } else {
            4 * new >= self.window.max(1) || self.selected.is_empty()
        };
        if take {
            self.selected.clear();
            self.selected.extend(self.ranked.iter().map(|r| r.1));
        }
        take
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
        let most = if self.store > 0 {
            self.store
        } else {
            self.window
        };
        let mut kf = if self.keyframes.len() >= most {
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
        if self.store > 0 {
            self.select(pose, true);
        }
        self.rebuild_reference(params)
    }

    /// Merges the chosen keyframes' points, normals and edges (every
    /// keyframe of a sliding window) into one list (the buffers are reused)
    /// and rebuilds the reference from it.
    fn rebuild_reference(&mut self, params: &IcpParams) -> Result<(), IcpError> {
        self.merged.clear();
        self.merged_normals.clear();
        self.merged_edges.clear();
        let mut add = |k: &Keyframe| {
            self.merged.extend_from_slice(&k.points);
            self.merged_normals.extend_from_slice(&k.normals);
            self.merged_edges.extend_from_slice(&k.edges);
        };
        if self.store > 0 {
            for &i in &self.selected {
                if let Some(k) = self.keyframes.get(i) {
                    add(k);
                }
            }
        } else {
            self.keyframes.iter().for_each(add);
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
    /// `keyframe_window`, or `keyframe_store`, are kept, each read up to its
    /// shortest list) and rebuilds the reference (in store mode from the
    /// keyframes nearest the newest one). On error (e.g. too few usable
    /// points) the map is left empty.
    pub fn restore(
        &mut self,
        keyframes: &[KeyframeState],
        params: &IcpParams,
    ) -> Result<(), IcpError> {
        self.clear();
        let most = if self.store > 0 {
            self.store
        } else {
            self.window
        };
        let skip = keyframes.len().saturating_sub(most);
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
        if let Some(last) = self.last_pose().filter(|_| self.store > 0) {
            self.select(&last, true);
        }
        let r = self.rebuild_reference(params);
        if r.is_err() {
            self.clear();
        }
        r
    }

    /// Store mode: takes the `keyframe_window` keyframes nearest `pose`
    /// whatever the current choice, and rebuilds the reference when the
    /// choice changed (after a relocalisation: the robot is elsewhere).
    pub(crate) fn reselect(&mut self, pose: &Pose, params: &IcpParams) -> Result<(), IcpError> {
        if self.store == 0 || self.keyframes.is_empty() || !self.select(pose, true) {
            return Ok(());
        }
        self.rebuild_reference(params)
    }

    /// Forgets the `n` newest keyframes (taken at a pose that proved
    /// wrong) and rebuilds the reference from what is left.
    pub(crate) fn drop_newest(&mut self, n: usize, params: &IcpParams) -> Result<(), IcpError> {
        let n = n.min(self.keyframes.len().saturating_sub(1));
        if n == 0 {
            return Ok(());
        }
        for _ in 0..n {
            if let Some(k) = self.keyframes.pop_back() {
                self.spare = Some(k);
            }
        }
        self.selected.clear();
        self.selected_at = None;
        if self.store == 0 {
            return self.rebuild_reference(params);
        }
        let last = self.keyframes.back().map(|k| k.pose);
        match last {
            Some(at) if self.select(&at, true) => self.rebuild_reference(params),
            _ => Ok(()),
        }
    }

    /// Forgets every keyframe (e.g. after the robot was carried away).
    pub fn clear(&mut self) {
        if let Some(k) = self.keyframes.pop_back() {
            self.spare = Some(k);
        }
        self.keyframes.clear();
        self.selected.clear();
        self.selected_at = None;
    }

    /// All keyframe points, world frame (for pictures).
    pub fn points(&self) -> impl Iterator<Item = &IPoint> {
        self.keyframes.iter().flat_map(|k| k.points.iter())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::pose;
    use crate::icp::synth::{cast_seeded, room};

    fn store_params() -> IcpParams {
        IcpParams {
            keyframe_window: 3,
            keyframe_store: 100,
            keyframe_distance: 0.3,
            ..IcpParams::default()
        }
    }

    /// Keyframes every 0.5 m along the middle of a 12 m × 3 m room.
    fn lane(params: &IcpParams) -> KeyframeMap {
        let walls = room(12.0, 3.0, 0.5);
        let mut map = KeyframeMap::new(params);
        for k in 0..20u64 {
            let at = pose(0.5 + 0.5 * k as f64, 1.5, 0.0);
            map.insert(&at, &cast_seeded(&walls, &at, k), params)
                .unwrap();
        }
        map
    }

    /// Where the reference's keyframes were taken, as the x of the scanner.
    fn chosen_x(map: &KeyframeMap) -> Vec<f64> {
        map.selected
            .iter()
            .map(|&i| map.keyframes[i].pose.translation.x)
            .collect()
    }

    #[test]
    fn a_store_keeps_every_keyframe_and_matches_against_the_nearest() {
        let params = store_params();
        let mut map = lane(&params);
        assert_eq!(map.len(), 20);
        // Just added at the far end: the three newest.
        assert_eq!(chosen_x(&map), vec![9.0, 9.5, 10.0]);
        // Back at the start: the first three, the reference rebuilt once.
        let start = pose(0.6, 1.4, 0.1);
        assert!(map.follow(&start, &params).unwrap());
        assert_eq!(chosen_x(&map), vec![0.5, 1.0, 1.5]);
        assert!(map.reference().points().iter().all(|p| p.x < 7.2));
        // A few centimetres on: no new choice, no rebuild.
        assert!(!map.follow(&pose(0.65, 1.4, 0.1), &params).unwrap());
        // Over ground it has seen, no keyframe is due; off it, one is.
        assert!(!map.due(&pose(3.1, 1.5, 0.0), &params));
        assert!(map.due(&pose(3.1, 0.5, 0.0), &params));
        assert!(map.due(&pose(3.0, 1.5, 1.0), &params));
    }

    #[test]
    fn a_sliding_window_keeps_the_newest_and_is_due_after_travel() {
        let params = IcpParams {
            keyframe_store: 0,
            ..store_params()
        };
        let mut map = lane(&params);
        assert_eq!(map.len(), 3);
        assert_eq!(map.last_pose().unwrap().translation.x, 10.0);
        assert!(!map.follow(&pose(0.6, 1.5, 0.0), &params).unwrap());
        // Due by distance from the newest keyframe alone.
        assert!(map.due(&pose(3.1, 1.5, 0.0), &params));
        assert!(!map.due(&pose(10.1, 1.5, 0.0), &params));
    }

    #[test]
    fn a_full_store_drops_its_oldest_and_a_restore_keeps_the_newest() {
        let params = IcpParams {
            keyframe_store: 8,
            ..store_params()
        };
        let map = lane(&params);
        assert_eq!(map.len(), 8);
        assert_eq!(map.keyframes[0].pose.translation.x, 6.5);
        let state = map.export();
        let mut small = KeyframeMap::new(&IcpParams {
            keyframe_store: 5,
            ..params.clone()
        });
        small
            .restore(
                &state,
                &IcpParams {
                    keyframe_store: 5,
                    ..params
                },
            )
            .unwrap();
        assert_eq!(small.len(), 5);
        assert_eq!(chosen_x(&small), vec![9.0, 9.5, 10.0]);
    }
}
