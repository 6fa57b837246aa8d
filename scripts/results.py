#!/usr/bin/env python3
"""Regenerates the results tables: runs the command behind each figure,
stores what it measured in docs/results.json (figure, date, version, command)
and rewrites the table of current figures in docs/results.md (between its
`results:begin` / `results:end` markers) and every `<!-- fig:KEY -->...
<!-- /fig -->` span in README.md and docs/*.md from that file. No figure in
those tables is edited by hand.

Usage: scripts/results.py [KEY...] [--list] [--write-only] [--reuse] [--out DIR]
  KEY           rows to measure again (default: none; `all`: every row)
  --list        the rows, their commands and when each was last measured
  --write-only  rewrite the tables from docs/results.json, measuring nothing
  --reuse       read `sweepline sim` run folders already in DIR instead of
                running them again (the other commands run anyway)
  --out DIR     where the runs write their folders (default: out/results)

Builds target/release/sweepline first (cargo build --release). Rows that
need ../shared fail with a message when it is missing. The closed loop's
figures spread between runs (thread timing): the main job is given for
three seeds. Machines are shared: a timing stands for the run it came from.
"""
import datetime
import json
import math
import os
import re
import subprocess
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import covrun  # noqa: E402
import simrun  # noqa: E402

BIN = os.path.join(ROOT, "target", "release", "sweepline")
STORE = os.path.join(ROOT, "docs", "results.json")
RESULTS_MD = os.path.join(ROOT, "docs", "results.md")
BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
SEEDS = (1, 2, 3)


def sh(cmd, **kw):
    """Runs `cmd` (a list) from the repository root; its output as text."""
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, **kw)
    if p.returncode not in (0, 3):
        raise RuntimeError(f"{' '.join(cmd)} exited {p.returncode}:\n{p.stdout[-800:]}\n{p.stderr[-800:]}")
    return p.stdout + p.stderr


def cell(md, name):
    """The value column of the summary.md row starting with `name`."""
    m = re.search(r"^\| " + re.escape(name) + r"[^|]*\|\s*([^|]*)\|", md, re.M)
    return m.group(1).strip() if m else ""


def nums(text):
    return [float(v) for v in re.findall(r"-?[0-9]+(?:\.[0-9]+)?", text)]


REUSE = False


def sim_run(out, name, args):
    """One `sweepline sim` run into OUT/NAME; its summary.md and report.md."""
    d = os.path.join(out, name)
    if not (REUSE and os.path.exists(os.path.join(d, "report.md"))):
        sh([BIN, "sim", "--out", d, *args])
    read = lambda f: open(os.path.join(d, f)).read()
    return read("summary.md"), read("report.md")


def span(vals, fmt="{:.2f}"):
    lo, hi = min(vals), max(vals)
    return fmt.format(lo) if lo == hi else f"{fmt.format(lo)}-{fmt.format(hi)}"


def main_job(out, extra, tag):
    """The default room, seeds 1-3, with `extra` options."""
    cov, ov, pos, head, wall, simt, e2e = [], [], [], [], [], [], []
    for s in SEEDS:
        md, _ = sim_run(out, f"{tag}_s{s}", ["--seed", str(s), *extra])
        cov.append(nums(cell(md, "coverage of reachable floor"))[0])
        ov.append(nums(cell(md, "overlap"))[0])
        loc = nums(cell(md, "localisation error at scan times"))
        pos.append(loc[0])
        head.append(loc[2])
        wall.append(nums(cell(md, "wall time"))[0])
        simt.append(nums(cell(md, "simulated time"))[0])
        e2e.append(nums(cell(md, "end-to-end latency"))[:2])
    return (f"coverage {span(cov)} %, overlap {span(ov, '{:.1f}')} %, "
            f"pose RMSE {span(pos, '{:.1f}')} mm / {span(head)}°, "
            f"end-to-end p50 {span([e[0] for e in e2e])} ms, p99 {span([e[1] for e in e2e])} ms; "
            f"{span(simt, '{:.0f}')} s simulated in {span(wall, '{:.1f}')} s wall")


def row_main(out):
    return main_job(out, [], "main")


def row_main_fixed5(out):
    return main_job(out, ["--speed", "5", "--fixed-speed"], "fixed5")


def row_realtime(out):
    md, rep = sim_run(out, "realtime", ["--speed", "1", "--fixed-speed", "--time-cap", "600"])
    m = re.search(r"the process without them: ([0-9.]+) % of one core", rep)
    cpu = m.group(1) if m else "?"
    e2e = nums(cell(md, "end-to-end latency"))
    return f"daemon CPU {cpu} % of one core (budget 5 %); end-to-end p50 {e2e[0]:.2f} ms, p99 {e2e[1]:.2f} ms"


