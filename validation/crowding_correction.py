#!/usr/bin/env python3
"""Trial of a neck-crowding correction of the half-pipe conductance against
the 3-D FE table (validation/data/random_conductivity.csv), with the Python
twin of the network (random_packing.network_kappa_py).  NOT in sinterdem.

Form (docs/validation-conductance.md "Random periodic packings", analysis):
fe_fit writes the half conductance as K_i = kappa pi a / D(x), x = a/r_i, and
D(0) = pi/4 is Holm's constriction of a small neck on a large body; the rest,
D(x) - pi/4, is the resistance of the sphere segment behind the neck, which
the pair geometry computes for a whole hemisphere per neck.  With several
necks the sphere body is shared; the correction scales that part by
    phi_i = 1 + k c_i^q,   c_i = sum over the necks of sphere i of h_c/(2 r_i)
(the fraction of the sphere's surface under neck caps; c = x^2/4 for one
small neck), fitted (k, q) on the equal-sphere cases and checked on the
size-spread cases (other packings, other seeds).
"""
import csv
import math
import os
import sys

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fe_conductance as fc  # noqa: E402
import fe_random as fr  # noqa: E402
import random_packing as rp  # noqa: E402
from test_conductance import rust_fit_coefficients  # noqa: E402

COEF = rust_fit_coefficients()


def coverage(pk):
    c = np.zeros(len(pk.r))
    for k in fr.necks(pk):
        for s in ("i", "j"):
            idx = k[s]
            r = pk.r[idx]
            c[idx] += fc.cap_height(r, k["a"]) / (2 * r)
    return c


def kappa(pk, k=0.0, q=1.0):
    c = coverage(pk)
    nk = fr.necks(pk)

    def half(a, r, e, side):
        x = a / r
        D = 1.0 / fc.fe_fit_eval(x, COEF)
        ci = c[nk[e][side]]
        return math.pi * a / (math.pi / 4 + (D - math.pi / 4) * (1 + k * ci ** q))
    return rp.network_kappa_py(pk, half)


def load():
    with open(fr.TABLE) as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    out = {}
    for r in rows:
        if r["level"] == "extrap":
            out[r["case"]] = np.array([float(r[f"fe_{c}"]) for c in ("xx", "yy", "zz")])
    return out


def main():
    fe = load()
    pks = {n: rp.make_packing(*fr.CASES[n]) for n in fe}
    train = [n for n in fe if not n.startswith("n16s")]
    test = [n for n in fe if n.startswith("n16s")]

    def dev(n, k, q):
        return np.diag(kappa(pks[n], k, q)) / fe[n] - 1

    def obj(p):
        return float(sum(np.sum(dev(n, *p) ** 2) for n in train))
    best = minimize(obj, [3.0, 1.5], method="Nelder-Mead", options=dict(xatol=1e-4, fatol=1e-10))
    k, q = best.x
    print(f"fitted on {train}: k = {k:.4f}, q = {q:.4f}")
    print("| case | mean coverage c | dev. fe_fit (mean; per axis) | dev. corrected (mean; per axis) | role |")
    print("|---|---|---|---|---|")
    for n in fe:
        d0, d1 = dev(n, 0.0, 1.0), dev(n, k, q)
        m0 = np.trace(kappa(pks[n])) / fe[n].sum() - 1
        m1 = np.trace(kappa(pks[n], k, q)) / fe[n].sum() - 1
        print(f"| {n} | {coverage(pks[n]).mean():.3f} | {100 * m0:+.2f} %; "
              f"{', '.join(f'{100 * v:+.1f}' for v in d0)} | {100 * m1:+.2f} %; "
              f"{', '.join(f'{100 * v:+.1f}' for v in d1)} | {'fit' if n in train else 'check'} |")


if __name__ == "__main__":
    main()
