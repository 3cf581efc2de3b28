#!/usr/bin/env python3
"""Small seeded periodic random packings of sintered spheres for the 3-D FE
check of the heat network (validation/fe_random.py, docs/validation-conductance.md
"Random periodic packings").

Recipe (lengths in units of the mean radius rbar):
 1. radii r_i = rbar (1 + spread U(-1, 1)); a cubic periodic box at solid
    fraction phi0 (before the necks); random centres; the overlap energy
    sum max(0, r_i + r_j - d)^2 under the minimum image minimised (L-BFGS),
    which gives a dense random non-overlapping packing.
 2. bonds: every pair closer than r_i + r_j + bond_gap rbar, and each sphere's
    nearest neighbours until it has at least min_bonds.  Each bond gets a
    target overlap h*_ij = eta (1 + jitter U(-1, 1)) min(r_i, r_j).
 3. the energy  sum_bonds (d - (r_i + r_j - h*_ij))^2
              + sum_other max(0, r_i + r_j + gap_min rbar - d)^2
    minimised over the centres and the box scale (the box shrinks as the
    necks form).  A non-bonded pair that ends up closer than
    r_i + r_j + gap_min/2 becomes a bond and step 3 is repeated.
The result: every pair either overlaps (a neck, h/r between ~0.3 eta and
~2 eta) or is separated by a clear gap (no hair-thin gaps and no near-zero
necks, which the 3-D mesh could not resolve at a sane cost).  sinterdem sees
exactly the bonds as contacts (overlap > 0 under the minimum image).
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize


@dataclass
class Packing:
    x: np.ndarray          # (N, 3) centres in [0, L)
    r: np.ndarray          # (N,) radii
    L: float               # cubic box edge
    bonds: np.ndarray      # (M, 2) i < j
    shifts: np.ndarray     # (M, 3) integer image of j: b_ij = x_j + L s - x_i
    meta: dict

    def branch(self):
        i, j = self.bonds[:, 0], self.bonds[:, 1]
        return self.x[j] + self.L * self.shifts - self.x[i]

    def overlaps(self):
        b = self.branch()
        i, j = self.bonds[:, 0], self.bonds[:, 1]
        return self.r[i] + self.r[j] - np.linalg.norm(b, axis=1)


def _pairs(n):
    i, j = np.triu_indices(n, 1)
    return i, j


def _min_image(x, L, i, j):
    dv = x[j] - x[i]
    s = -np.round(dv / L)
    return dv + L * s, s


def _relax_overlaps(x, r, L, iters=3):
    n = len(r)
    i, j = _pairs(n)
    rs = r[i] + r[j]

    def f(flat):
        X = flat.reshape(n, 3)
        dv, _ = _min_image(X, L, i, j)
        d = np.linalg.norm(dv, axis=1)
        ov = np.maximum(rs - d, 0.0)
        E = float(np.sum(ov ** 2))
        g = np.zeros((n, 3))
        w = (-2.0 * ov / np.maximum(d, 1e-12))[:, None] * dv   # dE/d(x_j)
        np.add.at(g, j, w)
        np.add.at(g, i, -w)
        return E, g.ravel()
    for _ in range(iters):
        res = minimize(f, x.ravel(), jac=True, method="L-BFGS-B",
                       options=dict(maxiter=5000, gtol=1e-14, ftol=1e-16))
        x = res.x.reshape(n, 3)
    return np.mod(x, L), res.fun


def make_packing(n: int, eta: float, spread: float = 0.0, seed: int = 1,
                 phi0: float = 0.60, bond_gap: float = 0.05, min_bonds: int = 3,
                 jitter: float = 0.3, gap_min: float = 0.10) -> Packing:
    rng = np.random.default_rng(seed)
    r = 1.0 + spread * rng.uniform(-1.0, 1.0, n)
    r *= 1.0 / r.mean()
    L = (np.sum(4.0 / 3.0 * math.pi * r ** 3) / phi0) ** (1.0 / 3.0)
    x = rng.uniform(0.0, L, (n, 3))
    x, e0 = _relax_overlaps(x, r, L)
    i, j = _pairs(n)
    rs = r[i] + r[j]
    dv, s = _min_image(x, L, i, j)
    d = np.linalg.norm(dv, axis=1)
    bonded = d < rs + bond_gap
    # at least min_bonds per sphere: add nearest neighbours
    for k in range(n):
        mine = np.flatnonzero((i == k) | (j == k))
        have = int(bonded[mine].sum())
        if have < min_bonds:
            order = mine[np.argsort(d[mine] - rs[mine])]
            for p in order:
                if have >= min_bonds:
                    break
                if not bonded[p]:
                    bonded[p] = True
                    have += 1
    hstar = eta * (1.0 + jitter * rng.uniform(-1.0, 1.0, len(i))) * np.minimum(r[i], r[j])
    for _round in range(20):
        dstar = rs - hstar
        dmin = rs + gap_min
        nv = 3 * n

        def f(flat):
            X = flat[:nv].reshape(n, 3)
            lam = math.exp(flat[nv])
            Lc = L * lam
            dvv = X[j] - X[i]
            sh = -np.round(dvv / Lc)
            dvv = dvv + Lc * sh
            dd = np.linalg.norm(dvv, axis=1)
            res = np.where(bonded, dd - dstar, np.minimum(dd - dmin, 0.0))
            E = float(np.sum(res ** 2))
            coef = 2.0 * res / np.maximum(dd, 1e-12)
            w = coef[:, None] * dvv
            g = np.zeros((n, 3))
            np.add.at(g, j, w)
            np.add.at(g, i, -w)
            gl = float(np.sum(np.einsum("ij,ij->i", w, sh)) * Lc)   # d/d(log lam)
            return E, np.concatenate([g.ravel(), [gl]])
        z0 = np.concatenate([x.ravel(), [0.0]])
        res = minimize(f, z0, jac=True, method="L-BFGS-B",
                       options=dict(maxiter=20000, gtol=1e-13, ftol=1e-18))
        x = res.x[:nv].reshape(n, 3)
        L = L * math.exp(res.x[nv])
        x = np.mod(x, L)
        dv, s = _min_image(x, L, i, j)
        d = np.linalg.norm(dv, axis=1)
        bad = (~bonded) & (d < rs + 0.5 * gap_min)
        h = rs - d
        rmin = np.minimum(r[i], r[j])
        lost = bonded & (h < 0.3 * eta * rmin)
        if not bad.any() and not lost.any():
            break
        bonded |= bad
        # a bond the others keep open (over-constrained network) is dropped;
        # the sphere keeps at least one bond
        for p in np.flatnonzero(lost)[np.argsort(h[lost])]:
            zi = np.count_nonzero(bonded & ((i == i[p]) | (j == i[p])))
            zj = np.count_nonzero(bonded & ((i == j[p]) | (j == j[p])))
            if zi > 1 and zj > 1:
                bonded[p] = False
    else:
        raise RuntimeError("make_packing: bond set did not settle")
    h = rs - d
    if np.any(h[bonded] <= 0.2 * eta * np.minimum(r[i], r[j])[bonded]):
        raise RuntimeError(f"make_packing: a bond lost its neck (min h/r "
                           f"{np.min(h[bonded] / np.minimum(r[i], r[j])[bonded]):.4f})")
    hmax = np.minimum(r[i], r[j]) * 2.0 / 3.0
    if np.any(h[bonded] >= 0.9 * hmax[bonded]):
        raise RuntimeError("make_packing: a neck beyond the model's limit")
    if L < 4.0 * r.max() * 1.01:
        raise RuntimeError(f"make_packing: box {L:.3f} shorter than two largest diameters "
                           f"({4 * r.max():.3f}); use more spheres")
    bi = np.stack([i[bonded], j[bonded]], axis=1)
    sh = s[bonded].astype(int)
    pk = Packing(x=x, r=r, L=L, bonds=bi, shifts=sh,
                 meta=dict(n=n, eta=eta, spread=spread, seed=seed, phi0=phi0,
                           bond_gap=bond_gap, min_bonds=min_bonds, jitter=jitter,
                           gap_min=gap_min, residual=float(res.fun)))
    # the centres may be translated freely (periodic); move them so that no
    # sphere surface or neck plane is nearly tangent to a box face (the OCC
    # booleans and the mesher dislike near-tangencies)
    pk.x = np.mod(pk.x + _best_translation(pk, rng), L)
    # s is the image of x_j - x_i: b = x_j - x_i + L s (minimum image)
    _, s2 = _min_image(pk.x, L, bi[:, 0], bi[:, 1])
    pk.shifts = s2.astype(int)
    return pk


def _face_clearance(pk: Packing, t) -> float:
    x = np.mod(pk.x + t, pk.L)
    # distance of each sphere surface to each face plane crossing it
    c = []
    for k in range(3):
        for plane in (0.0, pk.L):
            c.append(np.abs(np.abs(x[:, k] - plane) - pk.r))
    # neck circles: their planes may be cut by a face; keep the neck centre
    # away from the faces
    b = pk.branch()
    i = pk.bonds[:, 0]
    mid = x[i] + 0.5 * b
    m = np.mod(mid, pk.L)
    c.append(np.minimum(m, pk.L - m).ravel() * 0.5)
    return float(min(np.min(v) for v in c))


def _best_translation(pk: Packing, rng, tries=400):
    best, bt = -1.0, np.zeros(3)
    for _ in range(tries):
        t = rng.uniform(0.0, pk.L, 3)
        c = _face_clearance(pk, t)
        if c > best:
            best, bt = c, t
    return bt


def stats(pk: Packing) -> dict:
    i, j = pk.bonds[:, 0], pk.bonds[:, 1]
    h = pk.overlaps()
    hr = h / np.minimum(pk.r[i], pk.r[j])
    z = np.bincount(np.concatenate([i, j]), minlength=len(pk.r))
    phi = float(np.sum(4 / 3 * math.pi * pk.r ** 3) / pk.L ** 3)
    return dict(n=len(pk.r), contacts=len(h), mean_h_over_r=float(hr.mean()),
                min_h_over_r=float(hr.min()), max_h_over_r=float(hr.max()),
                coordination_mean=float(z.mean()), coordination_min=int(z.min()),
                coordination_max=int(z.max()), solid_fraction_spheres=phi, box=pk.L,
                clearance=_face_clearance(pk, np.zeros(3)))


def load_packing(folder: str, meta: dict | None = None) -> Packing:
    """The stored packing of `folder` (folder/packing.csv as written by write_case: centres and
    radii in metres, the periodic box in the header's "periodic box ... m" phrase), in units of the
    mean radius stored there ("mean radius ... m").  Bonds: every pair that overlaps under the
    minimum image, the contacts `sinterdem conductivity` sees.  The stored files are the reference
    geometry of the validation (docs/validation-conductance.md "Reference packings"): a
    regeneration by make_packing follows another L-BFGS path wherever the BLAS kernels differ
    (OPENBLAS_CORETYPE), so tests read these files instead."""
    path = os.path.join(folder, "packing.csv")
    with open(path) as fh:
        head = fh.readline()
    m_r = re.search(r"mean radius ([0-9.eE+-]+) m", head)
    m_l = re.search(r"periodic box ([0-9.eE+-]+) m", head)
    if not (m_r and m_l):
        raise ValueError(f"{path}: header lacks 'mean radius ... m' or 'periodic box ... m': {head!r}")
    rbar, Lm = float(m_r.group(1)), float(m_l.group(1))
    data = np.loadtxt(path, delimiter=",", skiprows=2, ndmin=2)
    exact = os.path.join(folder, EXACT_FILE)
    if os.path.exists(exact):
        # the generator's own floats: the metre file divided by rbar differs from them in the
        # last bit, and one ulp gives gmsh another mesh (docs "Reference packings")
        with open(exact) as fh:
            head2 = fh.readline()
        m_b = re.search(r"box ([0-9.eE+-]+) r", head2)
        if not m_b:
            raise ValueError(f"{exact}: header lacks 'box ... r': {head2!r}")
        L = float(m_b.group(1))
        d2 = np.loadtxt(exact, delimiter=",", skiprows=2, ndmin=2)
        x, r = d2[:, :3], d2[:, 3]
        if (d2.shape != data.shape or not np.array_equal(d2 * rbar, data)
                or float(L * rbar) != Lm):
            raise ValueError(f"{exact} and {path} disagree: the metre file must be this one times "
                             f"{rbar} m bit for bit")
    else:
        x, r, L = data[:, :3] / rbar, data[:, 3] / rbar, Lm / rbar
    n = len(r)
    i, j = _pairs(n)
    dv, s = _min_image(x, L, i, j)
    bonded = np.linalg.norm(dv, axis=1) < r[i] + r[j]
    if meta is None:
        meta = {}
        for key in ("n", "eta", "spread", "seed"):
            m = re.search(rf"\b{key}=([0-9.eE+-]+)", head)
            if m:
                meta[key] = float(m.group(1)) if key in ("eta", "spread") else int(m.group(1))
    meta = dict(meta, stored=path)
    return Packing(x=x, r=r, L=L, bonds=np.stack([i[bonded], j[bonded]], axis=1),
                   shifts=s[bonded].astype(int), meta=meta)


EXACT_FILE = "packing_rbar.csv"


def write_exact(pk: Packing, folder: str) -> str:
    """folder/packing_rbar.csv: centres and radii in units of the mean radius, every float
    written with repr (exact round trip), the box in the header."""
    path = os.path.join(folder, EXACT_FILE)
    with open(path + ".tmp", "w") as fh:
        fh.write(f"# The packing of packing.csv in units of the mean radius, the generator's floats "
                 f"(repr, exact): the geometry the FE meshes; box {float(pk.L)!r} r per axis.\n")
        fh.write("x,y,z,r\n")
        for p, rr in zip(pk.x, pk.r):
            fh.write(f"{float(p[0])!r},{float(p[1])!r},{float(p[2])!r},{float(rr)!r}\n")
    os.replace(path + ".tmp", path)
    return path


def write_case(pk: Packing, folder: str, name: str, rbar_m: float = 25e-6,
               conductance: str = "fe_fit", multi_neck: str | None = None) -> str:
    """Writes folder/packing.csv (metres) and folder/<name>.toml for
    `sinterdem conductivity` (periodic); `multi_neck` ("none" | "fabric")
    sets thermal.multi_neck, None leaves sinterdem's default ("none" for now).
    Returns the toml path."""
    os.makedirs(folder, exist_ok=True)
    st = stats(pk)
    csv = os.path.join(folder, "packing.csv")
    with open(csv, "w") as fh:
        fh.write(f"# Periodic random sintered packing of validation/random_packing.py "
                 f"(n={pk.meta['n']}, eta={pk.meta['eta']}, spread={pk.meta['spread']}, "
                 f"seed={pk.meta['seed']}): {st['contacts']} necks, mean h/r "
                 f"{st['mean_h_over_r']:.4f}; mean radius {rbar_m} m; periodic box "
                 f"{float(pk.L * rbar_m)!r} m per axis from the origin. Columns in m.\n")
        fh.write("x,y,z,r\n")
        for p, rr in zip(pk.x * rbar_m, pk.r * rbar_m):
            fh.write(f"{float(p[0])!r},{float(p[1])!r},{float(p[2])!r},{float(rr)!r}\n")
    toml = os.path.join(folder, f"{name}.toml")
    Lm = float(pk.L * rbar_m)
    with open(toml, "w") as fh:
        fh.write(f"# Network kappa_eff of a validation packing (validation/random_packing.py); "
                 f"compared with the 3-D FE of validation/fe_random.py.\n")
        fh.write(f'title = "{name}"\n\n[time]\nend = 1.0\ndt = 0.1\n\n')
        fh.write('[[materials]]\nname = "copper"\npreset = "copper-ivannikov2022"\n\n')
        fh.write(f'[particles]\nsource = "file"\nfile = "packing.csv"\n'
                 f"periodic_box = [{Lm!r}, {Lm!r}, {Lm!r}]\n\n")
        fh.write(f'[thermal]\nconductance = "{conductance}"\n')
        if multi_neck is not None:
            fh.write(f'multi_neck = "{multi_neck}"\n')
        fh.write("\n")
        fh.write('[conductivity]\nboundary = "periodic"\n')
    return toml


if __name__ == "__main__":
    import argparse
    import json
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=16)
    ap.add_argument("--eta", type=float, default=0.06)
    ap.add_argument("--spread", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    pk = make_packing(a.n, a.eta, a.spread, a.seed)
    print(json.dumps(stats(pk), indent=1))


# --------------------------------------------------------------------------
# an independent Python twin of the periodic network homogenisation of
# `sinterdem conductivity` (docs/heat-model.md "Effective conductivity"), for
# checking the binary and trying pipe-conductance variants
# --------------------------------------------------------------------------
def network_kappa_py(pk: Packing, half):
    """kappa_eff/kappa_s of the pipe network: pipes K_ij = 1/(1/K_i + 1/K_j),
    K_i = half(a, r_i, bond index, 'i'|'j') (kappa_s = 1); T_i = G.x_i + theta_i,
    theta periodic; kappa_kl = (1/V) sum K_ij (e_k.b + dtheta_k)(e_l.b + dtheta_l)."""
    import scipy.sparse as sps
    import scipy.sparse.linalg as spl
    from fe_conductance import neck_radius
    n = len(pk.r)
    b = pk.branch()
    i, j = pk.bonds[:, 0], pk.bonds[:, 1]
    hi, hj = np.empty(len(i)), np.empty(len(i))
    for e, (ii, jj) in enumerate(zip(i, j)):
        h = pk.r[ii] + pk.r[jj] - np.linalg.norm(b[e])
        a = neck_radius(pk.r[ii], pk.r[jj], h)[0]
        hi[e], hj[e] = half(a, pk.r[ii], e, "i"), half(a, pk.r[jj], e, "j")
    # the bound of docs/heat-model.md (H8d), as src/heat/pipes.rs::bound_halves in a periodic
    # cell (kappa_s = 1): one scale for every half, s = min(1, phi_c V/lambda_max(T),
    # 3 V 2 phi_c/(3 - phi_c)/tr T), T = sum K_ij b b^T the network's uniform-gradient (Voigt) flux
    K = 1.0 / (1.0 / hi + 1.0 / hj)
    T = np.einsum("e,ek,el->kl", K, b, b)
    V = pk.L ** 3
    phi = float((4.0 / 3.0 * math.pi * pk.r ** 3).sum() / V)
    pc = min(phi, 1.0)
    s = min(1.0, pc * V / np.linalg.eigvalsh(T).max(), 3.0 * V * 2.0 * pc / (3.0 - pc) / np.trace(T))
    if s < 1.0:
        K = 1.0 / (1.0 / (hi * s) + 1.0 / (hj * s))
    Lp = sps.coo_matrix((np.concatenate([K, K, -K, -K]),
                         (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))),
                        shape=(n, n)).tocsc()
    keep = np.arange(1, n)
    th = []
    for k in range(3):
        g = K * b[:, k]                       # flux of the imposed gradient along each pipe
        rhs = np.zeros(n)
        np.add.at(rhs, i, g)
        np.add.at(rhs, j, -g)
        t = np.zeros(n)
        t[keep] = spl.spsolve(Lp[keep][:, keep], rhs[keep])
        th.append(t)
    dT = [b[:, k] + th[k][j] - th[k][i] for k in range(3)]
    return np.array([[np.sum(K * dT[k] * dT[l]) / V for l in range(3)] for k in range(3)])


def neck_geometry_stats(pk: Packing) -> dict:
    """Crowding of necks on the spheres: the angle between the axes of two
    necks of one sphere, and how many such pairs have overlapping caps
    (angle < asin(a1/r) + asin(a2/r))."""
    from fe_conductance import neck_radius
    b = pk.branch()
    axes = [[] for _ in pk.r]
    for e, (ii, jj) in enumerate(pk.bonds):
        d = np.linalg.norm(b[e])
        a = neck_radius(pk.r[ii], pk.r[jj], pk.r[ii] + pk.r[jj] - d)[0]
        axes[ii].append((b[e] / d, a))
        axes[jj].append((-b[e] / d, a))
    angles, crowded = [], 0
    for k, ax in enumerate(axes):
        for p in range(len(ax)):
            for q in range(p + 1, len(ax)):
                ang = math.acos(max(-1.0, min(1.0, float(ax[p][0] @ ax[q][0]))))
                angles.append(ang)
                lim = math.asin(min(1, ax[p][1] / pk.r[k])) + math.asin(min(1, ax[q][1] / pk.r[k]))
                crowded += ang < lim
    angles = np.degrees(np.array(angles))
    cov = 0.0
    for k, ax in enumerate(axes):     # fraction of the sphere surface under caps
        for (_, a) in ax:
            hc = pk.r[k] - math.sqrt(max(pk.r[k] ** 2 - a * a, 0))
            cov += 2 * math.pi * pk.r[k] * hc / (4 * math.pi * pk.r[k] ** 2)
    return dict(min_neck_angle_deg=float(angles.min()), mean_neck_angle_deg=float(angles.mean()),
                overlapping_cap_pairs=int(crowded), neck_pairs=len(angles),
                cap_coverage=cov / len(pk.r))
