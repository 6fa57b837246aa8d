//! Fuzz-style tests of the checkpoint reader: every truncation, every bit
//! flip, random bytes, random mutations, and hand-crafted hostile files with
//! valid checksums (huge lengths, overflowing grid sizes, NaN, bad names).
//! Each must give a clear error and never panic or allocate what a length
//! field claims.

use nalgebra::Point2;
use nalgebra::Vector2;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sweepline::geom::{pose, IPoint, Pose};
use sweepline::grid::Grid;
use sweepline::icp::{KeyframeState, TrackerState};
use sweepline::pipeline::checkpoint::{
    crc32, Checkpoint, CheckpointError, ContactArc, ContactArcs, Encoder, MountRecord, RunProgress,
    TriedPlaces, WrittenAt, FORMAT_VERSION, MAGIC,
};
use sweepline::plan::cspace::Frame;
use sweepline::plan::{LatticePhase, PlanTries, SweptFloor, TriedCell};

/// Two small keyframes: enough to cover every field, small enough that the
/// every-bit-flip test stays quick.
fn keyframes() -> TrackerState {
    let kf = |x: f64| KeyframeState {
        pose: pose(x, 0.2, 0.1),
        points: (0..4)
            .map(|i| IPoint::new(x, f64::from(i) * 0.1, 0.5))
            .collect(),
        normals: vec![Vector2::new(1.0, 0.0); 4],
        edges: vec![false, true, false, false],
    };
    TrackerState {
        keyframes: vec![kf(1.0), kf(1.5)],
    }
}

fn sample() -> Checkpoint {
    let mut g = Grid::new(Point2::new(0.0, 0.0), 0.1, 12, 9);
    g.integrate_ray(&Point2::new(0.05, 0.05), &Point2::new(0.9, 0.6), true);
    let mut cp = Checkpoint::new();
    cp.put(&pose(1.0, 2.0, 0.5)).unwrap();
    cp.put(&g).unwrap();
    cp.put(&RunProgress {
        sequence: 7,
        elapsed: 30.0,
        coverage: 0.4,
        scans: 300,
        path_length: 12.0,
        resumes: 1,
    })
    .unwrap();
    cp.put(&WrittenAt { unix: 1.8e9 }).unwrap();
    cp.put(&SweptFloor {
        frame: Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.1,
            w: 5,
            h: 3,
        },
        covered: (0..15).map(|i| i % 4 == 0).collect(),
    })
    .unwrap();
    cp.put(&LatticePhase {
        x: Some(0.335),
        y: None,
    })
    .unwrap();
    cp.put(&PlanTries {
        frame: Frame {
            origin: Point2::new(0.0, 0.0),
            res: 0.1,
            w: 5,
            h: 3,
        },
        cells: vec![TriedCell {
            index: 7,
            tries: 2,
            abandoned: true,
            given_up: false,
        }],
        retried: true,
    })
    .unwrap();
    cp.put(&keyframes()).unwrap();
    cp.put(&ContactArcs {
        arcs: vec![ContactArc {
            centre: Point2::new(1.0, 2.0),
            at: Point2::new(1.18, 2.0),
            half_length: 0.02,
        }],
    })
    .unwrap();
    cp
}

/// Parses and, when the container is accepted, decodes every known section:
/// the full reader path a restarting daemon takes.
fn read_all(bytes: &[u8]) -> Result<(), CheckpointError> {
    let cp = Checkpoint::from_bytes(bytes)?;
    cp.get::<Pose>()?;
    cp.get::<Grid>()?;
    cp.get::<RunProgress>()?;
    cp.get::<WrittenAt>()?;
    cp.get::<SweptFloor>()?;
    cp.get::<LatticePhase>()?;
    cp.get::<PlanTries>()?;
    cp.get::<TrackerState>()?;
    cp.get::<ContactArcs>()?;
    cp.get::<TriedPlaces>()?;
    cp.get::<MountRecord>()?;
    Ok(())
}

/// One hand-made section: name bytes, version, payload, and a length field
/// to write instead of the payload's real length.
type RawSection<'a> = (&'a [u8], u16, &'a [u8], Option<u64>);

