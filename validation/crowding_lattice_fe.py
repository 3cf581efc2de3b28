#!/usr/bin/env python3
"""FE of sintered SC, FCC and BCC lattices (equal spheres, one conventional cell,
periodic) for the multi-neck correction (docs/validation-conductance.md
"Several necks per sphere"): every neck has the same overlap h, so the angle
structure of the correction is tested without randomness.  Writes
validation/data/lattice_crowding.csv.  Usage: python crowding_lattice_fe.py [NAME ...]
"""
import csv
import itertools
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fe_random as fr  # noqa: E402
import random_packing as rp  # noqa: E402

LATTICES = {"sc-h012": ("sc", 0.12), "fcc-h006": ("fcc", 0.06), "fcc-h012": ("fcc", 0.12),
            "bcc-h006": ("bcc", 0.06), "bcc-h012": ("bcc", 0.12),
            # late stage (issue 42), written with FE_OUT=lattice_late.csv: beyond the fitted range
            "fcc-h016": ("fcc", 0.16), "bcc-h020": ("bcc", 0.20), "sc-h030": ("sc", 0.30)}
OUT = os.path.join(fr.DATA, os.environ.get("FE_OUT", "lattice_crowding.csv"))


def lattice(kind: str, h: float) -> rp.Packing:
    """One conventional cell of touching-and-sintered equal spheres (r = 1),
    nearest-neighbour overlap h; bonds with their periodic images."""
    d = 2.0 - h
    if kind == "sc":
        L = d
        basis = np.array([[0, 0, 0]])
    elif kind == "fcc":
        L = d * math.sqrt(2.0)
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    elif kind == "bcc":
        L = 2.0 * d / math.sqrt(3.0)
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0.5]])
    else:
        raise ValueError(kind)
    x = np.mod((basis + np.array([0.137, 0.219, 0.311])) * L, L)
    n = len(x)
    bonds, shifts = [], []
    for i in range(n):
        for j in range(i, n):
            for s in itertools.product((-1, 0, 1), repeat=3):
                if i == j and s <= (0, 0, 0):
                    continue
                dv = x[j] + L * np.array(s) - x[i]
                if abs(np.linalg.norm(dv) - d) < 1e-9:
                    bonds.append((i, j))
                    shifts.append(s)
    return rp.Packing(x=x, r=np.ones(n), L=L, bonds=np.array(bonds), shifts=np.array(shifts),
                      meta=dict(kind=kind, h=h, seed=0))


def run(name, levels=tuple(int(v) for v in os.environ.get("FE_LEVELS", "1 2 3").split())):
    kind, h = LATTICES[name]
    pk = lattice(kind, h)
    Ks, infos = fr.fe_kappa_levels(pk, levels, verbose=True)
    hs = [info["ndofs"] ** (-1.0 / 3.0) for info in infos]
    tr = [np.trace(K) / 3 for K in Ks]
    mean_x, p = fr.extrapolate(hs[-3:], tr[-3:])
    return dict(case=name, kind=kind, h_over_r=h, contacts=len(pk.bonds), n=len(pk.r),
                levels=" ".join(map(str, levels)), fe_levels=" ".join(f"{t:.7g}" for t in tr),
                fe_mean=mean_x, order=p)


def main(names):
    rows = []
    if os.path.exists(OUT):       # keep the cases already computed
        with open(OUT) as fh:
            rows = [r for r in csv.DictReader(ln for ln in fh if not ln.startswith("#")) if r["case"] not in names]
    for name in names:
        rows.append(run(name))
        print("DONE", rows[-1], flush=True)
        with open(OUT + ".tmp", "w") as fh:
            fh.write("# 3-D periodic FE kappa_eff/kappa_s (mean of the diagonal) of sintered FCC/BCC "
                     "cells, validation/crowding_lattice_fe.py; fe_mean extrapolated as fe_random.py\n")
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        os.replace(OUT + ".tmp", OUT)


if __name__ == "__main__":
    main(sys.argv[1:] or list(LATTICES))
