//! `sweepline eval`: scores a trajectory against Kümmerle et al. relations,
//! or against the true poses a simulator's recording (`run.mcap`) holds.

use super::CliResult;
use crate::sim::eval::breakdown::{breakdown, shared, short_errors};
use crate::sim::eval::truth_noise::truth_noise;
use crate::sim::eval::{
    align, evaluate, parse_relations, parse_trajectory, read_text, STAMP_TOLERANCE,
};

/// Arguments of `sweepline eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The relations file (t1 t2 x y z roll pitch yaw per line).
    #[arg(long, required_unless_present = "truth", conflicts_with = "truth")]
    pub relations: Option<std::path::PathBuf>,
    /// A `sweepline sim` recording (`run.mcap`): score the trajectory (map
    /// frame, e.g. from `sweepline replay run.mcap`) against the true
    /// poses it holds, as the run's own report scores the live poses.
    #[arg(long, value_name = "RECORDING")]
    pub truth: Option<std::path::PathBuf>,
    /// The trajectory (timestamp x y theta per line).
    pub trajectory: std::path::PathBuf,
    /// Also estimate the annotation noise of the short relations from relation
    /// triangles (three-cornered hat) and the score a perfect matcher would get.
    #[arg(long)]
    pub truth_noise: bool,
    /// Also break the short relations' rotational error down (quantiles, bias, by size of the turn).
    #[arg(long)]
    pub breakdown: bool,
    /// A second trajectory: report how much of the two trajectories' signed
    /// errors on the short relations is common to both.
    #[arg(long, value_name = "TRAJECTORY")]
    pub against: Option<std::path::PathBuf>,
    /// Add this (s) to every trajectory timestamp before scoring: the
    /// benchmark's corrected logs are on a re-based clock (fr079: 1211.43,
    /// intel: 976052857.337, aces: 70.179; see the datasets README).
    #[arg(
        long,
        value_name = "SECONDS",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub time_offset: f64,
    /// Score each relation on the trajectory pose nearest its shifted time
    /// when it is this near (s; fr079 needs 0.1). Default: exact stamps.
    #[arg(long, value_name = "SECONDS")]
    pub tolerance: Option<f64>,
}

/// Runs `sweepline eval`.
pub fn run(args: Args) -> CliResult {
    let traj_text = read_text(&args.trajectory)?;
    let traj = parse_trajectory(&traj_text, &args.trajectory.display().to_string())?;
    let Some(relations) = &args.relations else {
        let truth = args.truth.as_deref().ok_or("give --relations or --truth")?;
        return score_truth(truth, &traj);
    };
    let rel_text = read_text(relations)?;
    let rels = parse_relations(&rel_text, &relations.display().to_string())?;
    let rels = match (args.time_offset, args.tolerance) {
        (0.0, None) => rels,
        (o, t) => align(&rels, &traj, o, t.unwrap_or(STAMP_TOLERANCE)),
    };
    let report = evaluate(&rels, &traj)?;
    print!("{report}");
    if args.breakdown || args.against.is_some() {
        let errors = short_errors(&rels, &traj);
        if args.breakdown {
            print!("{}", breakdown(&errors));
        }
        if let Some(other) = &args.against {
            let other_traj = parse_trajectory(&read_text(other)?, &other.display().to_string())?;
            print!("{}", shared(&errors, &short_errors(&rels, &other_traj)));
        }
    }
    if args.truth_noise {
        let noise = truth_noise(&rels, &traj, 2000, 1)?;
        print!("{noise}");
    }
    Ok(())
}

/// Scores `traj` against the truth of the recording at `path`.
fn score_truth(path: &std::path::Path, traj: &[crate::sim::eval::Stamped]) -> CliResult {
    let rec = crate::live::Recording::read(path)?;
    let to_w = rec
        .map_to_world
        .filter(|_| !rec.truth.is_empty())
        .ok_or_else(|| {
            format!(
                "{}: no truth recorded (not a `sweepline sim` recording)",
                path.display()
            )
        })?;
    let fixes: Vec<_> = traj.iter().map(|s| (s.t, s.pose)).collect();
    let (pos, head, max, n) = crate::sim::closed_loop::score_fixes(&fixes, &rec.truth, &to_w);
    if n == 0 {
        return Err(format!(
            "no trajectory pose within 0.2 s of a true pose of {}: another run's trajectory?",
            path.display()
        )
        .into());
    }
    println!(
        "against the truth of {}: position RMSE {:.1} mm, heading RMSE {:.2}°, max {:.1} mm ({n} of {} poses scored)",
        path.display(),
        pos * 1e3,
        head.to_degrees(),
        max * 1e3,
        traj.len()
    );
    Ok(())
}
