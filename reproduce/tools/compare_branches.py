#!/usr/bin/env python3
"""Paired comparison of two continuations of one run (the same checkpoint, two contact schemes).

Usage: compare_branches.py NZ FIRST_REV LAST_REV LABEL=RUN_DIR [LABEL=RUN_DIR ...]

For each run directory (a `slurry reproduce` output: run/timeseries.csv), over revolutions
FIRST_REV..LAST_REV (counted as the report counts them, step / steps_per_revolution, the
steps per revolution 1 / |speed| of the impeller in the run's own run/case.toml, as the
reproduction takes them: 1000 at s = 1/4, 2000 at s = 1/2): the means of <z_p>/H ((particle_mean_z + 1/2) / NZ: heights from the bottom wall, as the report's), Po_f, Po_c
and Po; their standard errors from 5-revolution block means (the blocks' spread / sqrt(n),
which allows for the samples' correlation within a block); the median MLUPS. Then each run's
difference from the first, with the combined standard error, and the paired difference: the
mean of the 5-revolution blocks' differences with the standard error of their spread (the two
branches share the trend of a run still rising, which the paired form cancels). Prints a
Markdown table. Used by the archived branch comparisons
(reproduce/pbt-ld2/runs/2026-11-26-s0.25-branch, reproduce/disk-ld1/runs/2026-11-27-s0.25-branch);
the paired line was added on 2026-11-27, the other lines are as the first comparison printed them.
"""
import csv, math, statistics, sys, tomllib

def load(path):
    with open(path) as f:
        return list(csv.DictReader(f))

def steps_per_revolution(run_dir):
    """1 / |impeller speed| of the run's case (what `reproduce` schedules the run with)."""
    with open(f"{run_dir}/run/case.toml", "rb") as f:
        return 1.0 / abs(tomllib.load(f)["impeller"]["speed"])

def block_stats(rows, key, first, last, scale, spr, block=5):
    vals = {}
    for r in rows:
        rev = int(r["step"]) / spr
        if first < rev <= last:
            b = int((rev - first - 1e-9) // block)
            vals.setdefault(b, []).append(scale(float(r[key])))
    means = [statistics.fmean(v) for _, v in sorted(vals.items())]
    allv = [x for v in vals.values() for x in v]
    m = statistics.fmean(allv)
    se = statistics.stdev(means) / math.sqrt(len(means)) if len(means) > 1 else float("nan")
    return m, se, means

def main():
    nz, first, last = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
    runs = [a.split("=", 1) for a in sys.argv[4:]]
    spr = {steps_per_revolution(d) for _, d in runs}
    if len(spr) != 1:
        sys.exit(f"the runs have different steps per revolution: {sorted(spr)}")
    spr = spr.pop()
    # Heights from the bottom wall, half a node below the first node (the report's H = NZ).
    same = lambda x: x
    keys = [("particle_mean_z", "<z_p>/H", lambda z: (z + 0.5) / nz), ("po_fluid", "Po_f", same),
            ("po_solids", "Po_c", same), ("po", "Po", same)]
    res = {}
    for label, d in runs:
        rows = load(f"{d}/run/timeseries.csv")
        res[label] = {name: block_stats(rows, k, first, last, s, spr) for k, name, s in keys}
        ml = [float(r["mlups"]) for r in rows if first < int(r["step"]) / spr <= last and float(r["mlups"]) > 0]
        res[label]["mlups"] = statistics.median(ml) if ml else float("nan")
    print(f"Revolutions {first:g}–{last:g}; standard errors from {int((last-first)//5)} blocks of 5 revolutions.\n")
    print("| run | " + " | ".join(n for _, n, _ in keys) + " | median MLUPS |")
    print("|---|" + "---|" * (len(keys) + 1))
    for label, _ in runs:
        cells = [f"{res[label][n][0]:.4f} ± {res[label][n][1]:.4f}" for _, n, _ in keys]
        print(f"| {label} | " + " | ".join(cells) + f" | {res[label]['mlups']:.2f} |")
    base = runs[0][0]
    for label, _ in runs[1:]:
        cells = []
        for _, n, _ in keys:
            (a, sa, _), (b, sb, _) = res[base][n], res[label][n]
            d, s = b - a, math.hypot(sa, sb)
            cells.append(f"{d:+.4f} ± {s:.4f} ({d / s:+.1f} σ)" if s > 0 else f"{d:+.4f}")
        print(f"| {label} − {base} | " + " | ".join(cells) + " | |")
        cells = []
        for _, n, _ in keys:
            d = [b - a for a, b in zip(res[base][n][2], res[label][n][2])]
            m = statistics.fmean(d)
            s = statistics.stdev(d) / math.sqrt(len(d)) if len(d) > 1 else float("nan")
            cells.append(f"{m:+.4f} ± {s:.4f} ({m / s:+.1f} σ)" if s > 0 else f"{m:+.4f}")
        print(f"| {label} − {base}, paired blocks | " + " | ".join(cells) + " | |")
    print()
    for label, _ in runs:
        for _, n, _ in keys:
            print(f"{label} {n} 5-rev blocks: " + ", ".join(f"{x:.4f}" for x in res[label][n][2]))

main()
