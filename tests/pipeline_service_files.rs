//! The shipped systemd unit and udev rules: the directives the daemon relies
//! on are present, every udev rule line is well-formed, real-time priority
//! is refused as shipped and granted by `systemd/realtime.conf`, the live
//! view is unreachable as shipped and loopback-only with
//! `systemd/live-view.conf`, and, where `systemd-analyze` is installed, the
//! unit (alone and with each drop-in) verifies without a warning.

use std::process::Command;

const UNIT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/systemd/sweepline.service");
const RULES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/hw/99-sweepline.rules");

fn directives(text: &str) -> Vec<(String, String)> {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with('['))
        .filter_map(|l| l.split_once('='))
        .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
        .collect()
}

#[test]
fn unit_has_the_directives_the_daemon_relies_on() {
    let text = std::fs::read_to_string(UNIT).unwrap();
    let d = directives(&text);
    let has = |k: &str, v: &str| d.iter().any(|(dk, dv)| dk == k && dv == v);
    for (k, v) in [
        ("Type", "notify"),
        ("NotifyAccess", "main"),
        ("WatchdogSec", "2s"),
        ("Restart", "on-failure"),
        ("User", "sweepline"),
        ("DevicePolicy", "closed"),
        ("DeviceAllow", "char-ttyACM rw"),
        ("DeviceAllow", "char-ttyUSB rw"),
        ("ProtectSystem", "strict"),
        ("StateDirectory", "sweepline"),
        ("NoNewPrivileges", "yes"),
    ] {
        assert!(has(k, v), "{k}={v} missing from the unit");
    }
    assert!(d.iter().any(|(k, _)| k == "CPUQuota"));
    assert!(d
        .iter()
        .any(|(k, v)| k == "ExecStart" && v.contains(" run --config ")));
    // The stable names the udev rules create are what the unit waits for.
    assert!(text.contains(r"dev-sweepline\x2durg.device"));
    assert!(text.contains(r"dev-sweepline\x2dbase.device"));
}

/// Whether `systemd-analyze` is here; says `skipped:` when it is not.
fn have_systemd_analyze() -> bool {
    let probe = Command::new("systemd-analyze").arg("--version").output();
    if probe.map(|o| !o.status.success()).unwrap_or(true) {
        eprintln!("skipped: systemd-analyze is not installed");
        return false;
    }
    true
}

/// `systemd-analyze verify` on the unit text `text` (its ExecStart pointed
/// at the test's binary, since verify checks that it exists), written to a
/// fresh folder named `tag`: no complaint about the file.
fn assert_verifies(tag: &str, text: &str) {
    let dir = std::env::temp_dir().join(format!("sweepline-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let text = text.replace("/usr/local/bin/sweepline", env!("CARGO_BIN_EXE_sweepline"));
    let unit = dir.join("sweepline.service");
    std::fs::write(&unit, text).unwrap();
    let out = Command::new("systemd-analyze")
        .arg("verify")
        .arg(&unit)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    // Without a running systemd, verify may complain about the manager
    // itself; only complaints about our file count.
    let ours: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("sweepline.service"))
        .collect();
    assert!(
        out.status.success() && ours.is_empty(),
        "systemd-analyze verify: {err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn unit_verifies_with_systemd_analyze() {
    if have_systemd_analyze() {
        assert_verifies("unit", &std::fs::read_to_string(UNIT).unwrap());
    }
}

#[test]
fn udev_rules_are_well_formed_and_name_both_devices() {
    let text = std::fs::read_to_string(RULES).unwrap();
    let rules: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    assert_eq!(rules.len(), 4);
    for r in &rules {
        for part in r.split(", ") {
            let op = ["==", "!=", "+=", ":=", "="]
                .iter()
                .find(|op| part.contains(*op))
                .unwrap_or_else(|| panic!("no operator in `{part}` of `{r}`"));
            let (key, value) = part.split_once(op).unwrap();
            assert!(
                key.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "{}_".contains(c)),
                "bad key `{key}` in `{r}`"
            );
            assert!(
                value.starts_with('"') && value.ends_with('"') && value.len() >= 2,
                "unquoted value in `{part}`"
            );
        }
    }
    let with = |vendor: &str, product: &str, link: &str| {
        rules.iter().any(|r| {
            r.contains(&format!("ATTRS{{idVendor}}==\"{vendor}\""))
                && r.contains(&format!("ATTRS{{idProduct}}==\"{product}\""))
                && r.contains(&format!("SYMLINK+=\"{link}\""))
                && r.contains("TAG+=\"systemd\"")
                && r.contains("MODE=\"0660\"")
        })
    };
    assert!(with("15d1", "0000", "sweepline-urg"), "URG-04LX rule");
    assert!(with("03eb", "2404", "sweepline-base"), "RoboClaw rule");
    assert!(with("0403", "6001", "sweepline-base"), "Create 2 FTDI rule");
}

/// The system-call filter a unit's `[Service]` lines leave, read as systemd
/// does: an empty assignment resets it; `~` lines deny, others allow.
fn filter(lines: &[(String, String)]) -> (Vec<String>, Vec<String>) {
    let (mut allow, mut deny) = (Vec::new(), Vec::new());
    for (_, v) in lines.iter().filter(|(k, _)| k == "SystemCallFilter") {
        if v.is_empty() {
            allow.clear();
            deny.clear();
        } else if let Some(d) = v.strip_prefix('~') {
            deny.extend(d.split_whitespace().map(str::to_string));
        } else {
            allow.extend(v.split_whitespace().map(str::to_string));
        }
    }
    (allow, deny)
}

fn last<'a>(lines: &'a [(String, String)], key: &str) -> Option<&'a str> {
    lines
        .iter()
        .rev()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

