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
    crc32, Checkpoint, CheckpointError, ContactArc, ContactArcs, MountRecord, RunProgress,
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

/// A `grid` payload: origin (0, 0), cell size `res`, `w` × `h` cells and
/// the evidence bytes given.
fn grid(res: f64, w: u32, h: u32, cells: &[u8]) -> Vec<u8> {
    postcard::to_allocvec(&((0.0f64, 0.0f64), res, u64::from(w), u64::from(h), cells)).unwrap()
}

/// A `grid` payload whose evidence claims `n` bytes and holds none.
fn grid_claiming(res: f64, w: u32, h: u32, n: u64) -> Vec<u8> {
    let mut b =
        postcard::to_allocvec(&((0.0f64, 0.0f64), res, u64::from(w), u64::from(h))).unwrap();
    b.extend_from_slice(&postcard::to_allocvec(&n).unwrap());
    b
}

#[test]
fn hostile_files_give_clear_errors() {
    let pose_payload = postcard::to_allocvec(&pose(1.0, 2.0, 0.5)).unwrap();
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
            craft(&[(b"pose", 1, &pose_payload, Some(u64::MAX))], None),
            "claims",
        ),
        (
            craft(&[(b"pose", 1, &pose_payload, Some(1 << 40))], None),
            "claims",
        ),
        (craft(&[(b"", 1, &[], None)], None), "name length of 0"),
        (
            craft(&[(b"Pose!", 1, &pose_payload, None)], None),
            "invalid name",
        ),
        (
            craft(&[(&[0xff, 0xfe], 1, &pose_payload, None)], None),
            "invalid name",
        ),
        (
            craft(
                &[
                    (b"pose", 1, &pose_payload, None),
                    (b"pose", 1, &pose_payload, None),
                ],
                None,
            ),
            "appears twice",
        ),
        (
            craft(&[(b"pose", 1, &pose_payload[..31], None)], None),
            "section `pose` is malformed",
        ),
        (
            craft(
                &[(b"pose", 1, &[&pose_payload[..], &[0]].concat(), None)],
                None,
            ),
            "trailing bytes",
        ),
        (
            craft(
                &[(
                    b"pose",
                    1,
                    &postcard::to_allocvec(&((1.0f64, 0.0f64), (f64::NAN, 0.0f64))).unwrap(),
                    None,
                )],
                None,
            ),
            "pose x is not a finite number",
        ),
        (
            craft(
                &[(
                    b"pose",
                    1,
                    &postcard::to_allocvec(&((2.0f64, 0.0f64), (0.0f64, 0.0f64))).unwrap(),
                    None,
                )],
                None,
            ),
            "not a unit complex number",
        ),
        (
            craft(&[(b"pose", 7, &pose_payload, None)], None),
            "has version 7",
        ),
        (
            craft(
                &[(b"grid", 1, &grid(0.1, u32::MAX, u32::MAX, &[]), None)],
                None,
            ),
            "more than the",
        ),
        (
            // A cell count far beyond the bytes present allocates nothing.
            craft(
                &[(b"grid", 1, &grid_claiming(0.1, 4, 4, u64::MAX), None)],
                None,
            ),
            "section `grid` is malformed",
        ),
        (
            craft(&[(b"grid", 1, &grid(-0.1, 4, 4, &[0; 16]), None)], None),
            "cell size -0.1 is not > 0",
        ),
        (
            craft(&[(b"grid", 1, &grid(0.1, 4, 4, &[0; 15]), None)], None),
            "15 cell value flags for a 4 x 4 grid",
        ),
        (
            {
                let mut b = sample().to_bytes();
                b[8] = 1;
                b[9] = 0;
                let n = b.len() - 4;
                let c = crc32(&b[..n]);
                b[n..].copy_from_slice(&c.to_le_bytes());
                b
            },
            "written by a sweepline from before 2026-12-02",
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
    // more points than a scan has, a NaN point.
    let kf = |count: usize, points: Vec<[f32; 3]>| {
        let one = (
            ((1.0f64, 0.0f64), (0.5f64, 0.5f64)),
            points.clone(),
            vec![None::<f32>; points.len()],
            (points.len() as u64, vec![0u8; points.len().div_ceil(8)]),
        );
        postcard::to_allocvec(&vec![one; count]).unwrap()
    };
    let ok_point = [1.0f32, 1.0, 0.5];
    let mut claims = kf(1, vec![ok_point]);
    claims.truncate(claims.len() - 4);
    let hostile_kf: Vec<(Vec<u8>, &str)> = vec![
        (kf(4097, vec![]), "more than the 4096 allowed"),
        (claims, "icp.keyframes` is malformed"),
        (kf(1, vec![ok_point; 1441]), "more than the 1440 allowed"),
        (kf(1, vec![[1.0, f32::NAN, 0.5]]), "point y"),
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
