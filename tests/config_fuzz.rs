//! Fuzz-style tests of the config loader: truncated, corrupted and hostile
//! TOML (random bytes, huge numbers, NaN, deep nesting, wrong types, unknown
//! keys) gives a clear one-line error naming the key or line, never a panic.

use std::path::Path;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sweepline::config::{Config, ConfigError, MAX_CONFIG_BYTES};

fn shipped() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml")).unwrap()
}

/// Every error must be one readable line of bounded length.
fn check_error(e: &ConfigError, input_len: usize) {
    let msg = e.to_string();
    assert!(!msg.contains('\n'), "multi-line error: {msg}");
    assert!(
        msg.len() < 600,
        "error of {} bytes for {input_len} bytes of input",
        msg.len()
    );
    match e {
        ConfigError::Parse { message, .. } => assert!(!message.is_empty()),
        ConfigError::Invalid { key, .. } => assert!(key.contains('.'), "key {key}"),
        ConfigError::Io { .. } => {}
    }
}

#[test]
fn every_truncation_of_the_shipped_file_is_ok_or_a_clear_error() {
    let text = shipped();
    let mut errors = 0;
    for (i, _) in text.char_indices() {
        if let Err(e) = Config::from_toml(&text[..i], "robot.toml") {
            check_error(&e, i);
            errors += 1;
        }
    }
    assert!(
        errors > 0,
        "some truncations must be errors (cut inside a key or value)"
    );
}

#[test]
fn corrupted_bytes_never_panic() {
    let text = shipped().into_bytes();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..3000 {
        let mut b = text.clone();
        for _ in 0..rng.random_range(1..4) {
            let i = rng.random_range(0..b.len());
            b[i] = rng.random_range(0x20..0x7f);
        }
        // A byte written into a multi-byte character leaves invalid UTF-8,
        // which the loader is never handed as text: check the lossy reading.
        let s = String::from_utf8_lossy(&b).into_owned();
        if let Err(e) = Config::from_toml(&s, "corrupt.toml") {
            check_error(&e, s.len());
        }
    }
}

#[test]
fn random_text_never_panics() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let alphabet = b"[]{}=.,\"'#\n \t0123456789abcdefxyz_-+eEnaif:";
    for _ in 0..3000 {
        let len = rng.random_range(0..200);
        let s: String = (0..len)
            .map(|_| alphabet[rng.random_range(0..alphabet.len())] as char)
            .collect();
        if let Err(e) = Config::from_toml(&s, "random.toml") {
            check_error(&e, s.len());
        }
    }
}