/// A container built by hand with correct checksums around arbitrary sections.
fn craft(sections: &[RawSection<'_>], count: Option<u32>) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out.extend_from_slice(&count.unwrap_or(sections.len() as u32).to_le_bytes());
    for (name, ver, payload, len) in sections {
        out.push(name.len() as u8);
        out.extend_from_slice(name);
        out.extend_from_slice(&ver.to_le_bytes());
        out.extend_from_slice(&len.unwrap_or(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(payload);
        out.extend_from_slice(&crc32(payload).to_le_bytes());
    }
    let c = crc32(&out);
    out.extend_from_slice(&c.to_le_bytes());
    out
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = sample().to_bytes();
    assert!(read_all(&bytes).is_ok());
    for n in 0..bytes.len() {
        let e = read_all(&bytes[..n]).expect_err("a truncated checkpoint must be rejected");
        let msg = e.to_string();
        assert!(
            msg.contains("truncated") || msg.contains("corrupted"),
            "at {n}: {msg}"
        );
    }
}

#[test]
fn every_bit_flip_is_an_error() {
    let bytes = sample().to_bytes();
    for i in 0..bytes.len() {
        for bit in 0..8 {
            let mut b = bytes.clone();
            b[i] ^= 1 << bit;
            assert!(
                read_all(&b).is_err(),
                "flip of bit {bit} in byte {i} accepted"
            );
        }
    }
}

#[test]
fn random_bytes_are_rejected() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    for round in 0..3000 {
        let len = rng.random_range(0..2048);
        let mut b: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        if round % 2 == 0 && b.len() >= 16 {
            // Give half of them a plausible header so the deeper checks run.
            b[..8].copy_from_slice(MAGIC);
            b[8..10].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        }
        assert!(read_all(&b).is_err());
    }
}

#[test]
fn random_payloads_with_valid_checksums_never_panic() {
    // The checksum guards against accidents, not against a hostile writer:
    // section decoders must hold on their own.
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    for _ in 0..3000 {
        let len = rng.random_range(0..96);
        let payload: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        for name in [
            &b"pose"[..],
            b"grid",
            b"progress",
            b"written",
            b"plan.swept",
            b"plan.lattice",
            b"plan.tries",
            b"icp.keyframes",
            b"daemon.contacts",
            b"daemon.contacts_tried",
            b"robot.mount",
        ] {
            let b = craft(&[(name, 1, &payload, None)], None);
            let _ = read_all(&b); // Ok or Err, never a panic
        }
    }
}

#[test]
fn hostile_files_give_clear_errors() {
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"PK\x03\x04 a zip file".to_vec(), "bad magic"),
        (MAGIC[..5].to_vec(), "truncated"),
        (
            {
                let mut b = sample().to_bytes();
                b[8] = 9;
                b
            },
            "format version 9",
        ),
        (craft(&[], Some(u32::MAX)), "more than the 256 allowed"),
        (craft(&[], Some(3)), "truncated"),
        (
            craft(&[(b"pose", 1, &[0; 24], Some(u64::MAX))], None),
            "claims",
        ),
        (
            craft(&[(b"pose", 1, &[0; 24], Some(1 << 40))], None),
            "claims",
        ),
        (craft(&[(b"", 1, &[], None)], None), "name length of 0"),
        (
            craft(&[(b"Pose!", 1, &[0; 24], None)], None),
            "invalid name",
        ),
        (
            craft(&[(&[0xff, 0xfe], 1, &[0; 24], None)], None),
            "invalid name",
        ),
        (
            craft(
                &[(b"pose", 1, &[0; 24], None), (b"pose", 1, &[0; 24], None)],
                None,
            ),
            "appears twice",
        ),
        (
            craft(&[(b"pose", 1, &[0; 23], None)], None),
            "section `pose` is malformed",
        ),
        (
            craft(&[(b"pose", 1, &[0; 25], None)], None),
            "trailing bytes",
        ),
        (
            craft(
                &[(
                    b"pose",
                    1,
                    &[f64::NAN.to_le_bytes(), [0; 8], [0; 8]].concat(),
                    None,
                )],
                None,
            ),
            "x is not a finite number",
        ),
        (
            craft(&[(b"pose", 7, &[0; 24], None)], None),
            "has version 7",
        ),
        (
            {
                let mut p = Vec::new();
                for v in [0.0f64, 0.0, 0.1] {
                    p.extend_from_slice(&v.to_le_bytes());
                }
                p.extend_from_slice(&u32::MAX.to_le_bytes());
                p.extend_from_slice(&u32::MAX.to_le_bytes());
                p.extend_from_slice(&0u64.to_le_bytes());
                craft(&[(b"grid", 1, &p, None)], None)
            },
            "more than the",
        ),
        (
            {
                let mut p = Vec::new();
                for v in [0.0f64, 0.0, 0.1] {
                    p.extend_from_slice(&v.to_le_bytes());
                }
                p.extend_from_slice(&4u32.to_le_bytes());
                p.extend_from_slice(&4u32.to_le_bytes());
                p.extend_from_slice(&u64::MAX.to_le_bytes());
                craft(&[(b"grid", 1, &p, None)], None)
            },
            "only 0 left",
        ),
        (
            {
                let mut p = Vec::new();
                for v in [0.0f64, 0.0, -0.1] {
                    p.extend_from_slice(&v.to_le_bytes());
                }
                craft(&[(b"grid", 1, &p, None)], None)
            },
            "resolution -0.1 is not > 0",
        ),
        (
            {
                let mut b = craft(&[], None);
                let n = b.len();
                b.insert(n - 4, 0);
                b
            },
            "corrupted",
        ),
        (
            {
                let mut b = craft(&[], None);
                b[10] = 1;
                let n = b.len() - 4;
                let c = crc32(&b[..n]);
                b[n..].copy_from_slice(&c.to_le_bytes());
                b
            },
            "unknown flags",
        ),
    ];
    // Keyframes: too many, a point count larger than the bytes present,
    // more points than a scan has, a NaN point, an edge flag that is no bool.
    let kf = |count: u32, points: u64, point: &[f64], flag: u8| {
        let mut e = Encoder::new();
        e.u32(count);
        for v in [0.5, 0.5, 0.0] {
            e.f64(v);
        }
        e.u64(points);
        for v in point {
            e.f32(*v);
        }
        e.u8(flag);
        e.into_bytes()
    };
    let ok_point = [1.0, 1.0, 0.5, 0.3];
    let big = {
        let mut e = Encoder::new();
        e.u32(1);
        for v in [0.5, 0.5, 0.0] {
            e.f64(v);
        }
        e.u64(2000);
        for _ in 0..2000 {
            for v in ok_point {
                e.f32(v);
            }
            e.u8(0);
        }
        e.into_bytes()
    };
    let hostile_kf: Vec<(Vec<u8>, &str)> = vec![
        (kf(1_000_000, 1, &ok_point, 0), "more than the 64 allowed"),
        (kf(1, u64::MAX / 2, &ok_point, 0), "cannot fit"),
        (big, "more than the 1440 allowed"),
        (kf(1, 1, &[1.0, f64::NAN, 0.5, 0.0], 0), "point y"),
        (
            kf(1, 1, &[1.0, 1.0, 0.5, f64::INFINITY], 2),
            "normal direction",
        ),
        (kf(1, 1, &ok_point, 7), "unknown bits"),
        (kf(2, 1, &ok_point, 0), "ends early"),
    ];
    for (payload, want) in hostile_kf {
        let b = craft(&[(b"icp.keyframes", 1, &payload, None)], None);
        let e = read_all(&b).expect_err(want);
        assert!(e.to_string().contains(want), "want {want:?}, got: {e}");
        assert!(e.to_string().contains("icp.keyframes"), "{e}");
    }
    let newer = craft(&[(b"icp.keyframes", 2, &[], None)], None);
    let e = read_all(&newer).expect_err("version 2");
    assert!(e.to_string().contains("has version 2"), "{e}");

    for (bytes, want) in cases {
        let e = read_all(&bytes).expect_err(want);
        assert!(e.to_string().contains(want), "want {want:?}, got: {e}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn mutated_checkpoints_never_panic(
        ops in proptest::collection::vec((any::<u16>(), any::<u8>(), 0u8..4), 1..8)
    ) {
        let mut b = sample().to_bytes();
        for (pos, val, kind) in ops {
            if b.is_empty() {
                break;
            }
            let i = pos as usize % b.len();
            match kind {
                0 => b[i] = val,
                1 => { b.remove(i); }
                2 => b.insert(i, val),
                _ => b.truncate(i),
            }
        }
        let _ = read_all(&b);
    }
}
