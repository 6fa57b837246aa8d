//! `sweepline sim`: the main job. Starts the emulated URG-04LX and wheel base
//! on ptys and the daemon opening both, covers the world, prints progress and
//! writes a report folder (summary, map/cells/path SVGs, budget report).
//!
//! ```text
//! sweepline sim                                  # hw/worlds/paper.world into out/sim
//! sweepline sim --room office_f:3 --out out/office_f_3
//! sweepline sim --map lab.yaml --region 2,3,9,8   # a room of a ROS map_server map
//! sweepline sim --base create2 --speed 5 --fixed-speed  # the clock at exactly ×5, not waiting for the daemon
//! ```

use std::path::PathBuf;

use super::world_args::WorldArgs;
use super::CliResult;
use crate::config::Config;
use crate::motor::BaseKind;
use crate::plan::HomeOutcome;
use crate::sim::closed_loop::{self, SimOptions};

/// Default world of `sweepline sim`.
pub const DEFAULT_WORLD: &str = "hw/worlds/paper.world";

/// Arguments of `sweepline sim`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The world to cover (default: hw/worlds/paper.world).
    #[command(flatten)]
    pub world: WorldArgs,
    /// Simulated seconds per wall-clock second at most: the simulated
    /// clock waits whenever the daemon is behind with a scan, so a loaded
    /// host slows the run down instead of starving the daemon.
    #[arg(long, default_value_t = 15.0)]
    pub speed: f64,
    /// Run the simulated clock at exactly `--speed`, never waiting for the
    /// daemon: a loaded host then starves the daemon and the figures suffer
    /// (for comparing with the paced clock).
    #[arg(long)]
    pub fixed_speed: bool,
    /// Report folder.
    #[arg(long, default_value = "out/sim")]
    pub out: PathBuf,
    /// Emulated wheel base.
    #[arg(long, default_value = "roboclaw", value_parser = ["roboclaw", "create2"])]
    pub base: String,
    /// Robot configuration.
    #[arg(long, default_value = "hw/robot.toml")]
    pub config: PathBuf,
    /// Seed of the simulated noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds after which the run stops unfinished (default:
    /// 3600, or 60 per m² of free floor where that is longer).
    #[arg(long)]
    pub time_cap: Option<f64>,
    /// Scanner emulator faults (as `sweepline emulate urg --faults`).
    #[arg(long, default_value = "")]
    pub urg_faults: String,
    /// Tell the daemon a start heading this far off the true one (degrees),
    /// as for a robot switched on at an angle to the walls: its map frame
    /// starts turned against the room and must be laid along the walls
    /// (`daemon.align_to_walls`).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = parse_heading_error)]
    pub heading_error: f64,
    /// A motion fault at a simulated time (s from the start); may be given
    /// more than once. `slip=AT:SECS:LEFT:RIGHT`: each wheel covers that
    /// share less floor than its encoder counts (slip=120:1:0.45:0);
    /// `kidnap=AT:DX:DY:DEG`: the robot is put down DX m ahead and DY m to
    /// the left, turned DEG, the daemon not told (kidnap=200:1:0:30);
    /// `knock=AT:DEG`: turned in place (knock=150:10).
    #[arg(long = "fault", value_name = "SPEC", allow_hyphen_values = true)]
    pub faults: Vec<String>,
    /// Each wheel covers this many percent more floor than its encoder
    /// counts: a wheel radius or tyre error the odometry does not know.
    #[arg(
        long,
        value_name = "PERCENT",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub odometry_scale_error: f64,
    /// Mount the emulated scanner this far (degrees, counter-clockwise)
    /// from the `robot.scanner_yaw` the daemon is told: a wrongly
    /// configured mount, which the daemon should catch on its first drive.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = parse_heading_error)]
    pub mount_yaw_error: f64,
    /// Mount the emulated scanner this far (metres ahead, left: `DX,DY`)
    /// from the `robot.scanner_offset_x`/`_y` the daemon is told, which it
    /// should catch on its first half turn in place.
    #[arg(long, default_value = "0,0", allow_hyphen_values = true, value_parser = parse_offset_error)]
    pub mount_offset_error: (f64, f64),
    /// Serve the live view (the Foxglove WebSocket protocol: open Foxglove
    /// or Lichtblick and connect to ws://HOST:PORT) on HOST:PORT; `off`:
    /// none. Read-only; keep it on the loopback address.
    #[arg(long, default_value = "127.0.0.1:8765", value_name = "HOST:PORT")]
    pub live: String,
    /// Do not write the recording `run.mcap` into the report folder.
    #[arg(long)]
    pub no_record: bool,
}

/// Parses a base name.
pub fn parse_base(s: &str) -> Result<BaseKind, String> {
    match s {
        "roboclaw" => Ok(BaseKind::Roboclaw),
        "create2" => Ok(BaseKind::Create2),
        other => Err(format!(
            "unknown base `{other}`: expected roboclaw or create2"
        )),
    }
}