def ws_viewer(port, seconds, counts, stall=False):
    """A minimal Foxglove WebSocket viewer (stdlib only): connects to the
    live view on `port`, subscribes to every channel and reads for
    `seconds`, counting binary message frames into `counts["messages"]`;
    with `stall`, never reads again once subscribed (a stalled viewer)."""
    import base64, json as _json, socket, struct, time as _time
    deadline = _time.monotonic() + 30
    while True:
        try:
            sock = socket.create_connection(("127.0.0.1", port), timeout=5)
            break
        except OSError:
            if _time.monotonic() > deadline:
                return
            _time.sleep(0.2)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                  "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n").encode())
    buf = b""
    while b"\r\n\r\n" not in buf:
        buf += sock.recv(4096)
    buf = buf.split(b"\r\n\r\n", 1)[1]

    def need(n):
        nonlocal buf
        while len(buf) < n:
            chunk = sock.recv(65536)
            if not chunk:
                raise EOFError
            buf += chunk
        out, buf = buf[:n], buf[n:]
        return out

    def send_text(text):
        data, mask = text.encode(), os.urandom(4)
        head = bytes([0x81]) + (bytes([0x80 | len(data)]) if len(data) < 126
                                else bytes([0x80 | 126]) + struct.pack(">H", len(data)))
        sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))

    end = _time.monotonic() + seconds
    sock.settimeout(1.0)
    while _time.monotonic() < end:
        try:
            b0, b1 = need(2)
            n = b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", need(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", need(8))[0]
            payload = need(n)
        except (socket.timeout, EOFError, OSError):
            if _time.monotonic() >= end:
                break
            continue
        if b0 & 0x0F == 1:
            msg = _json.loads(payload)
            if msg.get("op") == "advertise":
                subs = [{"id": c["id"], "channelId": c["id"]} for c in msg["channels"]]
                send_text(_json.dumps({"op": "subscribe", "subscriptions": subs}))
                if stall:
                    _time.sleep(max(0.0, end - _time.monotonic()))
                    break
        elif b0 & 0x0F == 2:
            counts["messages"] = counts.get("messages", 0) + 1
    sock.close()


LIVE_THREADS = ("telemetry", "live-view", "live-accept", "live-client", "live-client-up")


def live_threads_share(rep):
    """The share of one core (%) of the report's telemetry and live-view
    threads (its CPU-by-thread table), 0 when none ran."""
    total = 0.0
    for name, share in re.findall(r"^\| ([a-z-]+) \| [0-9.]+ s \| ([0-9.]+) % \|", rep, re.M):
        if name in LIVE_THREADS:
            total += float(share)
    return total


def row_live_cost(out):
    import socket, threading
    secs = 180
    base = ["--speed", "1", "--fixed-speed", "--time-cap", str(secs), "--seed", "1"]
    figs = []
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    counts = {}
    for name, extra in [("neither", ["--live", "off", "--no-record"]),
                        ("recording", ["--live", "off"]),
                        ("recording and a viewer", ["--live", f"127.0.0.1:{port}"]),
                        ("recording and a stalled viewer", ["--live", f"127.0.0.1:{port}"])]:
        viewer = None
        if "--live" in extra and extra[extra.index("--live") + 1] != "off":
            stall = "stalled" in name
            viewer = threading.Thread(target=ws_viewer, args=(port, secs + 20, {} if stall else counts, stall),
                                      daemon=True)
            viewer.start()
        md, rep = sim_run(out, "live-" + name.replace(" ", "-"), base + extra)
        if viewer:
            viewer.join(timeout=60)
        m = re.search(r"the process without them: ([0-9.]+) % of one core", rep)
        e2e = nums(cell(md, "end-to-end latency"))
        drops = re.search(r"^\| scans \|[^|]*\|[^|]*\|[^|]*\|[^|]*\| *([0-9]+)", rep, re.M)
        live = live_threads_share(rep)
        figs.append(f"{name}: CPU {m.group(1) if m else '?'} % of one core"
                    + (f" (of which the telemetry and live-view threads {live:.2f} %)" if live else "")
                    + f", end-to-end p99 {e2e[1]:.2f} ms, scans dropped {drops.group(1) if drops else '?'}")
    mcap = os.path.join(out, "live-recording", "run.mcap")
    size = os.path.getsize(mcap) / 1e6 if os.path.exists(mcap) else 0
    return ("; ".join(figs) + f" (the viewer read {counts.get('messages', 0)} messages); "
            f"recording {size / secs * 3600:.0f} MB per hour")


