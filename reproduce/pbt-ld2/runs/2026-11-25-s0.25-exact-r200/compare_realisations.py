"""pbt-ld2 at s = 1/4, three runs from the same seeded dry bed, by 10-revolution windows:
A the explicit run archived as 2026-11-25-s0.25-r100 (bed read from the cache one ulp off),
B the explicit run of the exact bed (this archive), C the limiter at 2 sub-steps
(2026-11-25-s0.25-lim2-r100, the same ulp-off bed as A). A and B differ only by the ulp:
their difference is the spread of two realisations of the same chaotic flow, against which
the limiter's difference C - A is judged.
usage: compare_realisations.py A.csv B.csv C.csv"""
import csv, sys
H, SPR = 60.0, 1000.0

def load(p):
    rows = list(csv.DictReader(open(p)))
    return [(float(r['step']) / SPR, (float(r['particle_mean_z']) + 0.5) / H,
             float(r['po_fluid']), float(r['po_solids'])) for r in rows]

runs = [load(p) for p in sys.argv[1:4]]
end = max(r[-1][0] for r in runs)

def win(x, lo, hi):
    s = [r for r in x if lo <= r[0] < hi]
    return tuple(sum(r[k] for r in s) / len(s) for k in (1, 2, 3)) if s and s[-1][0] >= hi - 0.5 else None

print("| revolutions | ⟨z_p⟩/H A | B | C | B − A | C − A | Po_f A | B | C | Po_c A | B | C |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
lo = 1.0
while lo < end:
    hi = lo + 10
    w = [win(r, lo, hi) for r in runs]
    if not any(w):
        break
    f = lambda v, k, fmt: (fmt.format(v[k]) if v else "—")
    d = lambda a, b: (f"{b[0] - a[0]:+.4f}" if a and b else "—")
    print(f"| {lo:.0f}–{hi:.0f} | " + " | ".join(f(v, 0, "{:.4f}") for v in w)
          + f" | {d(w[0], w[1])} | {d(w[0], w[2])} | "
          + " | ".join(f(v, 1, "{:.3f}") for v in w) + " | " + " | ".join(f(v, 2, "{:.3f}") for v in w) + " |")
    lo += 10
