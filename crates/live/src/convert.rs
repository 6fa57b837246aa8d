//! sweepline's types as Foxglove's well-known messages.

use foxglove::schemas::{
    packed_element_field::NumericType, Color, Grid, LinePrimitive, PackedElementField, Point3,
    Pose as FgPose, Quaternion, SceneEntity, Timestamp, Vector2, Vector3,
};

use crate::decomp::{CellStatus, Decomposition};
use crate::geom::Pose;

/// A timestamp from nanoseconds since the Unix epoch.
pub(crate) fn timestamp(ns: u64) -> Timestamp {
    Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
}

/// A planar pose as a 3D one (z = 0, turned about z).
pub(crate) fn pose(p: &Pose) -> FgPose {
    let (x, y) = (p.translation.vector.x, p.translation.vector.y);
    let h = p.rotation.angle() * 0.5;
    FgPose {
        position: Some(Vector3 { x, y, z: 0.0 }),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: h.sin(),
            w: h.cos(),
        }),
    }
}

/// A grid of one byte per cell, rows from the origin up.
pub(crate) fn grid(
    ns: u64,
    origin: nalgebra::Point2<f64>,
    resolution: f64,
    width: usize,
    field: &str,
    kind: NumericType,
    data: Vec<u8>,
) -> Grid {
    Grid {
        timestamp: Some(timestamp(ns)),
        frame_id: "map".into(),
        pose: Some(pose(&crate::geom::pose(origin.x, origin.y, 0.0))),
        column_count: width as u32,
        cell_size: Some(Vector2 {
            x: resolution,
            y: resolution,
        }),
        row_stride: width as u32,
        cell_stride: 1,
        fields: vec![PackedElementField {
            name: field.into(),
            offset: 0,
            r#type: kind as i32,
        }],
        data: data.into(),
    }
}

/// The evidence grid as ROS-style occupancy: −1 unknown, else 0-100.
pub(crate) fn occupancy(g: &crate::grid::Grid, out: &mut Vec<u8>) {
    out.clear();
    out.extend(g.raw_evidence().iter().map(|&v| {
        if v == 0 {
            -1i8 as u8
        } else {
            ((u32::from(v) * 100 + 127) / 255) as u8
        }
    }));
}

fn colour(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

fn point(p: &nalgebra::Point2<f64>) -> Point3 {
    Point3 {
        x: p.x,
        y: p.y,
        z: 0.0,
    }
}

/// A closed outline or an open polyline on the floor.
fn line(points: &[nalgebra::Point2<f64>], closed: bool, width: f64, c: Color) -> LinePrimitive {
    use foxglove::schemas::line_primitive::Type;
    LinePrimitive {
        r#type: if closed {
            Type::LineLoop
        } else {
            Type::LineStrip
        } as i32,
        pose: Some(pose(&Pose::identity())),
        thickness: width,
        scale_invariant: false,
        points: points.iter().map(point).collect(),
        color: Some(c),
        colors: Vec::new(),
        indices: Vec::new(),
    }
}

/// One entity per cell, outlined in the colour of its state (open: grey,
/// settling: amber, final: green).
pub(crate) fn cells(ns: u64, d: &Decomposition) -> Vec<SceneEntity> {
    d.cells
        .iter()
        .map(|c| {
            let col = match c.status {
                CellStatus::Open => colour(0.6, 0.6, 0.6, 0.8),
                CellStatus::Settling => colour(0.95, 0.65, 0.1, 0.9),
                CellStatus::Final => colour(0.2, 0.7, 0.3, 0.9),
            };
            SceneEntity {
                timestamp: Some(timestamp(ns)),
                frame_id: "map".into(),
                id: format!("cell/{}", c.id.0),
                lines: vec![line(&c.polygon, true, 0.02, col)],
                ..Default::default()
            }
        })
        .collect()
}

/// The planned path as one entity.
pub(crate) fn path(ns: u64, points: &[nalgebra::Point2<f64>]) -> SceneEntity {
    SceneEntity {
        timestamp: Some(timestamp(ns)),
        frame_id: "map".into(),
        id: "path".into(),
        lines: vec![line(points, false, 0.015, colour(0.15, 0.4, 0.95, 1.0))],
        ..Default::default()
    }
}