def row_lockstep24(out):
    rooms = covrun.expand(["@rooms24"])
    rs = covrun.run_all(BIN, os.path.join(ROOT, "hw", "robot.toml"), os.path.join(out, "rooms24"), rooms)
    bad = [r for r in rs if "error" in r]
    if bad:
        raise RuntimeError(f"lock-step runs failed: {bad[:2]}")
    n = len(rs)
    mean = lambda k: sum(r[k] for r in rs) / n
    low = min(rs, key=lambda r: r["cov_on"])
    return (f"{n} rooms: coverage {mean('cov_on'):.2f} / {mean('cov_off'):.2f} % mean (online / room known), "
            f"lowest {low['cov_on']:.2f} % ({low['world']}); overlap {mean('ov_on'):.1f} / {mean('ov_off'):.1f} %; "
            f"path at most {max(r['ratio'] for r in rs):.3f} × the room-known one")


def row_closed12(out):
    rs = []
    os.makedirs(os.path.join(out, "closed12"), exist_ok=True)
    for w in covrun.TEST12:
        rs.append(simrun.run(BIN, os.path.join(out, "closed12"), w, 1, []))
    ok = [r for r in rs if r and r["cov"] is not None]
    if len(ok) != len(rs):
        raise RuntimeError("a closed-loop room wrote no report")
    n = len(ok)
    return (f"coverage {min(r['cov'] for r in ok):.2f}-{max(r['cov'] for r in ok):.2f} %, "
            f"mean {sum(r['cov'] for r in ok) / n:.2f} %; overlap mean {sum(r['ov'] for r in ok) / n:.1f} %; "
            f"collisions {sum(r['coll'] for r in ok):.0f}")


def row_doorway(out):
    md, _ = sim_run(out, "doorway", ["--world", "hw/worlds/doorway.world"])
    cov = nums(cell(md, "coverage of reachable floor"))[0]
    return f"{cov:.2f} %, contacts with a person: {cell(md, 'contacts with a person') or '0'}"


def eval_groups(text):
    """(translation m, rotation °) of the `all` and `<= 1 s` lines of `sweepline eval`."""
    groups = {}
    for name in ("all", "<= 1 s"):
        m = re.search(r"^" + re.escape(name) + r"\s+\d+\s+([0-9.]+) ±\s*\S+\s+\S+ ±\s*\S+\s+([0-9.]+) ±", text, re.M)
        if not m:
            raise RuntimeError(f"no `{name}` line in the eval output:\n{text}")
        groups[name] = (float(m.group(1)), float(m.group(2)))
    return groups


def row_csail(out):
    d = os.path.join(out, "csail")
    log = os.path.join(ROOT, "..", "shared", "datasets", "mit-csail", "mit-csail.clf")
    rel = os.path.join(ROOT, "..", "shared", "datasets", "mit-csail", "mit-csail.relations")
    if not os.path.exists(log):
        raise RuntimeError("../shared/datasets/mit-csail missing")
    replay = sh([BIN, "replay", log, "--out", d])
    text = sh([BIN, "eval", "--relations", rel, os.path.join(d, "trajectory.txt")])
    groups = eval_groups(text)
    cpu = re.search(r"thread CPU time per scan.*?median ([0-9.]+) ms", replay)
    (ta, ra), (tl, rl) = groups["all"], groups["<= 1 s"]
    return (f"all relations {ta:.3f} m / {ra:.2f}°, relations ≤ 1 s {tl:.4f} m / {rl:.2f}° "
            f"(CSM PL-ICP: 0.261 m / 2.12° and 0.0275 m / 0.41°, measured in ../shared/research/scan-matching.md); "
            f"CPU per scan {cpu.group(1) if cpu else '?'} ms median")


# The benchmark's corrected logs replayed without their odometry: log file,
# relations, time offset and tolerance (../shared/datasets/README.md), and
# CSM's figures there (all relations; <= 1 s where they mean something).
NO_ODOMETRY_LOGS = [
    ("fr079", "fr079/freiburg-079-corrected.log.gz", "fr079/fr079.relations", "1211.43", "0.1",
     "CSM 1.47 m / 9.6°, ≤ 1 s 0.034 m / 0.62°"),
    ("Intel", "intel/intel-corrected.log.gz", "intel/intel.relations", "976052857.337", "0.006",
     "CSM 5.52 m / 35.2°"),
    ("ACES", "aces/aces-corrected.log.gz", "aces/aces.relations", "70.179", "0.006",
     "CSM 38.7 m / 48.7°, 3 relations"),
]


