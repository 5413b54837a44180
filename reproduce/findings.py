#!/usr/bin/env python3
"""The paper's qualitative findings from archived runs (reproduce/README.md, "The paper's
qualitative findings"): per run, from its statistics.json and statistics.h5 (the report's
windows: <z_p>/H over the last 20 revolutions, the profiles and pdfs over the last 10):

- <z_p>/H: longer cylinders better suspended;
- the orientation, phi the angle between the cylinder axis and the vertical (pi/2: lying flat):
  the mean phi and the fraction with phi > 60 degrees, all particles and the mobile ones
  (z_p > 0.2 H): longer cylinders lie more horizontal;
- the L1 distance int |pdf - sin phi| dphi of the mobile particles' pdf from random orientation
  (0: the same; 2: disjoint): close to sin phi for l/d = 1;
- the linear kinetic energy over the rotational one, both integrated over the height.

usage: findings.py RUN_DIR...   (archive folders: reproduce/<case>/runs/<name>)
Needs numpy and h5py.
"""
import json
import math
import sys
from pathlib import Path

import h5py
import numpy as np


def row(run: Path) -> dict:
    st = json.loads((run / "statistics.json").read_text())
    with h5py.File(run / "statistics.h5", "r") as f:
        o = f["orientation"]
        phi, dphi = o["phi"][:], o.attrs["bin_width"]
        out = {"case": st["case"], "run": run.name, "zp": st["mean_height"], "steady": st["steady"]}
        for k in ("all", "mobile"):
            pdf = o[k][:]
            out[f"phi_{k}"] = math.degrees(float(np.sum(phi * pdf) * dphi))
            out[f"flat_{k}"] = float(np.sum(pdf[phi > math.radians(60)]) * dphi)
        out["l1_mobile"] = float(np.sum(np.abs(o["mobile"][:] - np.sin(phi))) * dphi)
        out["mobile_share"] = o.attrs["samples_mobile"] / o.attrs["samples_all"]
        ke = f["kinetic_energy"]
        out["ke_ratio"] = float(np.sum(ke["linear"][:]) / np.sum(ke["rotational"][:]))
        out["window"] = f"{o.attrs['from_rev']:.0f}-{o.attrs['to_rev']:.0f}"
    return out


def main() -> None:
    rows = [row(Path(p)) for p in sys.argv[1:]]
    print("| case | run | steady | <z_p>/H | mean phi all | mobile | phi > 60 deg all | mobile "
          "| mobile share | L1(mobile pdf, sin) | KE lin/rot | pdf window (t N) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['run']} | {'yes' if r['steady'] else 'no'} | {r['zp']:.3f} "
              f"| {r['phi_all']:.1f} deg | {r['phi_mobile']:.1f} deg | {r['flat_all']:.2f} "
              f"| {r['flat_mobile']:.2f} | {r['mobile_share']:.2f} | {r['l1_mobile']:.3f} "
              f"| {r['ke_ratio']:.0f} | {r['window']} |")


if __name__ == "__main__":
    main()
