#!/usr/bin/env python3
"""Closed-loop A/B: two sweepline binaries on the same room, interleaved.

Usage: clab.py BIN_A BIN_B OUT ROOM N [-- extra `sweepline sim` options]

Runs `BIN sim --room ROOM --seed S --out OUT/{a,b}_sS` for S = 1..N,
alternating A and B seed by seed and one run at a time (the closed loop
runs on real threads and ptys, and a second run would disturb its timing).
Prints each pair's coverage, overlap and path, then per binary the mean
and standard deviation, and the paired differences (B - A) with their
mean, standard error and t. ROOM "paper" runs the default world. A binary
built in another checkout looks for the floor plans beside that checkout:
set SWEEPLINE_SHARED to the shared data folder if that one is gone.

Why interleaved: the closed loop does not repeat itself. Runs of one binary
with one seed spread by several points of overlap, and batches run at
different times of a shared machine drift apart (2026-11-28: two batches
of 8 office_f:0 runs that took the same decisions differed by 3.7 points).
Pairs run back to back see the same machine.
"""
import math
import os
import re
import subprocess
import sys

DONE = re.compile(
    r"coverage ([0-9.]+) % of [0-9.]+ m² reachable, path ([0-9.]+) m, \d+ turns, overlap ([0-9.]+) %"
)


def run(binp, room, seed, out, extra):
    arg = [] if room == "paper" else ["--room", room]
    p = subprocess.run(
        [binp, "sim", *arg, "--seed", str(seed), "--out", out, *extra],
        capture_output=True,
        text=True,
    )
    m = DONE.search(p.stdout + p.stderr)
    if not m:
        tail = (p.stdout + p.stderr).strip().splitlines()[-1:] or ["no output"]
        return None, tail[0]
    cov, path, ov = (float(g) for g in m.groups())
    return {"cov": cov, "path": path, "ov": ov}, ""


def stats(xs):
    n = len(xs)
    mean = sum(xs) / n
    sd = math.sqrt(sum((x - mean) ** 2 for x in xs) / (n - 1)) if n > 1 else float("nan")
    return mean, sd


def main():
    args = sys.argv[1:]
    extra = args[args.index("--") + 1:] if "--" in args else []
    args = args[: args.index("--")] if "--" in args else args
    if len(args) != 5:
        sys.exit(__doc__)
    bin_a, bin_b, out, room, n = args
    n = int(n)
    os.makedirs(out, exist_ok=True)
    res = {"a": [], "b": []}
    print(f"{'seed':>4}  {'A cov':>6} {'A ov':>5} {'A path':>6}   {'B cov':>6} {'B ov':>5} {'B path':>6}")
    for s in range(1, n + 1):
        row = {}
        for tag, binp in (("a", bin_a), ("b", bin_b)):
            r, err = run(binp, room, s, os.path.join(out, f"{tag}_s{s}"), extra)
            if r is None:
                print(f"seed {s} {tag.upper()}: no result ({err})")
            row[tag] = r
        if row["a"] and row["b"]:
            for tag in "ab":
                res[tag].append(row[tag])
            a, b = row["a"], row["b"]
            print(f"{s:4d}  {a['cov']:6.2f} {a['ov']:5.1f} {a['path']:6.1f}   {b['cov']:6.2f} {b['ov']:5.1f} {b['path']:6.1f}", flush=True)
    k = len(res["a"])
    if k < 2:
        sys.exit("fewer than two complete pairs")
    for key, name in (("ov", "overlap %"), ("cov", "coverage %"), ("path", "path m")):
        ma, sa = stats([r[key] for r in res["a"]])
        mb, sb = stats([r[key] for r in res["b"]])
        d = [rb[key] - ra[key] for ra, rb in zip(res["a"], res["b"])]
        md, sd = stats(d)
        se = sd / math.sqrt(k)
        t = md / se if se > 0 else float("nan")
        print(f"{name:11s} A {ma:7.2f} (sd {sa:5.2f})  B {mb:7.2f} (sd {sb:5.2f})  B-A {md:+6.2f} (se {se:5.2f}, t {t:+5.2f}, {k} pairs)")


if __name__ == "__main__":
    main()
