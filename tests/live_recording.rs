//! The recording and the live view of a simulated run, read by clients
//! nobody here wrote: `run.mcap` through the MCAP crate (the SDK's
//! messages decoded by their own types), the live view through a plain
//! WebSocket client speaking the Foxglove WebSocket protocol under both of
//! its subprotocol names, and a recording cut short by `kill -9`.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use foxglove::Decode;
use sweepline::config::Config;
use sweepline::daemon::shared::OdomLog;
use sweepline::daemon::taps::ScanRecord;
use sweepline::live::{topics, Recording};
use sweepline::sim::closed_loop::{self, SimOptions, SimReport};
use sweepline::sim::world::World;

/// A 3.2 m × 2.6 m room with a box.
const SMALL: &str = "name live-small\nresolution 0.02\n\
room 0 0 3.2 0 3.2 2.6 0 2.6 refl 0.55\n\
box 1.8 1.0 2.3 1.5 refl 0.8\n\
start 0.5 0.5 0.0\n";

fn config() -> Config {
    Config::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("hw/robot.toml")).unwrap()
}

fn out_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// The small room for `cap` simulated seconds, recorded into `out`.
fn short_run(out: &Path, cap: f64, live: Option<String>) -> SimReport {
    // The log lines reach `/log` through the logger the binary installs.
    sweepline::live::logs::install_quiet();
    let mut opts = SimOptions::new(World::parse(SMALL).unwrap(), config());
    opts.speed = 8.0;
    opts.time_cap = cap;
    opts.out = Some(out.to_path_buf());
    opts.live = live;
    closed_loop::run(&opts).unwrap()
}

/// Dropped messages of the report's edge `name`.
fn dropped(r: &SimReport, name: &str) -> u64 {
    let e = r.pipeline.edges.iter().find(|e| e.name == name);
    e.unwrap_or_else(|| panic!("no edge {name}")).dropped
}

fn sent(r: &SimReport, name: &str) -> u64 {
    let e = r.pipeline.edges.iter().find(|e| e.name == name);
    e.unwrap_or_else(|| panic!("no edge {name}")).sent
}

/// Per topic: schema name, encoding, and the messages.
type Topics = BTreeMap<String, (String, String, Vec<(u64, Vec<u8>)>)>;

fn read_topics(path: &Path) -> Topics {
    let bytes = std::fs::read(path).unwrap();
    let mut out = Topics::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let e = out.entry(m.channel.topic.clone()).or_insert_with(|| {
            (
                m.channel
                    .schema
                    .as_ref()
                    .map(|s| s.name.clone())
                    .unwrap_or_default(),
                m.channel.message_encoding.clone(),
                Vec::new(),
            )
        });
        e.2.push((m.log_time, m.data.to_vec()));
    }
    out
}

