#!/usr/bin/env python3
"""Lock-step coverage over several worlds, online and offline, in one table.

Usage: scripts/covrun.py BIN CONFIG OUT WORLD... [-- COVERAGE-OPTION...]
  BIN     the release binary (target/release/sweepline)
  CONFIG  the robot configuration (hw/robot.toml)
  OUT     folder for each world's metrics.md and pictures
  WORLD   `paper` (hw/worlds/paper.world), a floor-plan room MAP:N, or a
          named set: @test12 (the worlds of the coverage tests and the first
          held-out rooms) or @rooms24 (those and twelve more; per-room overlap
          swings by up to ten points on small map changes, so compare means
          over many rooms)
Options after `--` go to every `sweepline coverage` run, e.g.
`-- --grid-offset 0.025 --range-noise 0.005` (the map as the daemon's grid
holds it, from noisy scans; `--grid-offset 0.0` with the noise puts the
surfaces on the cell boundaries instead, the hardest case, see
measured 2026-11-29), or `-- --bare` (the floor-plan rooms without
their furniture; the paper world is left out then). Prints per world the online / offline overlap (%), coverage (%), the
online/offline path ratio, and the means; two runs at a time."""
import sys, subprocess, re, os, concurrent.futures as cf
PAPER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "hw", "worlds", "paper.world")
TEST12 = ["paper", "Freiburg52_scan:0", "lab_a_scan:1", "office_f:0", "lab_c_scan:2", "NLB:0",
          "office_f:5", "lab_a_scan:8", "Freiburg52_scan:2", "NLB:9", "Freiburg52_scan:7", "lab_c_scan:0"]
SETS = {"test12": TEST12,
        "rooms24": TEST12 + ["Freiburg52_scan:1", "Freiburg52_scan:3", "Freiburg52_scan:5", "lab_a_scan:10",
                             "lab_a_scan:11", "office_f:2", "office_f:13", "lab_c_scan:5", "lab_c_scan:11",
                             "NLB:10", "NLB:13", "NLB:25"]}
def expand(worlds):
    out = []
    for w in worlds:
        out.extend(SETS[w[1:]] if w.startswith("@") else [w])
    return out
def run(binp, cfg, out, w, extra=()):
    arg = ["--world", PAPER] if w == "paper" else ["--room", w]
    d = os.path.join(out, w.replace(":", "_"))
    p = subprocess.run([binp, "coverage", *arg, "--offline", "--config", cfg, "--out", d, "--picture-every", "100000", *extra], capture_output=True, text=True)
    try:
        md = open(os.path.join(d, "metrics.md")).read()
    except Exception:
        return {"world": w, "error": p.stderr[-300:]}
    def row(name):
        m = re.search(r"^\| " + re.escape(name) + r"[^|]*\|\s*([0-9.]+)[^|]*\|\s*([0-9.]+)", md, re.M)
        return (float(m.group(1)), float(m.group(2))) if m else (None, None)
    ov = row("overlap"); cov = row("coverage of reachable area"); pl = row("path length")
    fin = re.search(r"finished before the time cap \| (\w+) \| (\w+)", md)
    return {"world": w, "ov_on": ov[0], "ov_off": ov[1], "cov_on": cov[0], "cov_off": cov[1],
            "path_on": pl[0], "path_off": pl[1], "ratio": pl[0]/pl[1] if pl[1] else None,
            "fin": fin.groups() if fin else None}
def run_all(binp, cfg, out, worlds, jobs=2, extra=()):
    with cf.ThreadPoolExecutor(jobs) as ex:
        return list(ex.map(lambda w: run(binp, cfg, out, w, extra), worlds))
if __name__ == "__main__":
    args = sys.argv[1:]
    extra = args[args.index("--") + 1:] if "--" in args else []
    args = args[:args.index("--")] if "--" in args else args
    binp, cfg, out, *worlds = args
    worlds = expand(worlds)
    if "--bare" in extra:
        worlds = [w for w in worlds if w != "paper"]
    rs = run_all(binp, cfg, out, worlds, extra=extra)
    for r in rs:
        if "error" in r: print(r); continue
        print(f"{r['world']:20s} ov {r['ov_on']:5.1f} / {r['ov_off']:5.1f}  cov {r['cov_on']:6.2f} / {r['cov_off']:6.2f}  ratio {r['ratio']:.3f} fin {r['fin']}")
    ok = [r for r in rs if "error" not in r]
    print(f"MEAN ov {sum(r['ov_on'] for r in ok)/len(ok):.1f} / {sum(r['ov_off'] for r in ok)/len(ok):.1f}  min cov {min(r['cov_on'] for r in ok):.2f} / {min(r['cov_off'] for r in ok):.2f}  max ratio {max(r['ratio'] for r in ok):.3f}")
