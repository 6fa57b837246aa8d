//! Trajectory evaluation with the relative-pose metric of Kümmerle et al.
//! 2009 ("On measuring the accuracy of SLAM algorithms"): for each relation
//! (t1, t2, true relative pose), the estimated relative pose inv(P(t1))·P(t2)
//! is compared component-wise with the true one (angle wrapped).
//!
//! Relations are looked up by exact scan timestamp (within `STAMP_TOLERANCE`).
//!
//! [`truth_noise`]: how noisy a log's hand-made relations are, from relation
//! triangles; [`breakdown`]: where the short relations' error comes from.
//! Evaluation tooling with file input: the simulator layer, not the
//! matcher's crate.

pub mod breakdown;
pub mod truth_noise;

use std::io::BufRead;

use crate::geom::{pose, wrap_angle, Pose};

/// Largest timestamp difference (s) at which a trajectory pose is taken to be
/// the one a relation refers to (the benchmark's stamps agree to 5 µs).
pub const STAMP_TOLERANCE: f64 = 1e-4;

/// Why a relations or trajectory file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A line is not in the expected format.
    #[error("{path} line {line}: {message}")]
    Malformed {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// What was expected.
        message: String,
    },
    /// Too few relation triangles (a→b, a→c, short b→c) to estimate the ground truth's noise.
    #[error("only {found} relation triangles (a→b, a→c and a short b→c) refer to the trajectory; at least 3 are needed")]
    TooFewTriangles {
        /// Triangles found.
        found: usize,
    },
    /// No relation could be matched to the trajectory.
    #[error("none of the {relations} relations refer to timestamps of the trajectory")]
    NothingToScore {
        /// Relations read.
        relations: usize,
    },
}

/// One ground-truth relation: the pose at `t2` in the frame of the pose at `t1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Relation {
    /// First timestamp (s).
    pub t1: f64,
    /// Second timestamp (s).
    pub t2: f64,
    /// True relative pose.
    pub delta: Pose,
}

/// One pose of a trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stamped {
    /// Timestamp (s).
    pub t: f64,
    /// Pose.
    pub pose: Pose,
}

fn numbers(
    text: &str,
    path: &str,
    need: usize,
    what: &str,
) -> Result<Vec<(usize, Vec<f64>)>, EvalError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let mut v = Vec::with_capacity(need);
        for w in t.split_ascii_whitespace() {
            let x: f64 = w.parse().map_err(|_| EvalError::Malformed {
                path: path.into(),
                line: i + 1,
                message: format!("expected {what}, found `{w}` which is not a number"),
            })?;
            if !x.is_finite() {
                return Err(EvalError::Malformed {
                    path: path.into(),
                    line: i + 1,
                    message: format!("expected finite numbers ({what}), found {x}"),
                });
            }
            v.push(x);
        }
        if v.len() != need {
            return Err(EvalError::Malformed {
                path: path.into(),
                line: i + 1,
                message: format!("expected {need} numbers ({what}), found {}", v.len()),
            });
        }
        out.push((i + 1, v));
    }
    Ok(out)
}

/// Parses a relations file (`t1 t2 x y z roll pitch yaw` per line).
pub fn parse_relations(text: &str, path: &str) -> Result<Vec<Relation>, EvalError> {
    Ok(numbers(text, path, 8, "t1 t2 x y z roll pitch yaw")?
        .into_iter()
        .map(|(_, v)| Relation {
            t1: v[0],
            t2: v[1],
            delta: pose(v[2], v[3], v[7]),
        })
        .collect())
}

/// Parses a trajectory (`timestamp x y theta` per line) and sorts it by time.
pub fn parse_trajectory(text: &str, path: &str) -> Result<Vec<Stamped>, EvalError> {
    let mut t: Vec<Stamped> = numbers(text, path, 4, "timestamp x y theta")?
        .into_iter()
        .map(|(_, v)| Stamped {
            t: v[0],
            pose: pose(v[1], v[2], v[3]),
        })
        .collect();
    t.sort_by(|a, b| a.t.total_cmp(&b.t));
    Ok(t)
}

/// Reads a whole file as text.
pub fn read_text(path: &std::path::Path) -> Result<String, EvalError> {
    let f = std::fs::File::open(path).map_err(|source| EvalError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let mut s = String::new();
    for line in std::io::BufReader::new(f).lines() {
        let line = line.map_err(|source| EvalError::Io {
            path: path.display().to_string(),
            source,
        })?;
        s.push_str(&line);
        s.push('\n');
    }
    Ok(s)
}

/// Writes a trajectory line by line (`timestamp x y theta`, 6 decimals for time).
pub fn format_trajectory(poses: &[Stamped]) -> String {
    let mut s = String::with_capacity(poses.len() * 48);
    for p in poses {
        s.push_str(&format!(
            "{:.6} {:.6} {:.6} {:.6}\n",
            p.t,
            p.pose.translation.x,
            p.pose.translation.y,
            p.pose.rotation.angle()
        ));
    }
    s
}

/// The pose at timestamp `t` (within `STAMP_TOLERANCE`) of a sorted trajectory.
pub fn lookup(traj: &[Stamped], t: f64) -> Option<Pose> {
    let i = traj.partition_point(|p| p.t < t);
    let mut best: Option<(f64, Pose)> = None;
    for j in [i.wrapping_sub(1), i] {
        if let Some(p) = traj.get(j) {
            let d = (p.t - t).abs();
            if d <= STAMP_TOLERANCE && best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, p.pose));
            }
        }
    }
    best.map(|(_, p)| p)
}

