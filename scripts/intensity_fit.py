#!/usr/bin/env python3
"""Fits the shape of a Hokuyo's reported intensity to range and angle of
incidence from the one real intensity scan in ../shared: the UTM-30LX `ME`
capture of gbiggs/hokuyoaist (`example_utm_30lx.logr`).

The emulator's intensity model (crates/sim/src/urg_emu/intensity.rs) takes
its exponents from this fit; run it to see where they come from:

    python3 scripts/intensity_fit.py [../shared/datasets/hokuyo-captures]

Method: decode the capture (records of big-endian u32 seconds, microseconds,
length, then the bytes; SCIP 2.0 three-character values, range and
intensity interleaved), keep the steps that lie on a straight surface (the
9 neighbouring steps within 8 % of its range fit a line whose minor/major
spread ratio is below 0.08), take the angle of incidence from that line's
normal, and fit log I = a + b log r + c log cos(incidence) by least squares
over the steps at 0.5 m or more (the nearer ones are all 0.10-0.14 m away
and grazing: not enough to fit a near-field term). The surfaces' own
reflectivities are unknown: they are the scatter the fit leaves.
"""

import math
import os
import struct
import sys

CAPTURE = "example_utm_30lx.logr"
# The ME request in the capture: steps 0..1080, cluster 1, 0.25° a step,
# step 0 at -135°.
REQUEST = "ME0000108001100\n"
STEP = math.radians(0.25)
FIRST = math.radians(-135.0)
MIN_RANGE_M = 0.5


def records(data):
    """The byte records of a .logr file."""
    i = 0
    while i + 12 <= len(data):
        _s, _us, n = struct.unpack(">III", data[i : i + 12])
        yield data[i + 12 : i + 12 + n]
        i += 12 + n


def decode(text):
    """(range mm, intensity) per step of the first full ME scan."""
    k = text.find(REQUEST)
    if k < 0:
        sys.exit(f"no {REQUEST.strip()} scan in the capture")
    lines = text[k:].split("\n\n")[0].split("\n")
    # Echo, status, timestamp, then data lines with a checksum character.
    data = "".join(l[:-1] for l in lines[3:] if l)
    vals = [
        (ord(data[j]) - 0x30) << 12 | (ord(data[j + 1]) - 0x30) << 6 | (ord(data[j + 2]) - 0x30)
        for j in range(0, len(data) - 2, 3)
    ]
    return list(zip(vals[0::2], vals[1::2]))


def principal(points):
    """Direction of the major axis and the two spreads of a point set."""
    n = len(points)
    cx = sum(p[0] for p in points) / n
    cy = sum(p[1] for p in points) / n
    sxx = sum((p[0] - cx) ** 2 for p in points)
    syy = sum((p[1] - cy) ** 2 for p in points)
    sxy = sum((p[0] - cx) * (p[1] - cy) for p in points)
    half = (sxx + syy) / 2
    d = math.sqrt(max(half * half - (sxx * syy - sxy * sxy), 0.0))
    th = 0.5 * math.atan2(2 * sxy, sxx - syy)
    return (math.cos(th), math.sin(th)), half + d, half - d


def least_squares(xs, ys):
    """Coefficients of the linear least-squares fit y ≈ x · c."""
    k = len(xs[0])
    m = [[sum(x[i] * x[j] for x in xs) for j in range(k)] + [sum(x[i] * y for x, y in zip(xs, ys))] for i in range(k)]
    for i in range(k):
        p = max(range(i, k), key=lambda r: abs(m[r][i]))
        m[i], m[p] = m[p], m[i]
        for r in range(k):
            if r != i:
                f = m[r][i] / m[i][i]
                m[r] = [a - f * b for a, b in zip(m[r], m[i])]
    return [m[i][k] / m[i][i] for i in range(k)]


def main():
    folder = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "..", "shared", "datasets", "hokuyo-captures"
    )
    path = os.path.join(folder, CAPTURE)
    if not os.path.exists(path):
        sys.exit(f"skipped: {path} not found")
    with open(path, "rb") as f:
        text = b"".join(records(f.read())).decode("latin-1")
    steps = decode(text)
    pts = [
        (r / 1000 * math.cos(FIRST + s * STEP), r / 1000 * math.sin(FIRST + s * STEP))
        for s, (r, _) in enumerate(steps)
    ]
    rows = []
    for s, (r, inten) in enumerate(steps):
        if r < 100 or inten == 0:
            continue
        nb = [pts[j] for j in range(max(0, s - 4), min(len(steps), s + 5)) if abs(steps[j][0] - r) < 0.08 * r + 50]
        if len(nb) < 7:
            continue
        d, major, minor = principal(nb)
        if math.sqrt(minor / max(major, 1e-12)) > 0.08:
            continue
        bx, by = pts[s]
        length = math.hypot(bx, by)
        cos_i = abs(-d[1] * bx / length + d[0] * by / length)
        if cos_i < 0.05:
            continue
        rows.append((r / 1000, inten, cos_i))
    fit = [row for row in rows if row[0] >= MIN_RANGE_M]
    xs = [(1.0, math.log(r), math.log(c)) for r, _, c in fit]
    ys = [math.log(i) for _, i, _ in fit]
    a, b, c = least_squares(xs, ys)
    rms = math.sqrt(sum((y - (a + b * x[1] + c * x[2])) ** 2 for x, y in zip(xs, ys)) / len(ys))
    print(f"capture: {path}: {len(steps)} steps, {len(rows)} on straight surfaces, {len(fit)} at >= {MIN_RANGE_M} m")
    print(f"fit: log I = {a:.2f} {b:+.2f} log(r / 1 m) {c:+.2f} log cos(incidence); rms {rms:.2f} (log units)")
    print(f"  -> I = {math.exp(a):.0f} x r^{b:.2f} x cos^{c:.2f}")
    print("median intensity by range (m):")
    for lo, hi in [(0.0, 0.5), (0.5, 1), (1, 2), (2, 4), (4, 8)]:
        sel = sorted(i for r, i, _ in rows if lo <= r < hi)
        if sel:
            print(f"  {lo:>4}-{hi:<4} {len(sel):>4} steps  {sel[len(sel) // 2]}")
    print("median intensity by cos(incidence) (steps >= 0.5 m):")
    for lo, hi in [(0.05, 0.3), (0.3, 0.6), (0.6, 0.85), (0.85, 1.01)]:
        sel = sorted(i for r, i, c in fit if lo <= c < hi)
        if sel:
            print(f"  {lo:>4}-{hi:<4} {len(sel):>4} steps  {sel[len(sel) // 2]}")


if __name__ == "__main__":
    main()
