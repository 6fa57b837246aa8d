//! `sweepline probe`: asks a scanner what it is (VV, PP, II), takes one scan and prints a summary and the health counters.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use super::CliResult;
use crate::scip::{ErrorKind, Reading};
use crate::urg::{Clock, MonotonicClock, UrgError, UrgHealth, UrgParams, UrgScan, UrgSession};

/// Arguments of `sweepline probe`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scanner: a serial device (e.g. /dev/sweepline-urg or a pty path)
    /// or HOST:PORT of an Ethernet model (e.g. 192.168.0.10:10940); the same
    /// flag as `sweepline run --scanner`.
    #[arg(long, alias = "port")]
    pub scanner: PathBuf,
    /// Skip the TM clock sync (stamps then use the arrival time).
    #[arg(long)]
    pub no_time_sync: bool,
    /// Also draw the scan from above into this SVG file.
    #[arg(long)]
    pub svg: Option<PathBuf>,
}

/// Runs `sweepline probe`.
pub fn run(args: Args) -> CliResult {
    let params = UrgParams {
        port: args.scanner.display().to_string(),
        time_sync_samples: if args.no_time_sync { 0 } else { 10 },
        // A diagnostic never reboots what it is pointed at (it may not
        // even be a URG).
        reboot_last_resort: false,
        ..UrgParams::default()
    };
    let (text, scan) = probe_scan(&args.scanner, &params, Arc::new(MonotonicClock::new()))?;
    print!("{text}");
    if let (Some(path), Some(scan)) = (&args.svg, scan) {
        let title = args.scanner.display().to_string();
        crate::urg::picture::write_scan_svg(&scan, 12.0, &title, path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        println!("scan picture written to {}", path.display());
    }
    Ok(())
}

/// Opens the scanner at `port` as the daemon would, identifies it, takes one
/// scan (`MD…01`) and returns the printed summary.
pub fn probe(port: &Path, params: &UrgParams, clock: Arc<dyn Clock>) -> Result<String, UrgError> {
    probe_scan(port, params, clock).map(|(text, _)| text)
}

/// [`probe`], also returning the scan it took (if any).
pub fn probe_scan(
    port: &Path,
    params: &UrgParams,
    clock: Arc<dyn Clock>,
) -> Result<(String, Option<UrgScan>), UrgError> {
    let mut conn = crate::serial::scanner_connector(&port.display().to_string(), params.baud);
    let link = conn
        .open(std::time::Duration::from_secs_f64(
            params.poll.clamp(0.001, 1.0),
        ))
        .map_err(|source| UrgError::Io {
            port: port.display().to_string(),
            source,
        })?;
    let health = Arc::new(UrgHealth::default());
    let slot: Arc<Mutex<Option<UrgScan>>> = Arc::new(Mutex::new(None));
    let s2 = slot.clone();
    let sink = Box::new(move |s: &UrgScan| {
        if let Ok(mut g) = s2.lock() {
            *g = Some(s.clone());
        }
    });
    let mut session = UrgSession::open(
        link,
        params.clone(),
        clock,
        health.clone(),
        Arc::new(AtomicBool::new(false)),
        None,
        sink,
    )?;
    let scan_result = session.single_scan();
    let info = session.info();
    let model = session.clock_model();
    session.shutdown();
    let mut out = String::new();
    if let Some(i) = &info {
        let v = &i.version;
        let _ = writeln!(out, "sensor at {}", port.display());
        let _ = writeln!(out, "  vendor     {}", v.vendor);
        let _ = writeln!(out, "  product    {}", v.product);
        let _ = writeln!(out, "  firmware   {}", v.firmware);
        let _ = writeln!(out, "  protocol   {}", v.protocol);
        let _ = writeln!(out, "  serial     {}", v.serial);
        let p = &i.params;
        let _ = writeln!(out, "parameters (PP)");
        let _ = writeln!(out, "  model      {}", p.model);
        let _ = writeln!(out, "  range      {} .. {} mm", p.dmin, p.dmax);
        let _ = writeln!(
            out,
            "  steps      {} .. {} (front {}), {} per turn: {} beams over {:.1} deg",
            p.amin,
            p.amax,
            p.afrt,
            p.ares,
            p.step_count(),
            p.field_of_view().to_degrees()
        );
        let _ = writeln!(
            out,
            "  speed      {} rpm: one scan every {:.0} ms",
            p.scan_rpm,
            p.scan_period() * 1e3
        );
        match &i.info {
            Some(ii) => {
                let _ = writeln!(out, "state (II)");
                let _ = writeln!(out, "  laser      {}", ii.laser);
                let _ = writeln!(out, "  speed      {}", ii.scan_speed);
                let _ = writeln!(out, "  mode       {}", ii.measure_mode);
                let _ = writeln!(out, "  bit rate   {}", ii.bit_rate);
                let _ = writeln!(out, "  status     {}", ii.state);
            }
            None => {
                let _ = writeln!(out, "state (II)   not available");
            }
        }
    }
    let scan = slot.lock().ok().and_then(|g| g.clone());
    match (scan_result, &scan) {
        (Ok(()), Some(s)) => summarise(&mut out, s),
        (Err(e), _) => {
            let _ = writeln!(out, "scan         FAILED: {e}");
        }
        (Ok(()), None) => {
            let _ = writeln!(out, "scan         none received");
        }
    }
    if let Some(m) = model {
        let _ = writeln!(
            out,
            "clock sync   sensor - host = {:.4} s (best round trip {:.3} ms)",
            m.offset(),
            m.rtt * 1e3
        );
    }
    let _ = writeln!(out, "health");
    for line in health.snapshot().to_string().lines() {
        let _ = writeln!(out, "  {line}");
    }
    Ok((out, scan))
}

fn summarise(out: &mut String, s: &UrgScan) {
    let beams = &s.scan.beams;
    let valid = s.scan.valid_count();
    let _ = writeln!(out, "scan");
    let _ = writeln!(
        out,
        "  timestamp  {} ms (sensor clock), {:.4} s (host clock)",
        s.raw_stamp, s.scan.stamp
    );
    if let Some(f) = beams
        .iter()
        .zip(s.readings.iter())
        .min_by(|a, b| a.0.angle.abs().total_cmp(&b.0.angle.abs()))
    {
        match f.1 {
            Reading::Range(mm) => {
                let _ = writeln!(out, "  front      {mm} mm");
            }
            Reading::Error(e) => {
                let _ = writeln!(
                    out,
                    "  front      no range: code {} ({})",
                    e.code,
                    e.kind.meaning()
                );
            }
            Reading::BeyondMax(mm) => {
                let _ = writeln!(out, "  front      {mm} mm, beyond the maximum range");
            }
        }
    }
    let _ = writeln!(
        out,
        "  beams      {} valid, {} invalid of {}",
        valid,
        beams.len() - valid,
        beams.len()
    );
    // Invalid readings by kind, with the raw codes seen.
    let mut kinds: Vec<(ErrorKind, usize, Vec<u32>)> = Vec::new();
    let mut beyond = 0;
    for r in &s.readings {
        match r {
            Reading::Error(e) => match kinds.iter_mut().find(|k| k.0 == e.kind) {
                Some(k) => {
                    k.1 += 1;
                    if !k.2.contains(&e.code) {
                        k.2.push(e.code);
                    }
                }
                None => kinds.push((e.kind, 1, vec![e.code])),
            },
            Reading::BeyondMax(_) => beyond += 1,
            Reading::Range(_) => {}
        }
    }
    kinds.sort_by_key(|k| std::cmp::Reverse(k.1));
    for (kind, n, mut codes) in kinds {
        codes.sort_unstable();
        let codes: Vec<String> = codes.iter().map(u32::to_string).collect();
        let _ = writeln!(
            out,
            "    {n:4} x code {:<8} {}",
            codes.join(","),
            kind.meaning()
        );
    }
    if beyond > 0 {
        let _ = writeln!(out, "    {beyond:4} x beyond the maximum range");
    }
}