#[test]
fn a_sim_run_is_recorded_on_every_channel_with_its_schema() {
    let out = out_dir("live-record");
    let r = short_run(&out, 45.0, None);
    let topics = read_topics(&out.join("run.mcap"));
    let expect = [
        (topics::SCAN, "foxglove.LaserScan", "protobuf"),
        (topics::SCAN_INPUT, "sweepline.ScanInput", "json"),
        (topics::ODOMETRY_INPUT, "sweepline.OdometryInput", "json"),
        (topics::POSE, "foxglove.PoseInFrame", "protobuf"),
        (topics::ODOM, "foxglove.PoseInFrame", "protobuf"),
        (topics::TF, "foxglove.FrameTransform", "protobuf"),
        (topics::MAP, "foxglove.Grid", "protobuf"),
        (topics::SWEPT, "foxglove.Grid", "protobuf"),
        (topics::PLAN, "foxglove.SceneUpdate", "protobuf"),
        (topics::LOG, "foxglove.Log", "protobuf"),
        (topics::STATUS, "sweepline.Status", "json"),
        (topics::TRUTH, "foxglove.PoseInFrame", "protobuf"),
    ];
    for (topic, schema, encoding) in expect {
        let (s, e, msgs) = topics.get(topic).unwrap_or_else(|| panic!("no {topic}"));
        assert_eq!((s.as_str(), e.as_str()), (schema, encoding), "{topic}");
        assert!(!msgs.is_empty(), "{topic}: no message");
        assert!(
            msgs.windows(2).all(|w| w[0].0 <= w[1].0),
            "{topic}: log times go backwards"
        );
    }
    // Every scan the scanner stage handed on, none lost to the recorder
    // (the last one may be copied while the stages stop, after the
    // report's count; a loaded machine may make the localise stage skip
    // one: then there are fewer poses than scans).
    assert_eq!(dropped(&r, "tap_scans"), 0);
    let delivered = sent(&r, "scans") as usize;
    assert!(delivered > 300, "{delivered} scans");
    let recorded = topics[topics::SCAN].2.len();
    assert!(
        (delivered..=delivered + 1).contains(&recorded),
        "{recorded} scans recorded, {delivered} delivered"
    );
    assert_eq!(topics[topics::SCAN_INPUT].2.len(), recorded);
    assert_eq!(topics[topics::POSE].2.len() as u64, r.scans.0);
    // The LaserScan shows the very scan the localise stage got.
    // (A scan input without angles has the scan before's.)
    let mut angles: Vec<f64> = Vec::new();
    for (k, ((_, laser), (_, input))) in topics[topics::SCAN]
        .2
        .iter()
        .zip(&topics[topics::SCAN_INPUT].2)
        .enumerate()
    {
        let l = foxglove::schemas::LaserScan::decode(&laser[..]).unwrap();
        let mut s: ScanRecord = serde_json::from_slice(input).unwrap();
        if s.angles.is_empty() {
            assert!(k > 0, "the first scan input has its angles");
            s.angles.clone_from(&angles);
        }
        angles.clone_from(&s.angles);
        assert_eq!(l.ranges.len(), s.ranges.len());
        for (i, (a, b)) in l.ranges.iter().zip(&s.ranges).enumerate() {
            if s.invalid.contains(&(i as u32)) {
                assert!(a.is_nan(), "beam {i}: an invalid beam is NaN");
            } else {
                assert_eq!(a, b, "beam {i}");
            }
        }
        assert_eq!(l.intensities, s.intensities);
        assert_eq!(l.start_angle, s.angles[0]);
    }
    // Our own reader gets the same scans back, with the setup and truth.
    let rec = Recording::read(&out.join("run.mcap")).unwrap();
    assert!(rec.complete);
    assert_eq!(rec.scans.len(), recorded);
    odometry_is_whole(&r, &rec);
    assert!(rec.setup.as_ref().is_some_and(|s| s.is_ok()));
    assert!(rec.map_to_world.is_some());
    assert!(
        rec.truth.len() >= delivered / 2,
        "{} truth samples",
        rec.truth.len()
    );
    // `sweepline replay run.mcap`, then `sweepline eval --truth run.mcap`.
    let bin = env!("CARGO_BIN_EXE_sweepline");
    let replayed = out.join("replay");
    let st = Command::new(bin)
        .arg("replay")
        .arg(out.join("run.mcap"))
        .arg("--out")
        .arg(&replayed)
        .stderr(Stdio::null())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&st.stdout);
    assert!(st.status.success(), "{text}");
    assert!(
        text.contains("against the recorded truth: position RMSE"),
        "{text}"
    );
    let ev = Command::new(bin)
        .arg("eval")
        .arg(replayed.join("trajectory.txt"))
        .arg("--truth")
        .arg(out.join("run.mcap"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&ev.stdout);
    assert!(ev.status.success(), "{text}");
    let mm: f64 = text
        .split("position RMSE ")
        .nth(1)
        .and_then(|r| r.split(" mm").next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{text}"));
    assert!(mm < 30.0, "replayed position RMSE {mm} mm");
}

/// The recorded wheel odometry is every reading the motor stage took, and
/// integrated as the daemon integrates it, it gives the odometry pose each
/// scan was paired with (to the last bits of a heading written as an angle).
fn odometry_is_whole(r: &SimReport, rec: &Recording) {
    assert_eq!(dropped(r, "tap_odometry"), 0);
    let odo = &rec.odometry;
    assert!(odo.len() > 30 * 45, "{} odometry readings", odo.len());
    // Each reading starts where the one before ended: none is missing.
    for w in odo.windows(2) {
        assert_eq!(w[1].t0, w[0].t1, "a gap in the odometry");
        assert!(w[1].t1 >= w[1].t0);
    }
    let log = OdomLog::default();
    let mut next = 0;
    let mut checked = 0;
    for s in rec.scans.iter().filter(|s| s.odom_current) {
        // Readings up to the first at or after the scan, as the daemon had
        // them when it paired the scan.
        while next < odo.len() && (next == 0 || odo[next - 1].t1 < s.stamp) {
            let o = odo[next].to_odometry();
            log.push(o.t1, &o.delta);
            next += 1;
        }
        let p = log.at(s.stamp);
        let xyt = [p.translation.x, p.translation.y, p.rotation.angle()];
        let off = xyt.iter().zip(&s.odom).map(|(a, b)| (a - b).abs());
        assert!(
            off.fold(0.0, f64::max) < 1e-12,
            "scan {}: {xyt:?} against {:?}",
            s.seq,
            s.odom
        );
        checked += 1;
    }
    assert!(
        checked * 10 > rec.scans.len() * 9,
        "{checked} scans checked"
    );
}

/// A port free right now on the loopback address.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A live-view client: the subprotocol it offered and was given, and the
/// messages it received per topic.
fn viewer(
    port: u16,
    protocol: &'static str,
    read: bool,
) -> std::thread::JoinHandle<(String, BTreeMap<String, usize>)> {
    std::thread::spawn(move || {
        use tungstenite::client::IntoClientRequest;
        use tungstenite::Message;
        let deadline = Instant::now() + Duration::from_secs(60);
        let (mut ws, resp) = loop {
            let mut req = format!("ws://127.0.0.1:{port}/")
                .into_client_request()
                .unwrap();
            req.headers_mut()
                .insert("Sec-WebSocket-Protocol", protocol.parse().unwrap());
            match std::net::TcpStream::connect(("127.0.0.1", port)) {
                Ok(s) => match tungstenite::client(req, s) {
                    Ok(c) => break c,
                    Err(e) => panic!("{protocol}: handshake refused: {e}"),
                },
                Err(_) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(50))
                }
                Err(e) => panic!("cannot connect: {e}"),
            }
        };
        let given = resp
            .headers()
            .get("sec-websocket-protocol")
            .map(|v| v.to_str().unwrap().to_string())
            .unwrap_or_default();
        let mut channels: BTreeMap<u64, String> = BTreeMap::new();
        let mut counts: BTreeMap<String, usize> = BTreeMap::new();
        let mut subscribed = false;
        let until = Instant::now() + Duration::from_secs(20);
        while Instant::now() < until {
            let Ok(m) = ws.read() else { break };
            match m {
                Message::Text(t) => {
                    let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
                    if v["op"] == "advertise" {
                        for c in v["channels"].as_array().unwrap() {
                            channels.insert(
                                c["id"].as_u64().unwrap(),
                                c["topic"].as_str().unwrap().into(),
                            );
                        }
                    }
                }
                Message::Binary(b) => {
                    assert_eq!(b[0], 1, "message data opcode");
                    let sub = u32::from_le_bytes(b[1..5].try_into().unwrap()) as u64;
                    *counts.entry(channels[&sub].clone()).or_default() += 1;
                }
                _ => {}
            }
            if !subscribed && channels.values().any(|t| t == topics::POSE) {
                // Subscription id = channel id, so the data names its topic.
                let subs: Vec<_> = channels
                    .keys()
                    .map(|id| serde_json::json!({"id": id, "channelId": id}))
                    .collect();
                let msg = serde_json::json!({"op": "subscribe", "subscriptions": subs});
                ws.send(Message::Text(msg.to_string().into())).unwrap();
                subscribed = true;
                if !read {
                    // Subscribed to everything, then never reads again.
                    std::thread::sleep(Duration::from_secs(30));
                    break;
                }
            }
            if counts.get(topics::SCAN).is_some_and(|&n| n >= 20)
                && counts.get(topics::POSE).is_some_and(|&n| n >= 20)
            {
                break;
            }
        }
        (given, counts)
    })
}

