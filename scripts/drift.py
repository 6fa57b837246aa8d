#!/usr/bin/env python3
"""Where a closed-loop run's localisation error grew: turning or driving.

Usage: scripts/drift.py RUN... [--turn W]
  RUN       a `sweepline sim` run folder (reads RUN/fixes.csv) or a fixes.csv
  --turn W  true turn rate (rad/s) above which a scan counts as taken while
            turning (default 0.3; the paper robot turns at up to 0.78)

Splits each run's scans by the true turn rate between consecutive fixes
(turning, slow, straight) and prints per class the time spent, the net change
of the heading error (degrees) and the sum of its absolute changes. A deskew
or stamp error shows as heading error gained while turning, with one sign;
a matcher that random-walks shows the same per-scan change in every class.
Ends with the heading and position error of the last fix. Gaps between fixes
longer than 0.3 s (scanner unplugged, the run paused) are skipped."""
import csv, math, os, sys


def classes(path, turn):
    rows = list(csv.DictReader(open(path)))
    out = {}
    prev = None
    for r in rows:
        t, th = float(r["t_s"]), float(r["true_theta_rad"])
        he = float(r["heading_error_rad"])
        if prev is not None:
            dt = t - prev[0]
            if 0 < dt <= 0.3:
                w = abs(math.remainder(th - prev[1], math.tau)) / dt
                d = math.remainder(he - prev[2], math.tau)
                k = "turning" if w > turn else ("slow" if w > 0.05 else "straight")
                c = out.setdefault(k, [0, 0.0, 0.0, 0.0])
                c[0] += 1
                c[1] += dt
                c[2] += d
                c[3] += abs(d)
        prev = (t, th, he)
    last = rows[-1] if rows else None
    return out, last


def main():
    args = sys.argv[1:]
    turn = 0.3
    if "--turn" in args:
        i = args.index("--turn")
        turn = float(args[i + 1])
        del args[i:i + 2]
    if not args:
        sys.exit(__doc__)
    for run in args:
        path = os.path.join(run, "fixes.csv") if os.path.isdir(run) else run
        try:
            out, last = classes(path, turn)
        except (OSError, KeyError, ValueError) as e:
            print(f"{run}: cannot read {path}: {e}")
            continue
        print(run)
        for k in ("turning", "slow", "straight"):
            if k in out:
                n, dt, net, tot = out[k]
                print(f"  {k:9s} {n:6d} scans {dt:7.1f} s  heading error net {math.degrees(net):+7.3f}°"
                      f"  sum of |changes| {math.degrees(tot):7.2f}°  per scan {math.degrees(tot) / n:.3f}°")
        if last:
            print(f"  last fix at {float(last['t_s']):.1f} s: heading error "
                  f"{math.degrees(float(last['heading_error_rad'])):+.3f}°, position error "
                  f"{1000 * float(last['error_m']):.1f} mm")


if __name__ == "__main__":
    main()