/// The relations re-stamped onto a trajectory on another time base: each
/// relation time `t` is taken to be trajectory time `t - offset`, and
/// replaced by the stamp of the trajectory's nearest pose when that is
/// within `tolerance` (s). A time with no pose that near becomes NaN, which
/// [`lookup`] never finds, so the relation counts as missing.
///
/// The benchmark's corrected logs are thinned and re-based (see
/// `../shared/datasets/README.md`): fr079's offset is 1211.43 s with no
/// exact match, so its relations are scored on the nearest scan (0.1 s).
pub fn align(
    relations: &[Relation],
    traj: &[Stamped],
    offset: f64,
    tolerance: f64,
) -> Vec<Relation> {
    let nearest = |t: f64| {
        let t = t - offset;
        let i = traj.partition_point(|p| p.t < t);
        [i.wrapping_sub(1), i]
            .into_iter()
            .filter_map(|j| traj.get(j))
            .map(|p| p.t)
            .filter(|s| (s - t).abs() <= tolerance)
            .min_by(|a, b| (a - t).abs().total_cmp(&(b - t).abs()))
            .unwrap_or(f64::NAN)
    };
    relations
        .iter()
        .map(|r| Relation {
            t1: nearest(r.t1),
            t2: nearest(r.t2),
            delta: r.delta,
        })
        .collect()
}

/// Mean and (population) standard deviation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeanStd {
    /// Mean.
    pub mean: f64,
    /// Standard deviation.
    pub std: f64,
}

impl MeanStd {
    fn of(v: &[f64]) -> Self {
        if v.is_empty() {
            return Self::default();
        }
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        Self {
            mean,
            std: var.sqrt(),
        }
    }
}

/// Errors over one group of relations.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Scores {
    /// Relations scored.
    pub count: usize,
    /// Absolute translational error (m).
    pub trans: MeanStd,
    /// Squared translational error (m²).
    pub(crate) trans_sq: MeanStd,
    /// Absolute rotational error (degrees).
    pub rot_deg: MeanStd,
    /// Squared rotational error (degrees²).
    pub(crate) rot_sq_deg: MeanStd,
}

impl Scores {
    fn of(errs: &[(f64, f64)]) -> Self {
        let t: Vec<f64> = errs.iter().map(|e| e.0).collect();
        let r: Vec<f64> = errs.iter().map(|e| e.1.to_degrees()).collect();
        let t2: Vec<f64> = t.iter().map(|x| x * x).collect();
        let r2: Vec<f64> = r.iter().map(|x| x * x).collect();
        Self {
            count: errs.len(),
            trans: MeanStd::of(&t),
            trans_sq: MeanStd::of(&t2),
            rot_deg: MeanStd::of(&r),
            rot_sq_deg: MeanStd::of(&r2),
        }
    }
}

/// The evaluation report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Report {
    /// Relations in the file.
    pub relations: usize,
    /// Relations whose two timestamps were not found in the trajectory.
    pub missing: usize,
    /// All scored relations.
    pub all: Scores,
    /// Relations with t2 - t1 ≤ 1 s.
    pub local: Scores,
    /// Relations with t2 - t1 > 1 s.
    pub long: Scores,
}

/// Translational (m) and rotational (rad, absolute) error of one relation.
pub(crate) fn relation_error(rel: &Relation, p1: &Pose, p2: &Pose) -> (f64, f64) {
    let est = p1.inverse() * p2;
    let dx = est.translation.x - rel.delta.translation.x;
    let dy = est.translation.y - rel.delta.translation.y;
    let dth = wrap_angle(est.rotation.angle() - rel.delta.rotation.angle());
    (dx.hypot(dy), dth.abs())
}