def right_steps(log, trajectory):
    """The share (%) of the trajectory's scan-to-scan steps that agree with
    the corrected log's own laser poses (the SLAM result) to 0.1 m and 2°."""
    import gzip
    truth = {}
    with gzip.open(log, "rt") as f:
        for line in f:
            w = line.split()
            if w and w[0] == "FLASER":
                n = int(w[1])
                truth[round(float(w[n + 8]), 4)] = tuple(map(float, w[n + 2:n + 5]))
    poses = []
    with open(trajectory) as f:
        for line in f:
            w = line.split()
            if len(w) >= 4 and not line.startswith("#"):
                poses.append((round(float(w[0]), 4), tuple(map(float, w[1:4]))))

    def rel(a, b):
        dx, dy = b[0] - a[0], b[1] - a[1]
        c, s_ = math.cos(a[2]), math.sin(a[2])
        return c * dx + s_ * dy, -s_ * dx + c * dy, math.atan2(math.sin(b[2] - a[2]), math.cos(b[2] - a[2]))

    right = total = 0
    for (t0, p0), (t1, p1) in zip(poses, poses[1:]):
        if t0 in truth and t1 in truth:
            (gx, gy, ga), (wx, wy, wa) = rel(p0, p1), rel(truth[t0], truth[t1])
            da = math.degrees(abs(math.atan2(math.sin(ga - wa), math.cos(ga - wa))))
            total += 1
            right += math.hypot(gx - wx, gy - wy) < 0.1 and da < 2.0
    return 100.0 * right / max(total, 1)


def row_no_odometry(out):
    figs = []
    for name, log, rel, offset, tol, csm in NO_ODOMETRY_LOGS:
        data = os.path.join(ROOT, "..", "shared", "datasets")
        if not os.path.exists(os.path.join(data, log)):
            raise RuntimeError(f"../shared/datasets/{log} missing")
        d = os.path.join(out, "no-odometry", name)
        replay = sh([BIN, "replay", os.path.join(data, log), "--out", d,
                     "--config", os.path.join(ROOT, "hw", "replay-no-odometry.toml")])
        text = sh([BIN, "eval", "--relations", os.path.join(data, rel), os.path.join(d, "trajectory.txt"),
                   "--time-offset", offset, "--tolerance", tol])
        g = eval_groups(text)
        m = re.search(r"scans: (\d+)\s+matched: (\d+)", replay)
        run = re.search(r"longest run of scans without an accepted match: (\d+)", replay)
        srch = re.search(r"correlative search: ran (\d+) times.*?recovered the match (\d+); "
                         r"CPU per searching step median ([0-9.]+) ms", replay)
        (ta, ra), (tl, rl) = g["all"], g["<= 1 s"]
        short = f", ≤ 1 s {tl:.4f} m / {rl:.2f}°" if name == "fr079" else ""
        right = right_steps(os.path.join(data, log), os.path.join(d, "trajectory.txt"))
        figs.append(f"{name}: {m.group(2)} of {m.group(1)} scans matched (longest unmatched run {run.group(1)}), "
                    f"{right:.1f} % of the steps right to 0.1 m and 2° (the log's SLAM poses), "
                    f"all relations {ta:.3f} m / {ra:.2f}°{short} ({csm}); searched {srch.group(1)} times, "
                    f"{srch.group(2)} recovered, {srch.group(3)} ms CPU median")
    return "; ".join(figs)


# The closed loop's motion faults (`sweepline sim --fault`), each alone in
# the default room: name, extra options.
MOTION_FAULTS = [
    ("slip", ["--fault", "slip=200:1:0.45:0"]),
    ("knock", ["--fault", "knock=200:10"]),
    ("scale", ["--odometry-scale-error", "3"]),
    ("kidnap", ["--fault", "kidnap=200:1:0:30"]),
]


def row_motion_faults(out):
    from concurrent.futures import ThreadPoolExecutor
    runs = [(name, seed, args) for name, args in MOTION_FAULTS for seed in SEEDS]
    with ThreadPoolExecutor(2) as pool:
        mds = list(pool.map(lambda r: sim_run(out, f"fault_{r[0]}_s{r[1]}", ["--seed", str(r[1]), *r[2]])[0], runs))
    figs = []
    for name, _ in MOTION_FAULTS:
        cov, settle, peak, lost = [], [], [], []
        for (n, seed, _), md in zip(runs, mds):
            if n != name:
                continue
            cov.append(nums(cell(md, "coverage of reachable floor"))[0])
            f = cell(md, "after the motion faults")
            m = re.search(r"peak error ([0-9.]+) mm, under 20 mm for 5 s (not within the horizon|from ([0-9.]+) s after it)", f)
            if m:
                peak.append(float(m.group(1)))
                settle.append(m.group(3) or "never")
            lost.append(int(nums(cell(md, "robot lost and found again"))[0]))
            if name == "scale":
                peak.append(nums(cell(md, "localisation error at scan times"))[0])
        if name == "scale":
            figs.append(f"odometry 3 % short: coverage {span(cov)} %, pose RMSE {span(peak, '{:.1f}')} mm")
        else:
            figs.append(f"{name}: coverage {span(cov)} %, pose under 2 cm for 5 s from {'/'.join(settle)} s after it "
                        f"(peak {span(peak, '{:.1f}')} mm), lost and found {'/'.join(map(str, lost))} times")
    return "; ".join(figs) + " (seeds 1/2/3)"