#[test]
fn hostile_inputs_name_the_key_or_line() {
    let deep_arrays = format!("x = {}{}", "[".repeat(100_000), "]".repeat(100_000));
    let deep_tables = format!("x = {}1{}", "{a=".repeat(50_000), "}".repeat(50_000));
    let long_key = format!("[robot]\n{} = 1\n", "k".repeat(1 << 20));
    let long_string = format!("[robot]\nradius = \"{}\"\n", "s".repeat(1 << 20));
    let cases: Vec<(&str, String, &[&str])> = vec![
        (
            "NaN",
            "[robot]\nradius = nan\n".into(),
            &["robot.radius", "finite"],
        ),
        (
            "infinity",
            "[robot]\nradius = inf\n".into(),
            &["robot.radius"],
        ),
        (
            "negative",
            "[robot]\nradius = -0.1\n".into(),
            &["robot.radius", "> 0"],
        ),
        (
            "huge float",
            "[robot]\nradius = 1e400\n".into(),
            &["line 2", "radius"],
        ),
        (
            "huge int",
            "[pipeline]\nscan_queue = 99999999999999999999\n".into(),
            &["line 2", "scan_queue"],
        ),
        (
            "negative usize",
            "[pipeline]\nscan_queue = -1\n".into(),
            &["line 2", "scan_queue"],
        ),
        (
            "u8 overflow",
            "[pipeline]\nmax_degrade = 256\n".into(),
            &["line 2", "max_degrade"],
        ),
        (
            "zero queue",
            "[pipeline]\nscan_queue = 0\n".into(),
            &["pipeline.scan_queue"],
        ),
        (
            "float for int",
            "[pipeline]\nscan_queue = 4.5\n".into(),
            &["line 2", "scan_queue"],
        ),
        (
            "string for float",
            "[pipeline.budget]\nlocalise = \"fast\"\n".into(),
            &["line 2", "localise"],
        ),
        (
            "unknown key",
            "[pipeline.budget]\nlocalize = 0.002\n".into(),
            &["localize"],
        ),
        (
            "unknown table",
            "[lidar]\nport = 1\n".into(),
            &["lidar", "`pipeline`"],
        ),
        (
            "table as value",
            "[pipeline]\nbudget = 3\n".into(),
            &["line 2", "budget"],
        ),
        (
            "duplicate key",
            "[robot]\nradius = 0.2\nradius = 0.3\n".into(),
            &["line 3", "radius"],
        ),
        (
            "duplicate table",
            "[robot]\n[robot]\n".into(),
            &["line 2", "robot"],
        ),
        (
            "scalar for table",
            "robot = 5\n".into(),
            &["line 1", "robot"],
        ),
        (
            "huge budget",
            "[pipeline.budget]\nplan = 1e300\n".into(),
            &["pipeline.budget.plan", "got 1e300"],
        ),
        (
            "integer zero budget",
            "[pipeline.budget]\nmotor = 0\n".into(),
            &["pipeline.budget.motor"],
        ),
        (
            "stall too short",
            "[pipeline]\nstall_after = 0.01\n".into(),
            &["pipeline.stall_after"],
        ),
        (
            "poll too long",
            "[pipeline]\npoll_timeout = 1e300\n".into(),
            &["pipeline.poll_timeout"],
        ),
        (
            "negative watchdog",
            "[pipeline]\nwatchdog_period = -1.0\n".into(),
            &["pipeline.watchdog_period"],
        ),
        (
            "zero degrade",
            "[pipeline]\ndegrade_after = 0\n".into(),
            &["pipeline.degrade_after"],
        ),
        (
            "zero stuck limit",
            "[daemon]\nstuck_after = 0.0\n".into(),
            &["daemon.stuck_after", "got 0.0"],
        ),
        (
            "NaN stuck limit",
            "[daemon]\nstuck_after = nan\n".into(),
            &["daemon.stuck_after"],
        ),
        (
            "zero scan timeout",
            "[daemon]\nscan_timeout = 0.0\n".into(),
            &["daemon.scan_timeout", "got 0.0"],
        ),
        (
            "scan timeout of a minute",
            "[daemon]\nscan_timeout = 60.0\n".into(),
            &["daemon.scan_timeout", "got 60.0"],
        ),
        (
            "no time between plans",
            "[daemon]\nplan_interval = 0.0\n".into(),
            &["daemon.plan_interval", "got 0.0"],
        ),
        (
            "a plan a minute",
            "[daemon]\nplan_interval = 60.0\n".into(),
            &["daemon.plan_interval", "got 60.0"],
        ),
        (
            "bearing outside the bumper",
            "[daemon.contact]\nside_bearing = 1.5\n".into(),
            &["daemon.contact.side_bearing", "got 1.5"],
        ),
        (
            "bumper wider than a half circle",
            "[daemon.contact]\nbumper_half_arc = 3.0\n".into(),
            &["daemon.contact.bumper_half_arc"],
        ),
        (
            "negative contact gap",
            "[daemon.contact]\ngap = -0.01\n".into(),
            &["daemon.contact.gap"],
        ),
        (
            "zero arc",
            "[daemon.contact]\narc_half_length = 0\n".into(),
            &["daemon.contact.arc_half_length"],
        ),
        (
            "huge settle",
            "[daemon.contact]\nsettle = 1e300\n".into(),
            &["daemon.contact.settle"],
        ),
        (
            "retrying walled-off floor: a word, not a boolean",
            "[daemon.contact]\nretry_walled_floor = \"yes\"\n".into(),
            &["retry_walled_floor", "boolean"],
        ),
        (
            // A wrong type must not fall back to deskewing or not.
            "deskewing scans: a word, not a boolean",
            "[daemon]\ndeskew_scans = \"yes\"\n".into(),
            &["deskew_scans", "boolean"],
        ),
        (
            "a negative surface hold",
            "[plan]\nsurface_hold = -1\n".into(),
            &["surface_hold", "u32"],
        ),
        (
            // It also sets how firm a match must be to count in the mount
            // checks (6 x this): a bad value must not reach them.
            "a negative degeneracy threshold",
            "[icp]\ndegeneracy_threshold = -0.02\n".into(),
            &["icp.degeneracy_threshold", ">= 0"],
        ),
        (
            "a NaN degeneracy threshold",
            "[icp]\ndegeneracy_threshold = nan\n".into(),
            &["icp.degeneracy_threshold"],
        ),
        (
            // Intensities are divided by it before matching.
            "a zero intensity unit",
            "[scanner]\nintensity_unit = 0\n".into(),
            &["scanner.intensity_unit", "positive"],
        ),
        (
            "a NaN intensity unit",
            "[scanner]\nintensity_unit = nan\n".into(),
            &["scanner.intensity_unit"],
        ),
        (
            "unknown contact key",
            "[daemon.contact]\nbearing = 0.5\n".into(),
            &["bearing", "side_bearing"],
        ),
        (
            "live bind without a port",
            "[live]\nbind = \"localhost\"\n".into(),
            &["live.bind", "HOST:PORT"],
        ),
        (
            "live bind port out of range",
            "[live]\nbind = \"127.0.0.1:70000\"\n".into(),
            &["live.bind"],
        ),
        (
            "unknown live key",
            "[live]\nport = 8765\n".into(),
            &["port", "bind"],
        ),
        (
            "record file size NaN",
            "[record]\nfile_mib = nan\n".into(),
            &["record.file_mib"],
        ),
        (
            "record cap below one file",
            "[record]\nfile_mib = 64\nmax_mib = 10\n".into(),
            &["record.max_mib", "record.file_mib"],
        ),
        (
            "record channels not a list",
            "[record]\nchannels = \"/scan\"\n".into(),
            &["line 2", "channels"],
        ),
        (
            "record topic without a slash",
            "[record]\nchannels = [\"scan\"]\n".into(),
            &["record.channels", "scan"],
        ),
        ("deep arrays", deep_arrays, &["line 1"]),
        ("deep tables", deep_tables, &["line 1"]),
        ("long key", long_key, &["line 2", "kkkk"]),
        ("long string", long_string, &["line 2", "radius"]),
        ("NUL byte", "[robot]\nradius = 0.2\0\n".into(), &["line 2"]),
        ("unterminated", "[robot\nradius = 0.2\n".into(), &["line 1"]),
    ];
    for (what, input, wants) in cases {
        let e = Config::from_toml(&input, "hostile.toml").expect_err(what);
        check_error(&e, input.len());
        let msg = e.to_string();
        for want in wants {
            assert!(msg.contains(want), "{what}: want {want:?} in: {msg}");
        }
    }
}