#[test]
fn the_live_view_serves_both_subprotocol_names() {
    let out = out_dir("live-view");
    let port = free_port();
    let old = viewer(port, "foxglove.websocket.v1", true);
    let sdk = viewer(port, "foxglove.sdk.v1", true);
    let r = short_run(&out, 60.0, Some(format!("127.0.0.1:{port}")));
    for (client, name) in [(old, "foxglove.websocket.v1"), (sdk, "foxglove.sdk.v1")] {
        let (given, counts) = client.join().unwrap();
        assert_eq!(given, name, "the subprotocol the server chose");
        assert!(
            counts.get(topics::SCAN).is_some_and(|&n| n >= 20),
            "{name}: {counts:?}"
        );
        assert!(
            counts.get(topics::POSE).is_some_and(|&n| n >= 20),
            "{name}: {counts:?}"
        );
    }
    assert_eq!(dropped(&r, "tap_scans"), 0, "recorded scans lost");
}

/// Alone on the machine (the slow tier runs one test at a time), so that
/// a skipped scan can only be the viewer's doing.
#[test]
#[ignore = "slow tier: needs a quiet machine; cargo test --release -- --ignored"]
fn a_viewer_that_never_reads_costs_no_scan() {
    let out = out_dir("live-stalled");
    let port = free_port();
    let stalled = viewer(port, "foxglove.sdk.v1", false);
    let r = short_run(&out, 240.0, Some(format!("127.0.0.1:{port}")));
    let _ = stalled.join();
    assert_eq!(dropped(&r, "scans"), 0, "scans lost while a viewer stalled");
    assert_eq!(dropped(&r, "tap_scans"), 0, "recorded scans lost");
    assert_eq!(r.scans.0, sent(&r, "scans"), "every scan localised");
}

