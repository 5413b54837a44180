#!/usr/bin/env python3
"""How much of the bed moves: the particles at rest and the moving ones, per window of revolutions.

Usage: mobility.py [--every W] LABEL=DIR[:FIRST:LAST] [LABEL=DIR[:FIRST:LAST] ...]

DIR is a `slurry reproduce` output directory, finished or still running: its particle history
(run/particles.h5 and run/particles.frames/, every frame) and run/case.toml. Archives hold no
particle history, so this reads runs in their campaign directories. Needs h5py and numpy.

Time is t N = step / steps per revolution (1 / |impeller speed| of the run's case, as the
reproduction schedules it), less 1 for the ramp: revolutions after the ramp, as in the report.
The window is FIRST-LAST in those revolutions (default: the run's last 10); with --every W,
consecutive windows of W revolutions over the whole run instead.

In a window, a particle is **at rest** when its speed stays below 1 % of the blade tip speed in
every frame (pi D N, 0.1037 lattice units at every scale of the paper's cases) and its centre
moves less than half a diameter from the window's first frame to its last. Printed per window,
as a Markdown table: <z_p>/H (heights from the floor, (z + 1/2) / NZ, as the report), the share
of the particles at rest and their mean height, the moving particles' mean height, and the
share of particles by their mean height in the window.
"""
import glob, math, os, sys, tomllib

import h5py
import numpy as np

REST_SPEED = 0.01  # of the tip speed
BANDS = [0.0, 0.1, 0.2, 0.3, 0.5, 1.0]


def load(d):
    """(revolutions after the ramp, positions, velocities, diameter, NZ, tip speed) of run `d`."""
    with open(f"{d}/run/case.toml", "rb") as f:
        c = tomllib.load(f)
    speed, nz = abs(c["impeller"]["speed"]), c["domain"]["nz"]
    tip = math.pi * c["impeller"]["diameter"] * speed  # π D N, N in revolutions per step
    g = h5py.File(f"{d}/run/particles.h5", "r")
    steps, pos, vel = [g["step"][:]], [g["position"][:]], [g["velocity"][:]]
    for seg in sorted(glob.glob(f"{d}/run/particles.frames/*.h5")):
        h = h5py.File(seg, "r")
        steps.append(h["step"][:]), pos.append(h["position"][:]), vel.append(h["velocity"][:])
    steps = np.concatenate(steps)
    return steps * speed - 1.0, np.concatenate(pos), np.concatenate(vel), float(g["diameter"][0]), nz, tip


def window(rev, pos, vel, d, nz, tip, a, b):
    """One table row's cells for revolutions a-b, or None if no frame falls in it."""
    w = (rev >= a) & (rev <= b)
    if w.sum() < 2:
        return None
    p, v = pos[w], vel[w]
    rest = (np.linalg.norm(v, axis=2).max(axis=0) < REST_SPEED * tip) & (np.linalg.norm(p[-1] - p[0], axis=1) < d / 2)
    z = (p[..., 2] + 0.5) / nz
    zm = z.mean(axis=0)
    mean = lambda m: f"{zm[m].mean():.3f}" if m.any() else "–"
    bands = [((zm >= lo) & (zm < hi)).mean() for lo, hi in zip(BANDS[:-1], BANDS[1:])]
    return [f"{a:.1f}–{b:.1f}", str(int(w.sum())), f"{z.mean():.4f}", f"{100 * rest.mean():.1f}", mean(rest), mean(~rest)] + [
        f"{100 * x:.1f}" for x in bands
    ]


def main():
    args = sys.argv[1:]
    every = None
    if args[:1] == ["--every"]:
        every, args = float(args[1]), args[2:]
    if not args:
        sys.exit(__doc__)
    head = ["run", "revolutions", "frames", "<z_p>/H", "at rest %", "at rest: mean z/H", "moving: mean z/H"]
    head += [f"z/H {lo}–{hi} %" for lo, hi in zip(BANDS[:-1], BANDS[1:])]
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head))
    for arg in args:
        label, rest = arg.split("=", 1)
        parts = rest.split(":")
        rev, pos, vel, d, nz, tip = load(parts[0])
        if every:
            wins = [(a, a + every) for a in np.arange(max(rev[0], 0.0), rev[-1] - every + 1e-9, every)]
        elif len(parts) == 3:
            wins = [(float(parts[1]), float(parts[2]))]
        else:
            wins = [(rev[-1] - 10.0, rev[-1])]
        for a, b in wins:
            row = window(rev, pos, vel, d, nz, tip, a, b)
            if row:
                print(f"| {label} | " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