/// Scores a trajectory against relations.
pub fn evaluate(relations: &[Relation], traj: &[Stamped]) -> Result<Report, EvalError> {
    let mut all = Vec::new();
    let mut local = Vec::new();
    let mut long = Vec::new();
    let mut missing = 0;
    for r in relations {
        match (lookup(traj, r.t1), lookup(traj, r.t2)) {
            (Some(p1), Some(p2)) => {
                let e = relation_error(r, &p1, &p2);
                all.push(e);
                if (r.t2 - r.t1).abs() <= 1.0 {
                    local.push(e);
                } else {
                    long.push(e);
                }
            }
            _ => missing += 1,
        }
    }
    if all.is_empty() {
        return Err(EvalError::NothingToScore {
            relations: relations.len(),
        });
    }
    Ok(Report {
        relations: relations.len(),
        missing,
        all: Scores::of(&all),
        local: Scores::of(&local),
        long: Scores::of(&long),
    })
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "relations: {} ({} scored, {} not found in the trajectory)",
            self.relations, self.all.count, self.missing
        )?;
        writeln!(
            f,
            "{:<14} {:>5}  {:>18}  {:>20}  {:>16}  {:>18}",
            "group", "n", "trans abs [m]", "trans sqr [m^2]", "rot abs [deg]", "rot sqr [deg^2]"
        )?;
        for (name, s) in [
            ("all", &self.all),
            ("<= 1 s", &self.local),
            ("> 1 s", &self.long),
        ] {
            writeln!(
                f,
                "{:<14} {:>5}  {:>8.4} ± {:<7.4}  {:>9.5} ± {:<8.5}  {:>6.3} ± {:<7.3}  {:>7.3} ± {:<8.3}",
                name,
                s.count,
                s.trans.mean,
                s.trans.std,
                s.trans_sq.mean,
                s.trans_sq.std,
                s.rot_deg.mean,
                s.rot_deg.std,
                s.rot_sq_deg.mean,
                s.rot_sq_deg.std
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_trajectory_scores_zero_and_offsets_are_measured() {
        let traj = vec![
            Stamped {
                t: 1.0,
                pose: pose(1.0, 1.0, 0.5),
            },
            Stamped {
                t: 1.5,
                pose: pose(1.0, 1.0, 0.5) * pose(0.3, 0.1, 0.2),
            },
            Stamped {
                t: 9.0,
                pose: pose(4.0, 0.0, -1.0),
            },
        ];
        let rels = vec![
            Relation {
                t1: 1.0,
                t2: 1.5,
                delta: pose(0.3, 0.1, 0.2),
            },
            Relation {
                t1: 1.0,
                t2: 9.0,
                delta: pose(1.0, 1.0, 0.5).inverse() * pose(4.1, 0.0, -1.0),
            },
            Relation {
                t1: 1.0,
                t2: 7.0,
                delta: pose(0.0, 0.0, 0.0),
            },
        ];
        let r = evaluate(&rels, &traj).unwrap();
        assert_eq!(r.missing, 1);
        assert_eq!(r.all.count, 2);
        assert!(r.local.trans.mean < 1e-9 && r.local.rot_deg.mean < 1e-9);
        assert!((r.long.trans.mean - 0.1).abs() < 1e-9, "{r:?}");
        assert!(r.long.rot_deg.mean < 1e-9);
    }

    #[test]
    fn rotation_error_wraps() {
        let rel = Relation {
            t1: 0.0,
            t2: 1.0,
            delta: pose(0.0, 0.0, 3.1),
        };
        let (_, e) = relation_error(&rel, &pose(0.0, 0.0, 0.0), &pose(0.0, 0.0, -3.1));
        assert!((e - (2.0 * std::f64::consts::PI - 6.2)).abs() < 1e-9);
    }

    #[test]
    fn malformed_files_name_the_line() {
        let e = parse_relations("1 2 3 4 5 6 7 8\n1 2 x 4 5 6 7 8\n", "r").unwrap_err();
        assert!(
            e.to_string().contains("line 2") && e.to_string().contains("`x`"),
            "{e}"
        );
        let e = parse_trajectory("1 2 3\n", "t").unwrap_err();
        assert!(e.to_string().contains("expected 4 numbers"), "{e}");
        let e = parse_trajectory("1 2 3 inf\n", "t").unwrap_err();
        assert!(e.to_string().contains("finite"), "{e}");
        let traj = parse_trajectory("5 0 0 0\n", "t").unwrap();
        let rels = parse_relations("1 2 0 0 0 0 0 0\n", "r").unwrap();
        assert!(matches!(
            evaluate(&rels, &traj),
            Err(EvalError::NothingToScore { relations: 1 })
        ));
    }

    #[test]
    fn lookup_is_by_exact_stamp() {
        let traj = parse_trajectory("2.0 1 0 0\n1.0 0 0 0\n", "t").unwrap();
        assert_eq!(traj[0].t, 1.0);
        assert!(lookup(&traj, 2.00001).is_some());
        assert!(lookup(&traj, 2.01).is_none());
        assert!(lookup(&traj, 0.5).is_none());
    }

    #[test]
    fn aligned_relations_take_the_nearest_pose_on_the_shifted_clock() {
        let traj = parse_trajectory("1.0 0 0 0\n2.0 1 0 0\n3.0 3 0 0\n", "t").unwrap();
        let rels =
            parse_relations("101.04 102.03 1 0 0 0 0 0\n101.0 109.0 1 0 0 0 0 0\n", "r").unwrap();
        let aligned = align(&rels, &traj, 100.0, 0.1);
        assert_eq!((aligned[0].t1, aligned[0].t2), (1.0, 2.0));
        assert!(aligned[1].t2.is_nan(), "9 s has no pose within 0.1 s");
        let r = evaluate(&aligned, &traj).unwrap();
        assert_eq!((r.all.count, r.missing), (1, 1));
        assert!(r.all.trans.mean < 1e-9);
        // Without the offset nothing refers to the trajectory.
        assert!(evaluate(&align(&rels, &traj, 0.0, 0.1), &traj).is_err());
    }
}
