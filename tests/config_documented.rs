//! The shipped `hw/robot.toml` documents the whole configuration: every key
//! any module's `*Params` struct has appears in it, and every key line has a
//! comment line right above it.

use sweepline::config::Config;

const PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/hw/robot.toml");

/// Dotted paths of every leaf key in `t`.
fn leaves(prefix: &str, t: &toml::Table, out: &mut Vec<String>) {
    for (k, v) in t {
        let path = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            toml::Value::Table(sub) => leaves(&path, sub, out),
            _ => out.push(path),
        }
    }
}

#[test]
fn every_config_key_is_in_the_shipped_file() {
    let text = std::fs::read_to_string(PATH).unwrap();
    let shipped: toml::Table = text.parse().unwrap();
    let defaults = toml::Table::try_from(Config::default()).unwrap();
    let (mut want, mut have) = (Vec::new(), Vec::new());
    leaves("", &defaults, &mut want);
    leaves("", &shipped, &mut have);
    let missing: Vec<&String> = want.iter().filter(|k| !have.contains(k)).collect();
    assert!(
        missing.is_empty(),
        "keys missing from hw/robot.toml: {missing:?}"
    );
}

#[test]
fn every_key_line_has_a_comment_above_it() {
    let text = std::fs::read_to_string(PATH).unwrap();
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    let mut undocumented = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let is_key = !l.is_empty() && !l.starts_with('#') && !l.starts_with('[') && l.contains('=');
        if is_key && (i == 0 || !lines[i - 1].starts_with('#')) {
            undocumented.push(format!("line {}: {l}", i + 1));
        }
    }
    assert!(
        undocumented.is_empty(),
        "keys without a comment: {undocumented:?}"
    );
}