#[test]
fn a_killed_run_leaves_a_recording_readable_to_its_last_second() {
    let out = out_dir("live-kill");
    let mut child = Command::new(env!("CARGO_BIN_EXE_sweepline"))
        .args(["sim", "--live", "off", "--time-cap", "600", "--out"])
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Progress lines: "  W s wall  T s sim  coverage ...": kill after the
    // third, remembering its simulated time.
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut seen = 0;
    let mut sim_time = 0.0;
    for line in lines.by_ref() {
        let line = line.unwrap();
        if let Some(t) = line
            .split("s wall")
            .nth(1)
            .and_then(|r| r.split(" s sim").next())
        {
            sim_time = t.trim().parse::<f64>().unwrap();
            seen += 1;
            if seen == 3 {
                break;
            }
        }
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(sim_time > 5.0, "progress at {sim_time} s");
    let rec = Recording::read(&out.join("run.mcap")).unwrap();
    assert!(!rec.complete, "a killed writer leaves no footer");
    let first = rec.scans.first().unwrap().stamp;
    let last = rec.scans.last().unwrap().stamp;
    // The progress line was printed before the kill: at most the open
    // chunk and the last flush period are lost.
    assert!(
        last - first >= sim_time - 2.0,
        "scans to {:.1} s kept, {sim_time:.1} s simulated before the kill",
        last - first
    );
}
