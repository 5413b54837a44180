"""Explicit 8 sub-steps vs limiter 2 sub-steps, pbt-ld2 s=1/4, same bed: <z_p>/H and Po by 10-revolution windows."""
import csv, sys
H = 60.0
SPR = 1000.0
def load(p):
    rows = list(csv.DictReader(open(p)))
    return [(float(r['step']) / SPR, (float(r['particle_mean_z']) + 0.5) / H, float(r['po_fluid']), float(r['po_solids'])) for r in rows]
a = load(sys.argv[1]); b = load(sys.argv[2])
end = min(a[-1][0], b[-1][0])
def win(x, lo, hi):
    s = [r for r in x if lo <= r[0] < hi]
    n = len(s)
    return (sum(r[1] for r in s) / n, sum(r[2] for r in s) / n, sum(r[3] for r in s) / n, n) if n else None
print(f"{'revs':>10} | {'zp expl':>8} {'zp lim2':>8} {'diff':>7} | {'Pof expl':>8} {'Pof lim2':>8} | {'Poc expl':>8} {'Poc lim2':>8}")
lo = 1.0
while lo < end:
    hi = min(lo + 10, end + 1e-9)
    x, y = win(a, lo, hi), win(b, lo, hi)
    if x and y:
        print(f"{lo:4.0f}-{hi:4.0f} | {x[0]:8.4f} {y[0]:8.4f} {y[0]-x[0]:+7.4f} | {x[1]:8.3f} {y[1]:8.3f} | {x[2]:8.3f} {y[2]:8.3f}")
    lo += 10
