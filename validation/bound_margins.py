#!/usr/bin/env python3
"""How far the bound (H8d) stays from acting on the stored FE cells (docs/heat-model.md (H8d)).

For every stored cell (the random 16- and 64-sphere cells of validation/data/random and the
SC/BCC/FCC lattice cells of lattice_crowding.csv) and both multi-neck laws, prints the network's
uniform-gradient (Voigt) flux T/V over the Hashin-Shtrikman bound (mean of the diagonal) and
lambda_max(T/V) over phi (Wiener), and the network's kappa_eff over HS, all with the law alone
(kappa_s = 1). The bound acts only where a Voigt ratio exceeds 1.

Usage: validation/.venv/bin/python validation/bound_margins.py
"""
import math
import os
import sys

import numpy as np
import scipy.sparse as sps
import scipy.sparse.linalg as spl

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import crowding_correction as cc  # noqa: E402
import fe_conductance as fc  # noqa: E402
import fe_random as fr  # noqa: E402


def margins(pk, half):
    """(phi, Voigt mean/HS, Voigt lambda_max/phi, kappa_eff mean/HS) of the law alone."""
    n = len(pk.r)
    b = pk.branch()
    i, j = pk.bonds[:, 0], pk.bonds[:, 1]
    hi, hj = np.empty(len(i)), np.empty(len(i))
    for e, (ii, jj) in enumerate(zip(i, j)):
        a = fc.neck_radius(pk.r[ii], pk.r[jj], pk.r[ii] + pk.r[jj] - np.linalg.norm(b[e]))[0]
        hi[e], hj[e] = half(a, pk.r[ii], e, "i"), half(a, pk.r[jj], e, "j")
    V = pk.L ** 3
    phi = float((4.0 / 3.0 * math.pi * pk.r ** 3).sum() / V)
    pc = min(phi, 1.0)
    hs = 2 * pc / (3 - pc)
    K = 1.0 / (1.0 / hi + 1.0 / hj)
    T = np.einsum("e,ek,el->kl", K, b, b) / V
    Lp = sps.coo_matrix((np.concatenate([K, K, -K, -K]), (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))),
                        shape=(n, n)).tocsc()
    keep = np.arange(1, n)
    kap = 0.0
    for k in range(3):
        g = K * b[:, k]
        rhs = np.zeros(n)
        np.add.at(rhs, i, g)
        np.add.at(rhs, j, -g)
        t = np.zeros(n)
        t[keep] = spl.spsolve(Lp[keep][:, keep], rhs[keep])
        kap += np.sum(K * (b[:, k] + t[j] - t[i]) ** 2) / V / 3.0
    return phi, np.trace(T) / 3 / hs, np.linalg.eigvalsh(T).max() / pc, kap / hs


def main():
    cases = {name: c[0] for name, c in cc.cases().items()}
    for name in ("n64-h002", "n64-h006", "n64s-h012"):
        cases[name] = fr.stored_packing(name)
    print("| cell | law | φ | Voigt mean / HS | Voigt λ_max / φ | κ_eff / HS |")
    print("|---|---|---|---|---|---|")
    for name, pk in sorted(cases.items()):
        phis = cc.crowding(pk)
        for lab, beta in (("fabric", cc.BETA), ("none", 0.0)):
            def half(a, r, e, side, beta=beta):
                pair = 1.0 / (fc.fe_fit_eval(a / r, cc.COEF) * math.pi * a)
                res = pair + (phis[(e, side)] - 1.0) * beta / (math.pi * r)
                return 1.0 / max(res, 0.5 * pair)
            phi, vm, vw, km = margins(pk, half)
            print(f"| {name} | {lab} | {phi:.4f} | {vm:.3f} | {vw:.3f} | {km:.3f} |")


if __name__ == "__main__":
    main()
