"""Po_c against <z_p>/H over 10-revolution windows of timeseries.csv, and their least-squares line.

usage: python3 po_c_vs_height.py timeseries.csv > po_c_vs_height.md
Revolutions are the impeller's angle over 2 pi (t N from the impeller's start); heights above the
floor z = -0.5 of the 60-node box (s = 1/4).
"""
import csv
import math
import sys

rows = list(csv.DictReader(open(sys.argv[1])))
H = 60.0
rev = [float(r["impeller_angle"]) / (2 * math.pi) for r in rows]
z = [(float(r["particle_mean_z"]) + 0.5) / H for r in rows]
pc = [float(r["po_solids"]) for r in rows]
pf = [float(r["po_fluid"]) for r in rows]
windows = []
for lo in range(11, 201, 10):
    idx = [i for i, t in enumerate(rev) if lo <= t < lo + 10]
    mean = lambda v: sum(v[i] for i in idx) / len(idx)
    windows.append((lo, mean(z), mean(pc), mean(pf)))
n = len(windows)
mx = sum(w[1] for w in windows) / n
my = sum(w[2] for w in windows) / n
sxx = sum((w[1] - mx) ** 2 for w in windows)
syy = sum((w[2] - my) ** 2 for w in windows)
sxy = sum((w[1] - mx) * (w[2] - my) for w in windows)
slope = sxy / sxx
icpt = my - slope * mx
r = sxy / math.sqrt(sxx * syy)
print("| revolutions | <z_p>/H | Po_c | Po_f |")
print("|---|---|---|---|")
for lo, zz, c, f in windows:
    print(f"| {lo}–{lo + 10} | {zz:.4f} | {c:.3f} | {f:.3f} |")
print()
print(f"Least squares over the {n} windows: Po_c = {slope:.2f} <z_p>/H {icpt:+.2f} "
      f"(correlation {r:.3f}); at the paper's <z_p>/H = 0.31 the line gives Po_c = {slope * 0.31 + icpt:.3f}.")