const DROP_IN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/systemd/realtime.conf");

#[test]
fn real_time_priority_is_refused_as_shipped_and_granted_by_the_drop_in() {
    let unit = directives(&std::fs::read_to_string(UNIT).unwrap());
    // As shipped: no real-time scheduling, and the calls for it denied.
    assert_eq!(last(&unit, "RestrictRealtime"), Some("yes"));
    assert!(last(&unit, "LimitRTPRIO").is_none());
    let (_, deny) = filter(&unit);
    assert!(deny.iter().any(|d| d == "@resources"), "{deny:?}");
    // With the drop-in (read after the unit, as systemd reads drop-ins).
    let mut both = unit.clone();
    both.extend(directives(&std::fs::read_to_string(DROP_IN).unwrap()));
    assert_eq!(last(&both, "RestrictRealtime"), Some("no"));
    assert_eq!(last(&both, "LimitRTPRIO"), Some("20"));
    let (allow, deny) = filter(&both);
    assert!(allow.iter().any(|a| a == "@system-service"), "{allow:?}");
    assert!(deny.iter().any(|d| d == "@privileged"), "{deny:?}");
    for call in ["@resources", "sched_setscheduler", "sched_setparam"] {
        assert!(
            !deny.iter().any(|d| d == call),
            "{call} still denied: {deny:?}"
        );
    }
}

/// Where `systemd-analyze` is installed: the unit with the drop-in at
/// `drop_in` (its [Service] lines put at the end of the unit's [Service],
/// what systemd makes of the pair) verifies without a warning.
fn verifies_with_drop_in(tag: &str, drop_in: &str) {
    if !have_systemd_analyze() {
        return;
    }
    let unit = std::fs::read_to_string(UNIT).unwrap();
    let drop_in = std::fs::read_to_string(drop_in).unwrap();
    let (_, service_lines) = drop_in.split_once("[Service]").unwrap();
    let (head, install) = unit.split_once("[Install]").unwrap();
    assert_verifies(tag, &format!("{head}{service_lines}\n[Install]{install}"));
}

#[test]
fn unit_with_the_real_time_drop_in_verifies_with_systemd_analyze() {
    verifies_with_drop_in("unit-rt", DROP_IN);
}

const LIVE_DROP_IN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/systemd/live-view.conf");

/// As shipped the unit has no network at all (the live view cannot be
/// reached); `systemd/live-view.conf` opens IP sockets to and from the
/// loopback addresses only.
#[test]
fn the_live_view_is_unreachable_as_shipped_and_loopback_only_with_the_drop_in() {
    let unit = directives(&std::fs::read_to_string(UNIT).unwrap());
    assert_eq!(last(&unit, "PrivateNetwork"), Some("yes"));
    assert_eq!(last(&unit, "RestrictAddressFamilies"), Some("AF_UNIX"));
    let mut both = unit.clone();
    both.extend(directives(&std::fs::read_to_string(LIVE_DROP_IN).unwrap()));
    assert_eq!(last(&both, "PrivateNetwork"), Some("no"));
    let families = last(&both, "RestrictAddressFamilies").unwrap_or_default();
    assert!(families.contains("AF_INET"), "{families}");
    assert_eq!(last(&both, "IPAddressDeny"), Some("any"));
    assert_eq!(last(&both, "IPAddressAllow"), Some("localhost"));
}

#[test]
fn unit_with_the_live_view_drop_in_verifies_with_systemd_analyze() {
    verifies_with_drop_in("unit-live", LIVE_DROP_IN);
}
