#!/usr/bin/env python3
"""How fast the suspension rises: one case at several scales (the resolution study's transient).

Usage: lift_rates.py LABEL=DIR [LABEL=DIR ...]

DIR is an archived run (`reproduce/<case>/runs/<name>`: timeseries.csv, reproduce.json) or a
`slurry reproduce` output, finished or still running (run/timeseries.csv, run/case.toml). The
time is step / steps per revolution (the archive's schedule, or 1 / |impeller speed| of the
run's case: what the reproduction schedules with), <z_p>/H is (particle_mean_z + 1/2) / NZ, as
the report computes it (heights from the bottom wall, H = NZ).

Prints three Markdown tables:
1. the bed's <z_p>/H (the first row) and the revolution at which the 2-revolution block means
   of <z_p>/H first reach each of the LEVELS ("bed": the bed is already there; "–": not
   within the run);
2. the rise rate at each level: the least-squares slope of <z_p>/H, per 10 revolutions, over
   the 10 revolutions centred on that crossing (where the run covers them), so that runs whose
   beds start at different heights are compared at the same suspension level;
3. the 10-revolution means.
"""
import csv, json, os, statistics, sys, tomllib

LEVELS = [0.15, 0.16, 0.18, 0.20, 0.22, 0.25, 0.28, 0.30]
BLOCK = 2.0  # revolutions per block mean for the crossings
WINDOW = 10.0  # revolutions of the slope fit, centred on the crossing


def load(d):
    """(revolutions, <z_p>/H) of run or archive `d`."""
    if os.path.isfile(f"{d}/reproduce.json"):
        with open(f"{d}/reproduce.json") as f:
            r = json.load(f)
        spr, nz, ts = r["schedule"]["steps_per_revolution"], r["run"]["grid"]["nz"], f"{d}/timeseries.csv"
    else:
        with open(f"{d}/run/case.toml", "rb") as f:
            c = tomllib.load(f)
        spr, nz, ts = 1.0 / abs(c["impeller"]["speed"]), c["domain"]["nz"], f"{d}/run/timeseries.csv"
    with open(ts) as f:
        rows = list(csv.DictReader(f))
    return [int(r["step"]) / spr for r in rows], [(float(r["particle_mean_z"]) + 0.5) / nz for r in rows]


def slope(t, z):
    mt, mz = statistics.fmean(t), statistics.fmean(z)
    return sum((a - mt) * (b - mz) for a, b in zip(t, z)) / sum((a - mt) ** 2 for a in t)


def crossing(t, z, level):
    """The end of the first 2-revolution block whose mean reaches `level`, or None."""
    blocks = {}
    for a, b in zip(t, z):
        blocks.setdefault(int(a // BLOCK), []).append(b)
    for k in sorted(blocks):
        if statistics.fmean(blocks[k]) >= level:
            return (k + 1) * BLOCK
    return None


def main():
    runs = [a.split("=", 1) for a in sys.argv[1:]]
    if not runs:
        sys.exit(__doc__)
    data = {label: load(d) for label, d in runs}
    print("| run | bed | last revolution | " + " | ".join(f"reaches {l:.2f}" for l in LEVELS) + " |")
    print("|---|---|---|" + "---|" * len(LEVELS))
    for label, (t, z) in data.items():
        cells = ["bed" if z[0] >= l else "–" if c is None else f"{c:.0f}" for l, c in ((l, crossing(t, z, l)) for l in LEVELS)]
        print(f"| {label} | {z[0]:.4f} | {t[-1]:.1f} | " + " | ".join(cells) + " |")
    print("\nRise rate of <z_p>/H per 10 revolutions over the 10 revolutions centred on each crossing:\n")
    print("| run | " + " | ".join(f"at {l:.2f}" for l in LEVELS) + " |")
    print("|---|" + "---|" * len(LEVELS))
    for label, (t, z) in data.items():
        cells = []
        for l in LEVELS:
            c = crossing(t, z, l)
            lo, hi = (c - BLOCK / 2 - WINDOW / 2, c - BLOCK / 2 + WINDOW / 2) if c is not None else (0, 0)
            sel = [(a, b) for a, b in zip(t, z) if lo <= a < hi]
            ok = c is not None and z[0] < l and lo >= t[0] and hi <= t[-1] and len(sel) > 3
            cells.append(f"{10 * slope(*zip(*sel)):.4f}" if ok else "–")
        print(f"| {label} | " + " | ".join(cells) + " |")
    print("\n10-revolution means of <z_p>/H:\n")
    n = max(int(t[-1] // 10) for t, _ in data.values())
    print("| run | " + " | ".join(f"{10 * k}–{10 * k + 10}" for k in range(n)) + " |")
    print("|---|" + "---|" * n)
    for label, (t, z) in data.items():
        cells = []
        for k in range(n):
            v = [b for a, b in zip(t, z) if 10 * k <= a < 10 * k + 10]
            full = t[-1] >= 10 * k + 10
            cells.append(f"{statistics.fmean(v):.3f}" if v and full else "–")
        print(f"| {label} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