#[test]
fn the_daemon_keys_are_read_from_the_file() {
    let text = "[daemon]\nstuck_after = 7.5\nscan_timeout = 0.4\n[daemon.contact]\nside_bearing = 0.4\nsettle = 0.5\n";
    let cfg = Config::from_toml(text, "t.toml").unwrap();
    assert_eq!(cfg.daemon.stuck_after, 7.5);
    assert_eq!(cfg.daemon.scan_timeout, 0.4);
    assert_eq!(cfg.daemon.contact.side_bearing, 0.4);
    assert_eq!(cfg.daemon.contact.settle, 0.5);
    let def = sweepline::daemon::DaemonParams::default();
    assert_eq!(cfg.daemon.contact.gap, def.contact.gap);
}

#[test]
fn the_zero_budget_is_named_by_its_dotted_key_too() {
    let e = Config::from_toml("[pipeline.budget]\nmotor = 0.0\n", "t.toml").unwrap_err();
    assert!(e.to_string().contains("pipeline.budget.motor"), "{e}");
}

#[test]
fn bad_files_are_clear_errors() {
    let dir = std::env::temp_dir().join(format!("sweepline-cfg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let missing = Config::load(Path::new("/nonexistent/robot.toml")).unwrap_err();
    assert!(
        missing.to_string().contains("/nonexistent/robot.toml"),
        "{missing}"
    );
    let e = Config::load(&dir).unwrap_err();
    assert!(e.to_string().contains(&dir.display().to_string()), "{e}");
    let bin = dir.join("binary.toml");
    std::fs::write(&bin, b"[robot]\nradius = \xff\xfe\n").unwrap();
    let e = Config::load(&bin).unwrap_err();
    assert!(e.to_string().contains("not UTF-8"), "{e}");
    let big = dir.join("big.toml");
    std::fs::write(&big, vec![b'#'; MAX_CONFIG_BYTES as usize + 10]).unwrap();
    let e = Config::load(&big).unwrap_err();
    assert!(e.to_string().contains("larger than"), "{e}");
    let ok = dir.join("ok.toml");
    std::fs::write(&ok, shipped()).unwrap();
    assert_eq!(
        Config::load(&ok).unwrap().pipeline,
        Config::default().pipeline
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