def row_rooms3(out):
    figs = []
    for room in ("office_f:0", "lab_a_scan:1", "Freiburg52_scan:0"):
        md, _ = sim_run(out, room.replace(":", "_"), ["--room", room, "--time-cap", "1500"])
        cov = nums(cell(md, "coverage of reachable floor"))[0]
        coll = nums(cell(md, "collisions"))[0]
        figs.append(f"{room} {cov:.2f} % ({coll:.0f} collisions)")
    return ", ".join(figs)


def config_with(out, name, line, replacement):
    """hw/robot.toml with its line `line` replaced, written to OUT/NAME."""
    text = open(os.path.join(ROOT, "hw", "robot.toml")).read()
    text, n = re.subn("^" + re.escape(line) + "$", replacement, text, flags=re.M)
    if n != 1:
        raise RuntimeError(f"hw/robot.toml has no `{line}` line")
    cfg = os.path.join(out, name)
    with open(cfg, "w") as f:
        f.write(text)
    return cfg


def paper_map_config(out):
    return config_with(out, "paper-map.toml", 'kind = "grid"', 'kind = "paper"')


def row_map_kinds(out):
    """Lock-step, 24 rooms: `[map] kind = "grid"` against `"paper"`."""
    rooms = covrun.expand(["@rooms24"])
    got = {}
    for kind, cfg in (("grid", os.path.join(ROOT, "hw", "robot.toml")), ("paper", paper_map_config(out))):
        rs = covrun.run_all(BIN, cfg, os.path.join(out, f"rooms24_{kind}"), rooms)
        if any("error" in r for r in rs):
            raise RuntimeError(f"lock-step runs failed ({kind})")
        got[kind] = rs
    both = lambda f: " / ".join(f(got[k]) for k in ("grid", "paper"))
    mean = lambda k: lambda rs: f"{sum(r[k] for r in rs) / len(rs):.2f}"
    low = lambda rs: f"{min(r['cov_on'] for r in rs):.2f}"
    ov = lambda rs: f"{sum(r['ov_on'] for r in rs) / len(rs):.1f}"
    path = lambda rs: f"{sum(r['path_on'] for r in rs):.0f}"
    shifts, memory = [], {"grid": [], "paper": []}
    for w in rooms:
        read = lambda kind: open(os.path.join(out, f"rooms24_{kind}", w.replace(":", "_"), "metrics.md")).read()
        md = read("paper")
        shifts.append(nums(cell(md, "paper map: segment corrections"))[3])
        for kind in memory:
            memory[kind].append(nums(cell(read(kind), "map memory"))[0])
    mem = lambda k: f"{sum(memory[k]) / len(memory[k]):.2f}"
    return (f"grid / paper: coverage {both(mean('cov_on'))} % mean (lowest {both(low)}), overlap {both(ov)} %, "
            f"path {path(got['grid'])} / {path(got['paper'])} m in all, map memory {mem('grid')} / {mem('paper')} MB mean; "
            f"the segment correction moves maps built on exact poses {span(shifts, '{:.1f}')} mm on a room's mean")


def row_map_kinds_closed(out):
    """Closed loop, the default room, seeds 1-3, both kinds of map."""
    got = {}
    for kind, extra in (("grid", []), ("paper", ["--config", paper_map_config(out)])):
        cov, ov, pos, cpu = [], [], [], []
        for s in SEEDS:
            md, rep = sim_run(out, f"mapkind_{kind}_s{s}", ["--seed", str(s), *extra])
            cov.append(nums(cell(md, "coverage of reachable floor"))[0])
            ov.append(nums(cell(md, "overlap"))[0])
            pos.append(nums(cell(md, "localisation error at scan times"))[0])
            m = re.search(r"^\| map \| (\d+) \|.*\| ([0-9.]+) s \| [0-9.]+ % \|$", rep, re.M)
            if not m:
                raise RuntimeError("report.md has no map stage row")
            cpu.append(float(m.group(2)) / int(m.group(1)) * 1e3)
        got[kind] = (cov, ov, pos, cpu)
    g, p = got["grid"], got["paper"]
    mean = lambda v: sum(v) / len(v)
    return (f"grid / paper: coverage {span(g[0])} / {span(p[0])} %, overlap {mean(g[1]):.1f} / {mean(p[1]):.1f} % mean, "
            f"pose RMSE {span(g[2], '{:.1f}')} / {span(p[2], '{:.1f}')} mm, "
            f"map stage CPU {mean(g[3]):.2f} / {mean(p[3]):.2f} ms per message")


