#!/usr/bin/env python3
"""The multi-neck correction of the half-pipe conductance (docs/heat-model.md
(H8a)-(H8c), `thermal.multi_neck = "fabric"`, src/heat/conductance.rs) against
the 3-D FE: its Python twin, the fit of its one constant beta, and the table of
docs/validation-conductance.md "Several necks per sphere".

    phi_k = (n_k^T M_i n_k + max(0, 2 a_k - A_i)) / (2 a_k),
    M_i = sum_l a_l n_l n_l^T,  A_i = sum_l a_l          (necks l of particle i)   (H8a)
    1/K_k = 1/K_pair(a_k, r_i) + (phi_k - 1) beta / (kappa pi r_i)                  (H8b)

Fitted on (train): the three equal-sphere packings of random_conductivity.csv
and the FCC cells at h/r = 0.06, 0.12 (lattice_crowding.csv).  Checked on
(check, not used in the fit): the three size-spread packings, the new seeds of
random_crowding*.csv, the BCC and SC cells.
Usage: python validation/crowding_correction.py [--fit]
"""
import csv
import glob
import math
import os
import sys

import numpy as np
from scipy.optimize import minimize_scalar

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import crowding_fe  # noqa: E402
import crowding_lattice_fe as cl  # noqa: E402
import fe_conductance as fc  # noqa: E402
import fe_random as fr  # noqa: E402
import random_packing as rp  # noqa: E402
from test_conductance import rust_fit_coefficients  # noqa: E402

COEF = rust_fit_coefficients()
BETA = 0.857          # src/heat/conductance.rs MULTI_NECK_BETA
TRAIN = ("n16-h002", "n16-h006", "n16-h012", "fcc-h006", "fcc-h012")


def crowding(pk):
    """phi per (bond, 'i'|'j') of (H8a)."""
    b = pk.branch()
    per = [[] for _ in pk.r]
    for e, (i, j) in enumerate(pk.bonds):
        d = float(np.linalg.norm(b[e]))
        a = fc.neck_radius(pk.r[i], pk.r[j], pk.r[i] + pk.r[j] - d)[0]
        per[i].append((e, "i", b[e] / d, a))
        per[j].append((e, "j", -b[e] / d, a))
    phi = {}
    for lst in per:
        total = sum(a for *_, a in lst)
        for e, s, n, a in lst:
            q = sum(a2 * float(n @ n2) ** 2 for _, _, n2, a2 in lst)
            phi[(e, s)] = (q + max(0.0, 2 * a - total)) / (2 * a)
    return phi


def kappa(pk, beta=BETA, phi=None):
    """kappa_eff/kappa_s of the network with the fe_fit law and (H8b); beta = 0:
    multi_neck = "none"."""
    phi = crowding(pk) if phi is None else phi

    def half(a, r, e, side):
        pair = 1.0 / (fc.fe_fit_eval(a / r, COEF) * math.pi * a)
        res = pair + (phi[(e, side)] - 1.0) * beta / (math.pi * r)
        return 1.0 / max(res, 0.5 * pair)
    return rp.network_kappa_py(pk, half)


def _extrap(path):
    """case -> (converged diagonal, mean of the finest level's diagonal)."""
    with open(path) as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    finest = {}
    for r in rows:
        if r["level"] != "extrap":
            finest[r["case"]] = float(r["fe_mean"])      # rows are in level order
    return {r["case"]: (np.array([float(r[f"fe_{c}"]) for c in ("xx", "yy", "zz")]), finest[r["case"]])
            for r in rows if r["level"] == "extrap"}


def _levels(path, name):
    """The mesh levels stored for case `name` in `path`, as "first-last"."""
    with open(path) as fh:
        lv = [int(r["level"]) for r in csv.DictReader(ln for ln in fh if not ln.startswith("#"))
              if r["case"] == name and r["level"] != "extrap"]
    return f"{min(lv)}-{max(lv)}"


def cases():
    """name -> (packing, FE diagonal (converged), role, note)."""
    out = {}
    for name, (fe, fin) in _extrap(fr.TABLE).items():
        out[name] = (fr.stored_packing(name), fe, "train" if name in TRAIN else "check",
                     "table, levels 0-4", fin)
    for path in sorted(glob.glob(os.path.join(fr.DATA, "random_crowding*.csv"))):
        for name, (fe, fin) in _extrap(path).items():
            out[name] = (fr.stored_packing(name), fe, "check",
                         "new seed, levels " + _levels(path, name), fin)
    if os.path.exists(cl.OUT):
        with open(cl.OUT) as fh:
            for r in csv.DictReader(ln for ln in fh if not ln.startswith("#")):
                v = float(r["fe_mean"])
                fin = float(r["fe_levels"].split()[-1])
                out[r["case"]] = (cl.lattice(*cl.LATTICES[r["case"]]), np.array([v, v, v]),
                                  "train" if r["case"] in TRAIN else "check", f"lattice, levels {r['levels']}", fin)
    return out


def fit(cs):
    phis = {n: crowding(c[0]) for n, c in cs.items()}

    def obj(beta):
        return sum((np.trace(kappa(cs[n][0], beta, phis[n])) / cs[n][1].sum() - 1) ** 2
                   for n in cs if cs[n][2] == "train")
    return minimize_scalar(obj, bounds=(0.1, 3.0), method="bounded",
                           options=dict(xatol=1e-5)).x


def table(cs, beta=BETA):
    """Per case: FE converged (mean of the per-axis extrapolations) and finest level, the
    extrapolation's change of the finest level ('conv'), networks before/after, deviations."""
    rows = []
    for n, (pk, fe, role, note, fin) in cs.items():
        st = rp.stats(pk)
        k0, k1 = np.diag(kappa(pk, 0.0)), np.diag(kappa(pk, beta))
        rows.append(dict(case=n, role=role, note=note, h=st["mean_h_over_r"], z=st["coordination_mean"],
                         fe=fe.mean(), finest=fin, conv=1 - fe.mean() / fin, before=k0.mean(), after=k1.mean(),
                         d0=k0.sum() / fe.sum() - 1, d1=k1.sum() / fe.sum() - 1, ax1=k1 / fe - 1))
    return rows


def main():
    cs = cases()
    beta = BETA
    if "--fit" in sys.argv:
        beta = fit(cs)
        print(f"beta fitted on {[n for n in cs if cs[n][2] == 'train']}: {beta:.4f}")
    print("| case | role | mean h/r | coordination | FE finest level | FE converged (change) | "
          "network before (none) | network after (fabric) | before | after (mean; per axis) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in table(cs, beta):
        print(f"| {r['case']} | {r['role']} ({r['note']}) | {r['h']:.3f} | {r['z']:.2f} | {r['finest']:.5f} | "
              f"{r['fe']:.5f} ({-100 * r['conv']:+.1f} %) | "
              f"{r['before']:.5f} | {r['after']:.5f} | {100 * r['d0']:+.2f} % | {100 * r['d1']:+.2f} %; "
              f"{', '.join(f'{100 * v:+.1f}' for v in r['ax1'])} |")


if __name__ == "__main__":
    main()
