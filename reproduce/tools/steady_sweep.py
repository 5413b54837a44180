#!/usr/bin/env python3
"""steady_sweep.py [--test W:TOL:K:CAP ...] LABEL=RUN ... : variants of the steady test applied,
as `--until-steady` would, to archived time series.

Each RUN is a reproduction's output directory or its archive (`timeseries.csv` and
`manifest.json`, directly or under `run/`). The series is the one `slurry status` tests:
t N = step / steps per revolution, ⟨z_p⟩/H = (particle_mean_z + ½) / nz.

A test `W:TOL` is `stats::steady_state` with a window of W revolutions: the least-squares
drift across the window and its standard error σ from 10 batch means, steady when
`|drift| ≤ TOL` and `σ ≤ TOL`; the report's test is `20:0.005` (src/reproduce/report.rs,
STEADY_REVOLUTIONS and STEADY_DRIFT; src/stats/mod.rs). `W:TOL:K:CAP` is the test of
2026-11-27 to 2026-11-30 and its variants: steady when `|drift| − K σ ≤ TOL` and
`|drift| ≤ CAP` (that test: `20:0.005:2:0.015`). The defaults are these two.

For each run and test it prints the first leg end (t N = 101, 111, … as `--until-steady`
checks after 100 revolutions and every 10 after) at which the test passes, the level there
(the mean over the last 20 revolutions, the report's ⟨z_p⟩/H), and that level's difference
from the run's own final level (the mean over its last 30 revolutions): how far below or
above its later level a run would have stopped. The final level is only a reference where the
run itself ends on a plateau; the table says how long each run is.
"""
import csv
import json
import math
import os
import sys

BATCHES = 10
REV_EPS = 1e-9
DEFAULT_TESTS = ["20:0.005:2:0.015", "20:0.005"]


def load(path):
    base = path if os.path.exists(os.path.join(path, "timeseries.csv")) else os.path.join(path, "run")
    m = json.load(open(os.path.join(path, "manifest.json")))
    s = float(m["scale"])
    nz = round(240 * s)
    spr = 4000 * s
    rows = list(csv.DictReader(open(os.path.join(base, "timeseries.csv"))))
    return [(float(r["step"]) / spr, (float(r["particle_mean_z"]) + 0.5) / nz) for r in rows], s


def fit(points):
    n = len(points)
    if n < 2:
        return None
    rm = sum(p[0] for p in points) / n
    vm = sum(p[1] for p in points) / n
    sxx = sum((p[0] - rm) ** 2 for p in points)
    if sxx == 0:
        return None
    return sum((p[0] - rm) * (p[1] - vm) for p in points) / sxx, rm, vm


def drift_se(w, start, window):
    sums = [[0.0, 0.0, 0] for _ in range(BATCHES)]
    for r, v in w:
        k = min(max(int(math.floor((r - start) / window * BATCHES)), 0), BATCHES - 1)
        sums[k][0] += r
        sums[k][1] += v
        sums[k][2] += 1
    pts = [(a / n, b / n) for a, b, n in sums if n > 0]
    if len(pts) < 3:
        return float("nan")
    f = fit(pts)
    if f is None:
        return float("nan")
    slope, rm, vm = f
    res = sum((v - (vm + slope * (r - rm))) ** 2 for r, v in pts)
    sxx = sum((r - rm) ** 2 for r, _ in pts)
    return math.sqrt(res / ((len(pts) - 2) * sxx)) * window


def steady(series, window, tol, k=None, cap=None):
    """The test `window:tol` (k None) or `window:tol:k:cap`: (steady, drift, σ)."""
    last = series[-1][0]
    cutoff = last - window - REV_EPS * max(window, 1.0)
    w = [p for p in series if p[0] >= cutoff]
    f = fit(w)
    if f is None or last - series[0][0] < window * (1 - REV_EPS):
        return False, float("nan"), float("nan")
    d = f[0] * window
    se = drift_se(w, last - window, window)
    if k is None:
        return abs(d) <= tol and not se > tol, d, se
    noise = k * se if math.isfinite(se) else 0.0
    return (abs(d) - noise <= tol and abs(d) <= cap), d, se


def mean_last(series, revs):
    last = series[-1][0]
    w = [v for t, v in series if t >= last - revs - REV_EPS]
    return sum(w) / len(w)


def main(argv):
    tests, runs = [], []
    it = iter(argv)
    for a in it:
        if a == "--test":
            tests.append(next(it))
        elif "=" in a:
            label, path = a.split("=", 1)
            runs.append((label, path))
        else:
            sys.exit(__doc__)
    if not runs:
        sys.exit(__doc__)
    tests = tests or DEFAULT_TESTS
    print("| run | t N at the end | final level (last 30) | test | first leg passing | drift ± σ there | level there | level − final |")
    print("|---|---|---|---|---|---|---|---|")
    for label, path in runs:
        series, _ = load(path)
        end = series[-1][0]
        final = mean_last(series, 30)
        for t in tests:
            w, tol, *rest = (float(x) for x in t.split(":"))
            k, cap = rest if rest else (None, None)
            found = None
            leg = 101.0
            while leg <= end + 1e-6:
                part = [p for p in series if p[0] <= leg + 1e-9]
                ok, d, se = steady(part, w, tol, k, cap)
                if ok:
                    found = (leg, d, se, mean_last(part, 20))
                    break
                leg += 10
            if found:
                leg, d, se, lvl = found
                print(f"| {label} | {end:.0f} | {final:.4f} | {t} | {leg:.0f} | {d:+.4f} ± {se:.4f} | {lvl:.4f} | {lvl - final:+.4f} |")
            else:
                print(f"| {label} | {end:.0f} | {final:.4f} | {t} | – | | | |")


if __name__ == "__main__":
    main(sys.argv[1:])