def row_deskew(out):
    cfg = os.path.join(out, "no-deskew.toml")
    text = open(os.path.join(ROOT, "hw", "robot.toml")).read()
    text, n = re.subn(r"^deskew_scans = true$", "deskew_scans = false", text, flags=re.M)
    if n != 1:
        raise RuntimeError("hw/robot.toml has no `deskew_scans = true` line")
    with open(cfg, "w") as f:
        f.write(text)
    figs = []
    for s in (1, 2):
        on, _ = sim_run(out, f"deskew_s{s}", ["--time-cap", "300", "--seed", str(s)])
        off, _ = sim_run(out, f"no_deskew_s{s}", ["--time-cap", "300", "--seed", str(s), "--config", cfg])
        a = nums(cell(on, "localisation error at scan times"))
        b = nums(cell(off, "localisation error at scan times"))
        figs.append(f"seed {s}: {a[0]:.1f} mm / {a[2]:.2f}° deskewed, {b[0]:.1f} mm / {b[2]:.2f}° not")
    return "; ".join(figs)


def row_large_room(out):
    image = os.path.join(ROOT, "..", "shared", "maps", "ipa_coverage_planning_test_maps", "map.pgm")
    if not os.path.exists(image):
        raise RuntimeError("../shared/maps missing")
    yaml = os.path.join(out, "lab_ipa.yaml")
    with open(yaml, "w") as f:
        f.write(f"image: {os.path.abspath(image)}\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n"
                "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    md, _ = sim_run(out, "large_room", ["--map", yaml, "--region", "16.5,9.0,25.5,21.2", "--seed", "1"])
    cov = nums(cell(md, "coverage of reachable floor"))[0]
    loc = nums(cell(md, "localisation error at scan times"))
    return f"{cov:.2f} %, pose RMSE {loc[0]:.1f} mm / {loc[2]:.2f}° (see Known gaps)"


def row_large_room10(out):
    """The large room on seeds 1-10, two runs at a time (the paced clock
    waits for a daemon that falls behind)."""
    from concurrent.futures import ThreadPoolExecutor
    row_large_room(out)  # writes lab_ipa.yaml (seed 1 is the first of the ten)
    yaml = os.path.join(out, "lab_ipa.yaml")

    def one(seed):
        md, _ = sim_run(out, f"large_room_s{seed}",
                        ["--map", yaml, "--region", "16.5,9.0,25.5,21.2", "--seed", str(seed)])
        return nums(cell(md, "coverage of reachable floor"))[0], nums(cell(md, "localisation error at scan times"))[0]

    with ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(one, range(1, 11)))
    pos = [p for _, p in runs]
    return (f"pose RMSE by seed {', '.join(f'{p:.1f}' for p in pos)} mm; {sum(p <= 20.0 for p in pos)} of 10 "
            f"at most 20 mm; coverage {span([c for c, _ in runs])} %")


def bench(name, *filt):
    text = sh(["cargo", "bench", "-p", "sweepline-bench", "--bench", name, "--", *filt,
               "--warm-up-time", "1", "--measurement-time", "3"])
    out = []
    for m in re.finditer(r"^(\S+)\s+time:\s+\[\S+ \S+ (\S+) (\S+) \S+ \S+\]", text, re.M):
        out.append(f"{m.group(1)} {m.group(2)} {m.group(3)}")
    return "; ".join(out) or "no criterion output"


def row_bench_scip(out):
    return bench("scip_decode")


def row_bench_decomp(out):
    return bench("decomp_update")


def row_bench_plan(out):
    return bench("plan_update", "plan_decision")


def row_faults(out):
    text = sh(["cargo", "test", "--release", "--test", "sim_faults", "--", "--ignored", "--nocapture",
               "--test-threads=1"])
    cov = [float(v) for v in re.findall(r"coverage ([0-9.]+) %", text)]
    if not cov:
        raise RuntimeError("no coverage figures in the test output")
    return f"{len(cov)} runs: coverage {min(cov):.2f}-{max(cov):.2f} %, mean {sum(cov) / len(cov):.2f} %"


