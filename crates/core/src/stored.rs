//! Compact serde forms for fields of the plain state a daemon checkpoints,
//! used with `#[serde(with = "…")]` on the state types: one bit per flag,
//! single-precision keyframe points and normal directions. The state types
//! derive `Serialize` / `Deserialize` themselves; what the values must
//! satisfy (finite numbers, lengths that agree with a grid) is checked by
//! whoever restores them, since a serde error cannot say which value was bad.

/// `Vec<bool>` as its length (u64) and a byte string of one bit per flag,
/// least significant bit first: a 400 × 400 record is 20 kB, not 160 kB.
pub mod bits {
    use serde::de::Error;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    /// Writes `flags` packed.
    pub fn serialize<S: Serializer>(flags: &[bool], s: S) -> Result<S::Ok, S::Error> {
        let mut packed = vec![0u8; flags.len().div_ceil(8)];
        for (i, _) in flags.iter().enumerate().filter(|(_, f)| **f) {
            packed[i / 8] |= 1 << (i % 8);
        }
        (flags.len() as u64, &packed[..]).serialize(s)
    }

    /// Reads flags [`serialize`] packed; the byte string must hold exactly
    /// the bits of the length given (so a hostile length allocates nothing
    /// the input does not back).
    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<bool>, D::Error> {
        let (n, packed): (u64, Vec<u8>) = Deserialize::deserialize(d)?;
        let n = usize::try_from(n).map_err(|_| D::Error::custom("flag count overflows"))?;
        if packed.len() != n.div_ceil(8) {
            return Err(D::Error::custom("flag bytes disagree with the flag count"));
        }
        Ok((0..n)
            .map(|i| packed[i / 8] & (1 << (i % 8)) != 0)
            .collect())
    }
}

/// Keyframe points (`Vec<IPoint>`, f64) as `[f32; 3]` each (x, y,
/// intensity): micrometres at 100 m, far below a scanner's centimetre noise,
/// and a 40-keyframe window half the size.
pub mod f32_points {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use crate::geom::IPoint;

    /// Writes the points in single precision.
    pub fn serialize<S: Serializer>(points: &[IPoint], s: S) -> Result<S::Ok, S::Error> {
        let v: Vec<[f32; 3]> = points
            .iter()
            .map(|p| [p.x as f32, p.y as f32, p.intensity as f32])
            .collect();
        v.serialize(s)
    }

    /// Reads points [`serialize`] wrote.
    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<IPoint>, D::Error> {
        let v: Vec<[f32; 3]> = Deserialize::deserialize(d)?;
        Ok(v.into_iter()
            .map(|[x, y, i]| IPoint::new(f64::from(x), f64::from(y), f64::from(i)))
            .collect())
    }
}

/// Unit surface normals (`Vec<Vector2<f64>>`, zero = unknown) as their
/// direction in single precision, `None` where unknown.
pub mod normal_directions {
    use nalgebra::Vector2;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    /// Writes each normal's direction (rad), `None` for a zero normal.
    pub fn serialize<S: Serializer>(normals: &[Vector2<f64>], s: S) -> Result<S::Ok, S::Error> {
        let v: Vec<Option<f32>> = normals
            .iter()
            .map(|n| (n.norm_squared() > 0.0).then(|| n.y.atan2(n.x) as f32))
            .collect();
        v.serialize(s)
    }

    /// Reads normals [`serialize`] wrote: unit vectors, zero where unknown.
    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Vec<Vector2<f64>>, D::Error> {
        let v: Vec<Option<f32>> = Deserialize::deserialize(d)?;
        Ok(v.into_iter()
            .map(|a| match a {
                Some(a) => Vector2::new(f64::from(a).cos(), f64::from(a).sin()),
                None => Vector2::zeros(),
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector2;
    use serde::{Deserialize, Serialize};

    use crate::geom::IPoint;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Flags(#[serde(with = "super::bits")] Vec<bool>);

    #[derive(Debug, Serialize, Deserialize)]
    struct Points(
        #[serde(with = "super::f32_points")] Vec<IPoint>,
        #[serde(with = "super::normal_directions")] Vec<Vector2<f64>>,
    );

    #[test]
    fn flags_pack_to_bits_and_back() {
        let f = Flags((0..21).map(|i| i % 3 == 0).collect());
        let bytes = postcard::to_allocvec(&f).unwrap();
        // length (varint 21), byte count (varint 3), three bytes.
        assert_eq!(bytes.len(), 5);
        assert_eq!(postcard::from_bytes::<Flags>(&bytes).unwrap(), f);
    }

    #[test]
    fn flags_with_the_wrong_byte_count_are_refused() {
        let bytes = postcard::to_allocvec(&(25u64, vec![0xffu8; 3])).unwrap();
        assert!(postcard::from_bytes::<Flags>(&bytes).is_err());
        let huge = postcard::to_allocvec(&(u64::MAX, vec![0u8; 1])).unwrap();
        assert!(postcard::from_bytes::<Flags>(&huge).is_err());
    }

    #[test]
    fn points_and_normals_survive_in_single_precision() {
        let p = Points(
            vec![
                IPoint::new(12.345678, -3.25, 0.7),
                IPoint::new(0.0, 1.0, 0.0),
            ],
            vec![Vector2::new(0.6, -0.8), Vector2::zeros()],
        );
        let back: Points = postcard::from_bytes(&postcard::to_allocvec(&p).unwrap()).unwrap();
        assert!((back.0[0].x - 12.345678).abs() < 1e-5);
        assert_eq!(back.0[1].y, 1.0);
        assert!((back.1[0] - Vector2::new(0.6, -0.8)).norm() < 1e-6);
        assert_eq!(back.1[1], Vector2::zeros());
    }
}
