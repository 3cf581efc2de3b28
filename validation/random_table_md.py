#!/usr/bin/env python3
"""Markdown summary of validation/data/random_conductivity.csv for
docs/validation-conductance.md ("Random periodic packings")."""
import csv
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fe_random as fr  # noqa: E402


def corner_order(x):
    return 2 * math.pi / (1.5 * math.pi - math.asin(x))


def main(path=fr.TABLE):
    with open(path) as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    cases = {}
    for r in rows:
        cases.setdefault(r["case"], []).append(r)
    print("| case | spheres (radii) | necks | mean h/r | mean Z | FE levels: ⟨κ⟩/κ_s | observed p | "
          "FE converged ⟨κ⟩/κ_s | disc. error (±) | with p = 2π/ω | network fe_fit | dev. fe_fit | network linear | dev. linear | "
          "dev. per axis (fe_fit) |")
    print("|" + "---|" * 15)
    for name, rs in cases.items():
        lv = [r for r in rs if r["level"] != "extrap"]
        ex = [r for r in rs if r["level"] == "extrap"][0]
        fe = [float(r["fe_mean"]) for r in lv]
        fx = float(ex["fe_mean"])
        p = float(ex["ndofs"])
        # error band: |extrapolated - finest|, and the extrapolation with the
        # corner-limited order 2 pi/omega of the smallest... (mean a/r)
        err = abs(fe[-1] - fx)
        nf, nl = float(ex["net_fit_mean"]), float(ex["net_lin_mean"])
        # pessimistic: the corner-limited order of the mean neck, last two levels
        import fe_conductance as fc
        hr = float(lv[0]["mean_h_over_r"])
        x = fc.neck_radius(1.0, 1.0, hr)[0]
        hs = [float(r["ndofs"]) ** (-1 / 3) for r in lv[-2:]]
        pc = corner_order(x)
        fpess = fe[-1] - (fe[-2] - fe[-1]) / ((hs[0] / hs[1]) ** pc - 1)
        dax = [float(ex[f"net_fit_{c}"]) / float(ex[f"fe_{c}"]) - 1 for c in ("xx", "yy", "zz")]
        sp = "equal" if float(lv[0]["spread"]) == 0 else f"±{100 * float(lv[0]['spread']):.0f} %"
        print(f"| {name} | {lv[0]['n']} ({sp}) | {lv[0]['contacts']} | {float(lv[0]['mean_h_over_r']):.3f} | "
              f"{float(lv[0]['coordination_mean']):.2f} | {', '.join(f'{v:.5f}' for v in fe)} | {p:.2f} | "
              f"**{fx:.5f}** | {100 * err / fx:.2f} % | {fpess:.5f} (net {100 * (nf / fpess - 1):+.1f} %) | {nf:.5f} | **{100 * (nf / fx - 1):+.2f} %** | "
              f"{nl:.5f} | {100 * (nl / fx - 1):+.2f} % | "
              f"{', '.join(f'{100 * d:+.1f}' for d in dax)} % |")


if __name__ == "__main__":
    main(*sys.argv[1:])