def row_resume(out):
    text = sh(["cargo", "test", "--release", "--test", "e2e_resume", "--", "--ignored", "--nocapture",
               "--test-threads=1", "killed_daemon_resumes_its_coverage"])
    m = re.search(r"checkpointed pose vs truth: max ([0-9.]+) m before the kill, ([0-9.]+) m after", text)
    f = re.search(r"finished at ([0-9.]+) % true coverage", text)
    if not (m and f):
        raise RuntimeError("no pose error in the test output")
    return (f"checkpointed pose {float(m.group(1)) * 1e3:.0f} mm from the truth before the kill, "
            f"{float(m.group(2)) * 1e3:.0f} mm after the resume; finished at {f.group(1)} %")


# key, metric, command as shown, function
ROWS = [
    ("main", "main job, default room, seeds 1-3 (paced clock, at most ×15)",
     "`sweepline sim --seed N`", row_main),
    ("main-fixed5", "the same at a fixed ×5 (the simulator's clock before it was paced)",
     "`sweepline sim --seed N --speed 5 --fixed-speed`", row_main_fixed5),
    ("realtime", "real time: CPU of the daemon (without the in-process emulators), end-to-end latency",
     "`sweepline sim --speed 1 --fixed-speed --time-cap 600`", row_realtime),
    ("live-cost", "real time, default room, 180 s: CPU of the daemon and end-to-end latency with neither recording nor viewer, with the recording, with the recording and a viewer reading every channel, with the recording and a viewer that subscribes to every channel and never reads",
     "`sweepline sim --speed 1 --fixed-speed --time-cap 180 --seed 1 [--live off] [--no-record]`", row_live_cost),
    ("lockstep24", "lock-step coverage, 24 rooms, ideal localisation",
     "`python3 scripts/covrun.py target/release/sweepline hw/robot.toml OUT @rooms24`", row_lockstep24),
    ("map-kinds", "the planner's map, `[map] kind` grid against paper: lock-step, 24 rooms, ideal localisation",
     "`python3 scripts/covrun.py target/release/sweepline CONFIG OUT @rooms24` (CONFIG: hw/robot.toml with `kind = \"grid\"` or `\"paper\"`)",
     row_map_kinds),
    ("map-kinds-closed", "the planner's map, `[map] kind` grid against paper: closed loop, the default room, seeds 1-3",
     "`sweepline sim --seed N [--config PAPER-MAP.toml]`", row_map_kinds_closed),
    ("closed12", "closed loop, twelve rooms, seed 1",
     "`python3 scripts/simrun.py target/release/sweepline OUT paper Freiburg52_scan:0 ...` (the rooms of `covrun.py @test12`)",
     row_closed12),
    ("rooms3", "closed loop, three floor-plan rooms, seed 1",
     "`sweepline sim --room MAP:N --time-cap 1500`", row_rooms3),
    ("deskew", "deskewing, default room, 300 s, seeds 1 and 2 (with `daemon.deskew_scans = false` for the second figure)",
     "`sweepline sim --time-cap 300 --seed N [--config NO-DESKEW.toml]`", row_deskew),
    ("large-room", "large open room (9 m × 12 m, walls beyond 5.6 m), seed 1",
     "`sweepline sim --map MAP.yaml --region 16.5,9.0,25.5,21.2 --seed 1` (MAP: the lab_ipa building's map in `../shared/maps`)",
     row_large_room),
    ("large-room10", "large open room (9 m × 12 m), seeds 1-10",
     "`sweepline sim --map lab_ipa.yaml --region 16.5,9.0,25.5,21.2 --seed N` (N = 1-10, two at a time)",
     row_large_room10),
    ("doorway", "person standing in a doorway, closed loop",
     "`sweepline sim --world hw/worlds/doorway.world`", row_doorway),
    ("csail", "scan matching, MIT CSAIL log (translation / rotation error over the relations)",
     "`sweepline replay ../shared/datasets/mit-csail/mit-csail.clf --out OUT`; `sweepline eval --relations ../shared/datasets/mit-csail/mit-csail.relations OUT/trajectory.txt`",
     row_csail),
    ("motion-faults", "closed loop, default room, motion faults one at a time, seeds 1-3: a 1 s slip burst (left wheel loses 45 %), a knock turning the robot 10°, odometry 3 % short, a kidnap (carried 1 m, turned 30°)",
     "`sweepline sim --seed N --fault slip=200:1:0.45:0` (`knock=200:10`, `kidnap=200:1:0:30`; `--odometry-scale-error 3`)",
     row_motion_faults),
    ("no-odometry", "scan matching without odometry (constant-velocity prior, correlative search, keyframe store), the benchmark's fr079, Intel and ACES logs",
     "`sweepline replay LOG --config hw/replay-no-odometry.toml --out OUT`; `sweepline eval --relations REL OUT/trajectory.txt --time-offset S --tolerance S`",
     row_no_odometry),
    ("faults", "faults end to end (cable pulled, link silent, corrupted bytes; bumper on RoboClaw and Create 2)",
     "`cargo test --release --test sim_faults -- --ignored --nocapture --test-threads=1`", row_faults),
    ("resume", "crash and resume (the daemon killed mid-run and started again)",
     "`cargo test --release --test e2e_resume -- --ignored --nocapture killed_daemon_resumes_its_coverage`",
     row_resume),
    ("bench-scip", "scan decode and deskew, 682 beams (criterion median)",
     "`cargo bench -p sweepline-bench --bench scip_decode`", row_bench_scip),
    ("bench-decomp", "decomposition update (criterion median)",
     "`cargo bench -p sweepline-bench --bench decomp_update`", row_bench_decomp),
    ("bench-plan", "lane-tour decision (criterion median)",
     "`cargo bench -p sweepline-bench --bench plan_update -- plan_decision`", row_bench_plan),
]


