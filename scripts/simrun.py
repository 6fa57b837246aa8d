#!/usr/bin/env python3
"""Closed-loop coverage (the daemon through the ptys) over several worlds and
seeds, in one table: the closed loop's counterpart of covrun.py.

Usage: scripts/simrun.py BIN OUT WORLD... [--seeds N] [--jobs J] [-- SIM-OPTION...]
  BIN     the release binary (target/release/sweepline)
  OUT     folder for each run's report (OUT/<world>_s<seed>/)
  WORLD   `paper` (hw/worlds/paper.world), a world file (…/NAME.world) or a
          floor-plan room MAP:N
Options:
  --seeds N   seeds 1..N of the simulated noise per world (default 1)
  --jobs J    runs at a time (default 1: the closed loop runs on real
              threads and ptys, and a second run disturbs its timing; see
              clab.py, which A/B-tests two binaries on one room)
  --parse     only read the reports already in OUT (no runs)
Options after `--` go to every `sweepline sim` run (e.g. `--base create2`).
The environment is passed on (e.g. RUST_LOG, or a variable an experiment
reads). Prints per run the coverage of the reachable floor (%), overlap (%),
tasks planned (paths blocked), path length (m), collisions and the pose
RMSE (mm), then the means. The closed loop's overlap varies by several
points between seeds and between runs of one seed (thread timing): compare
means over several runs, never one run."""
import sys, subprocess, re, os, concurrent.futures as cf

PAPER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "hw", "worlds", "paper.world")


def folder(out, world, seed):
    if world.endswith(".world"):
        world = os.path.splitext(os.path.basename(world))[0]
    return os.path.join(out, f"{world.replace(':', '_')}_s{seed}")


def parse(d):
    try:
        md = open(os.path.join(d, "summary.md")).read()
    except OSError:
        return None

    def cell(name):
        m = re.search(r"^\| " + re.escape(name) + r"[^|]*\|\s*([^|]*)\|", md, re.M)
        return m.group(1).strip() if m else ""

    def num(text, k=0):
        v = re.findall(r"[0-9]+(?:\.[0-9]+)?", text)
        return float(v[k]) if len(v) > k else None

    tasks = cell("tasks planned")
    return {
        "cov": num(cell("coverage of reachable floor")),
        "ov": num(cell("overlap")),
        "tasks": num(tasks), "blocked": num(tasks, 1),
        "path": num(cell("path length")),
        "coll": num(cell("collisions")),
        "rmse": num(cell("localisation error at scan times")),
        "fin": cell("finished by itself").split(" ")[0],
    }


def run(binp, out, world, seed, extra):
    d = folder(out, world, seed)
    if world == "paper":
        arg = ["--world", PAPER]
    elif world.endswith(".world"):
        arg = ["--world", world]
    else:
        arg = ["--room", world]
    with open(d + ".log", "w") as log:
        subprocess.run([binp, "sim", *arg, "--seed", str(seed), "--out", d, *extra],
                       stdout=log, stderr=subprocess.STDOUT)
    return parse(d)


def main():
    args = sys.argv[1:]
    extra = args[args.index("--") + 1:] if "--" in args else []
    args = args[:args.index("--")] if "--" in args else args
    seeds, jobs, only_parse = 1, 1, False
    rest = []
    i = 0
    while i < len(args):
        if args[i] == "--seeds":
            seeds = int(args[i + 1]); i += 2
        elif args[i] == "--jobs":
            jobs = int(args[i + 1]); i += 2
        elif args[i] == "--parse":
            only_parse = True; i += 1
        else:
            rest.append(args[i]); i += 1
    if len(rest) < 3:
        sys.exit(__doc__)
    binp, out, *worlds = rest
    os.makedirs(out, exist_ok=True)
    todo = [(w, s) for w in worlds for s in range(1, seeds + 1)]
    if only_parse:
        rs = [parse(folder(out, w, s)) for w, s in todo]
    else:
        with cf.ThreadPoolExecutor(jobs) as ex:
            rs = list(ex.map(lambda t: run(binp, out, t[0], t[1], extra), todo))
    ok = []
    for (w, s), r in zip(todo, rs):
        name = f"{w} s{s}"
        if r is None or r["cov"] is None:
            print(f"{name:26s} no report (see {folder(out, w, s)}.log)")
            continue
        ok.append(r)
        print(f"{name:26s} cov {r['cov']:6.2f}  ov {r['ov']:5.1f}  tasks {r['tasks']:3.0f} ({r['blocked']:.0f} blocked)"
              f"  path {r['path']:6.1f} m  coll {r['coll']:.0f}  rmse {r['rmse']:5.1f} mm  finished {r['fin']}")
    if ok:
        n = len(ok)
        print(f"MEAN of {n}: cov {sum(r['cov'] for r in ok) / n:.2f} (lowest {min(r['cov'] for r in ok):.2f}, "
              f"{sum(r['cov'] < 99 for r in ok)} under 99)  ov {sum(r['ov'] for r in ok) / n:.1f}  "
              f"collisions {sum(r['coll'] for r in ok):.0f}")


if __name__ == "__main__":
    main()