/// Parses `--heading-error`: degrees in -180..=180.
pub fn parse_heading_error(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= 180.0 => Ok(v),
        _ => Err(format!("expected degrees in -180..=180, got `{s}`")),
    }
}

/// Parses `--mount-offset-error`: `DX,DY` in metres, each within ±0.5.
pub fn parse_offset_error(s: &str) -> Result<(f64, f64), String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected DX,DY in metres, got `{s}`"))?;
    match v[..] {
        [x, y] if x.is_finite() && y.is_finite() && x.abs() <= 0.5 && y.abs() <= 0.5 => Ok((x, y)),
        _ => Err(format!(
            "expected DX,DY in metres, each within ±0.5, got `{s}`"
        )),
    }
}

/// Runs `sweepline sim`.
pub fn run(args: Args) -> CliResult {
    let world = args.world.load(Some(std::path::Path::new(DEFAULT_WORLD)))?;
    let config = Config::load(&args.config)?;
    let mut opts = SimOptions::new(world, config);
    opts.speed = args.speed;
    if args.fixed_speed {
        opts.pace = None;
    }
    opts.base = parse_base(&args.base)?;
    opts.out = Some(args.out.clone());
    opts.seed = args.seed;
    opts.time_cap = super::world_args::time_cap(args.time_cap, &opts.world);
    opts.progress = true;
    opts.live = (args.live != "off").then(|| args.live.clone());
    opts.record = !args.no_record;
    opts.urg_faults = args.urg_faults.parse()?;
    opts.heading_error = args.heading_error.to_radians();
    opts.odometry_scale_error = args.odometry_scale_error / 100.0;
    for spec in &args.faults {
        let (at, fault) = crate::sim::base_emu::faults::parse_motion(spec)?;
        opts.base_faults
            .push(crate::sim::closed_loop::TimedFault { at, fault });
    }
    let (dx, dy) = args.mount_offset_error;
    if args.mount_yaw_error != 0.0 || dx != 0.0 || dy != 0.0 {
        let r = &opts.config.robot;
        let m = r.scanner_mount();
        let truth = crate::geom::pose(
            m.translation.x + dx,
            m.translation.y + dy,
            crate::geom::heading(&m) + args.mount_yaw_error.to_radians(),
        );
        opts.scanner_truth = Some((truth, r.scanner_upside_down));
    }
    if args.out.join("state").exists() {
        std::fs::remove_dir_all(args.out.join("state"))?;
    }
    println!(
        "sweepline sim: {} ({:.1} m² free), {:?} base, speed {}×{}, report in {}",
        opts.world.name,
        opts.world.free.free_area(),
        opts.base,
        if opts.pace.is_some() { "up to " } else { "" },
        opts.speed,
        args.out.display()
    );
    let r = closed_loop::run(&opts)?;
    let m = &r.metrics;
    println!(
        "done in {:.1} s wall ({:.0} s simulated): {} — coverage {:.2} % of {:.2} m² reachable, \
         path {:.1} m, {} turns, overlap {:.1} %, pose RMSE {:.1} mm / {:.2}°; drive back: {}, \
         ended {:.2} m from the start",
        r.wall,
        r.sim_time,
        r.reason,
        m.coverage * 100.0,
        m.reachable_area,
        m.path_length,
        m.turns,
        m.overlap * 100.0,
        r.position_rmse * 1e3,
        r.heading_rmse.to_degrees(),
        HomeOutcome::describe_run(r.home),
        r.ended_from_start
    );
    println!(
        "report: {}/summary.md (pictures map.svg, cells.svg, path.svg; recording run.mcap)",
        args.out.display()
    );
    if r.finished {
        Ok(())
    } else if r.capped {
        Err(super::TimeCapReached(format!(
            "coverage did not finish within the time cap ({:.0} s simulated)",
            r.sim_time
        ))
        .into())
    } else {
        Err(format!("coverage did not finish: {}", r.reason).into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_offset_error_is_two_distances_in_metres() {
        assert_eq!(parse_offset_error("0.05,-0.02"), Ok((0.05, -0.02)));
        assert_eq!(parse_offset_error(" -0.1 , 0 "), Ok((-0.1, 0.0)));
        for bad in ["0.05", "0.1,0.2,0.3", "a,b", "0.6,0", "NaN,0", ""] {
            let e = parse_offset_error(bad).unwrap_err();
            assert!(e.contains("DX,DY"), "{bad}: {e}");
        }
    }

    #[test]
    fn a_heading_error_is_degrees_within_a_half_turn() {
        assert_eq!(parse_heading_error("-35"), Ok(-35.0));
        assert_eq!(parse_heading_error("180"), Ok(180.0));
        for bad in ["181", "nan", "inf", "20deg", ""] {
            let e = parse_heading_error(bad).unwrap_err();
            assert!(e.contains("-180..=180") && e.contains(bad), "{bad}: {e}");
        }
    }
}