def load():
    try:
        with open(STORE) as f:
            return json.load(f)
    except FileNotFoundError:
        return {}


def version():
    m = re.search(r'^version = "([^"]+)"', open(os.path.join(ROOT, "Cargo.toml")).read(), re.M)
    return m.group(1) if m else "?"


def table(store):
    lines = ["| metric | figure | measured | command |", "|---|---|---|---|"]
    for key, metric, cmd, _ in ROWS:
        r = store.get(key)
        fig, when = (r["figure"], f"{r['date']} ({r['version']})") if r else ("not measured yet", "")
        lines.append(f"| {metric} | {fig} | {when} | {cmd} (`scripts/results.py {key}`) |")
    return "\n".join(lines)


def figure(store, key):
    """A stored figure with its date, for a `fig:KEY` span."""
    r = store.get(key)
    return f"{r['figure']} ({r['date']}, {r['version']})" if r else "not measured yet"


def write(store):
    md = open(RESULTS_MD).read()
    i, j = md.find(BEGIN), md.find(END)
    if i < 0 or j < i:
        raise RuntimeError(f"{RESULTS_MD} has no {BEGIN} ... {END} markers")
    md = md[:i + len(BEGIN)] + "\n" + table(store) + "\n" + md[j:]
    with open(RESULTS_MD, "w") as f:
        f.write(md)
    spans = re.compile(r"<!-- fig:([a-z0-9-]+) -->.*?<!-- /fig -->", re.S)
    docs = [os.path.join(ROOT, "README.md")] + [
        os.path.join(ROOT, "docs", f) for f in sorted(os.listdir(os.path.join(ROOT, "docs"))) if f.endswith(".md")]
    for path in docs:
        text = open(path).read()
        new = spans.sub(lambda m: f"<!-- fig:{m.group(1)} -->{figure(store, m.group(1))}<!-- /fig -->", text)
        if new != text:
            with open(path, "w") as f:
                f.write(new)


def main():
    args = sys.argv[1:]
    out = os.path.join(ROOT, "out", "results")
    if "--out" in args:
        k = args.index("--out")
        out = os.path.abspath(args[k + 1])
        del args[k:k + 2]
    store = load()
    global REUSE
    REUSE = "--reuse" in args
    if "--list" in args:
        for key, metric, cmd, _ in ROWS:
            when = store.get(key, {}).get("date", "never")
            print(f"{key:13s} {when:11s} {metric}\n{'':25s}{cmd}")
        return
    keys = [a for a in args if not a.startswith("--")]
    if keys == ["all"]:
        keys = [r[0] for r in ROWS]
    unknown = set(keys) - {r[0] for r in ROWS}
    if unknown:
        sys.exit(f"unknown rows: {', '.join(sorted(unknown))} (see --list)")
    if keys and "--write-only" not in args:
        sh(["cargo", "build", "--release"])
        os.makedirs(out, exist_ok=True)
    for key, metric, cmd, fn in ROWS:
        if key not in keys or "--write-only" in args:
            continue
        print(f"== {key}: {metric}", flush=True)
        try:
            fig = fn(out)
        except RuntimeError as e:
            print(f"   failed: {e}", flush=True)
            continue
        store[key] = {"figure": fig, "date": datetime.date.today().isoformat(), "version": version(),
                      "command": cmd}
        print(f"   {fig}", flush=True)
        with open(STORE, "w") as f:
            json.dump(store, f, indent=1, sort_keys=True, ensure_ascii=False)
            f.write("\n")
    write(store)


if __name__ == "__main__":
    main()
