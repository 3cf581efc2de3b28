#!/usr/bin/env python3
"""Axisymmetric finite-element conductance of the sintering geometry of
Rojek, Kasztelan, Tharmaraj (2022) -- validation of the heat-network
conductance law of sinterdem (docs: docs/heat-model.md (H6),
docs/validation-conductance.md).

Geometry (the paper's Fig. 12, section 5, equal spheres): the segment of a
sphere of radius r between the equatorial plane (section radius r) and the
plane where the section radius equals the neck radius a, plus half of the
volume-conserving cylindrical neck (radius a, height h_n/2).  Temperature 1 on
the equatorial plane, 0 on the neck mid-plane, all curved surfaces insulated.
K = Q/dT, normalised by K_cyl = kappa*pi*r.

The unequal pair (paper section 6): both spheres' segments (equator to cap
plane) plus the full neck, temperatures fixed on the two equatorial planes.

Discretisation: scikit-fem, P2 Lagrange triangles on an isoparametric
(quadratic) mesh, r-weighted weak form  int grad(u).grad(v) rho drho dz.
K = 2*pi*kappa * u^T A u (energy), A the r-weighted stiffness matrix.

Mesher (own, no gmsh): structured multi-block mapping.  Per sphere segment
 * S1: rectangle [0,a] x [equator, cap plane] (under the neck),
 * S2: the curved region between rho = a, the sphere and the equator, mapped
   by transfinite interpolation with one side collapsed onto the re-entrant
   corner C = (a, z_cap): a polar-like fan around C,
and the neck rectangle [0,a] x [z_cap, z_mid].  Node spacing is geometric
(first step d0 at C, ratio q, capped at hmax) towards C in every block.  Mesh
level L bisects every parameter interval L times (uniform refinement of the
graded base mesh); the P2 mid-edge nodes are the images of the parameter
mid-points, so curved boundaries are represented exactly at the nodes.

Usage:
  python validation/fe_conductance.py --full     # regenerate table, csv, png, vtu
  python validation/fe_conductance.py --pair     # unequal pair only
  python validation/fe_conductance.py --row 0.3  # one row, all levels
  python validation/fe_conductance.py --refit    # fe_fit + plot from the stored table
"""
from __future__ import annotations

import argparse
import datetime
import math
import os
import sys
import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import scipy
import scipy.sparse.linalg
from scipy.spatial import cKDTree

import skfem
from skfem import Basis, BilinearForm, ElementTriP2, MeshTri1, MeshTri2, asm, condense
from skfem.helpers import dot, grad

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "data")
CSV_PATH = os.path.join(DATA, "conductance_half.csv")

# a/r values of the table (0.05 .. 0.8; denser at the small-neck end)
A_OVER_R_TABLE = [0.05, 0.075, 0.1, 0.125, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4,
                  0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8]
LEVELS_FULL = (0, 1, 2, 3)
SLOPE_PAPER = 1.064          # eq. 40
HOLM = 4.0 / math.pi         # small-neck limit of K_i/(kappa*pi*a)

# unequal pair of the paper (section 6), SI
PAIR_RI, PAIR_RJ, PAIR_H, PAIR_KAPPA = 1e-3, 3e-3, 6e-5, 394.0
PAIR_A_SPEC = 0.4191863e-3
PAIR_K_PAPER_FE = 0.278033
PAIR_K_LINEAR = 0.2760354


# --------------------------------------------------------------------------
# neck geometry (docs/heat-model.md (H9)–(H15), "Volume-conserving cylindrical neck")
# --------------------------------------------------------------------------
def cap_height(r: float, a: float) -> float:
    """Height of the spherical cap of a sphere of radius r cut at section radius a."""
    return r - math.sqrt(max(r * r - a * a, 0.0))


def neck_height_equal(a: float, r: float = 1.0) -> float:
    """Full height h_n of the volume-conserving neck of two equal spheres:
    pi a^2 h_n = 2 (pi h_c^2 r - pi h_c^3 / 3)."""
    hc = cap_height(r, a)
    return 2.0 * (hc * hc * r - hc ** 3 / 3.0) / (a * a)


def neck_radius(ri: float, rj: float, h: float, tol: float = 1e-12):
    """Volume-conserving neck radius a of eq. 27 by Newton from Coble's
    estimate (dZ/da = 6 a h_n).  Returns (a, h_ci, h_cj, h_n, iterations)."""
    ri, rj = min(ri, rj), max(ri, rj)
    rstar = 2.0 * ri * rj / (ri + rj)
    a = min(math.sqrt(2.0 * rstar * h), ri)
    for it in range(1, 51):
        hci, hcj = cap_height(ri, a), cap_height(rj, a)
        hn = hci + hcj - h
        z = 3 * a * a * hn - hcj * hcj * (3 * rj - hcj) - hci * hci * (3 * ri - hci)
        da = z / (6.0 * a * hn)
        a -= da
        if abs(da) <= tol * ri:
            hci, hcj = cap_height(ri, a), cap_height(rj, a)
            return a, hci, hcj, hci + hcj - h, it
    raise RuntimeError("neck_radius: no convergence")


# --------------------------------------------------------------------------
# 1-D graded node distributions
# --------------------------------------------------------------------------
def graded(length: float, d0: float, q: float, hmax: float) -> np.ndarray:
    """Nodes 0 = x_0 < ... < x_n = length: first step ~d0 at x = 0, each step
    q times the previous, capped at hmax; all steps rescaled to hit length."""
    steps = []
    s, d = 0.0, min(d0, length)
    while s < length * (1 - 1e-12):
        steps.append(d)
        s += d
        d = min(d * q, hmax)
    if len(steps) > 1 and (s - length) > 0.5 * steps[-1]:
        s -= steps.pop()
    x = np.concatenate([[0.0], np.cumsum(steps)]) * (length / s)
    x[-1] = length
    return x


def refine_1d(x: np.ndarray, times: int) -> np.ndarray:
    """Insert the mid-points of every interval, `times` times."""
    for _ in range(times):
        mid = 0.5 * (x[:-1] + x[1:])
        y = np.empty(2 * len(x) - 1)
        y[0::2], y[1::2] = x, mid
        x = y
    return x


# --------------------------------------------------------------------------
# structured blocks -> quadratic triangle mesh
# --------------------------------------------------------------------------
@dataclass
class Block:
    s: np.ndarray                 # vertex parameters along the first direction
    t: np.ndarray                 # vertex parameters along the second direction
    mapping: Callable             # (S, T) -> (X, Z) arrays
    collapsed_s0: bool = False    # all points with s = s[0] coincide (fan)


def build_mesh(blocks: Sequence[Block], scale: float) -> MeshTri2:
    """Conforming isoparametric P2 triangle mesh from the blocks; shared
    block edges must use the same parameter nodes (merged by position)."""
    pts, tris, mids = [], [], []
    off = 0
    for b in blocks:
        sf, tf = refine_1d(b.s, 1), refine_1d(b.t, 1)   # with P2 mid-points
        S, T = np.meshgrid(sf, tf, indexing="ij")
        X, Z = b.mapping(S, T)
        P = np.stack([X, Z], axis=-1)                   # (2n+1, 2m+1, 2)
        n, m = len(b.s) - 1, len(b.t) - 1
        vid = off + np.arange((n + 1) * (m + 1)).reshape(n + 1, m + 1)
        pts.append(P[0::2, 0::2].reshape(-1, 2))
        off += (n + 1) * (m + 1)
        I, J = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
        I, J = I.ravel(), J.ravel()
        v00, v10 = vid[I, J], vid[I + 1, J]
        v11, v01 = vid[I + 1, J + 1], vid[I, J + 1]
        # triangle (v00, v10, v11): edges v00-v10, v10-v11, v11-v00
        tris.append(np.stack([v00, v10, v11]))
        mids.append((v00, v10, P[2 * I + 1, 2 * J]))
        mids.append((v10, v11, P[2 * I + 2, 2 * J + 1]))
        # diagonal mid-point; in the collapsed first row the diagonal is the
        # ray C -> (s1, t_{j+1}), whose mid-point is at (s_1/2, t_{j+1})
        diag = P[2 * I + 1, 2 * J + 1]
        if b.collapsed_s0:
            diag = np.where((I == 0)[:, None], P[2 * I + 1, 2 * J + 2], diag)
        mids.append((v00, v11, diag))
        keep = ~((I == 0) & b.collapsed_s0)            # (v00, v11, v01)
        tris.append(np.stack([v00, v11, v01])[:, keep])
        mids.append((v11[keep], v01[keep], P[2 * I + 1, 2 * J + 2][keep]))
        mids.append((v01[keep], v00[keep], P[2 * I, 2 * J + 1][keep]))
    p = np.concatenate(pts)
    t = np.concatenate(tris, axis=1)
    # merge coincident vertices (shared block edges, collapsed fan side)
    tree = cKDTree(p)
    pairs = tree.query_pairs(1e-11 * scale, output_type="ndarray")
    parent = np.arange(len(p))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i, j in pairs:
        ri, rj = find(i), find(j)
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    root = np.array([find(i) for i in range(len(p))])
    uniq, new = np.unique(root, return_inverse=True)
    p, t = p[uniq], new[t]
    # orient counter-clockwise
    d = ((p[t[1], 0] - p[t[0], 0]) * (p[t[2], 1] - p[t[0], 1])
         - (p[t[2], 0] - p[t[0], 0]) * (p[t[1], 1] - p[t[0], 1]))
    if np.any(np.abs(d) < 1e-30 * scale ** 2):
        raise RuntimeError("degenerate triangle in mesh")
    t[[1, 2]] = np.where(d < 0, t[[2, 1]], t[[1, 2]])
    m1 = MeshTri1(p.T.copy(), t, sort_t=False)
    M = MeshTri2.from_mesh(m1)
    # mid-edge node positions from the block mappings
    key = {}
    for va, vb, xy in mids:
        va, vb = new[va], new[vb]
        lo, hi = np.minimum(va, vb), np.maximum(va, vb)
        for k, (l, h) in enumerate(zip(lo.tolist(), hi.tolist())):
            key[(l, h)] = xy[k]
    fac = M.facets
    fd = M.dofs.facet_dofs[0]
    doflocs = M.doflocs.copy()
    for f in range(fac.shape[1]):
        doflocs[:, fd[f]] = key[(int(fac[0, f]), int(fac[1, f]))]
    return MeshTri2(doflocs, M.t, sort_t=False)


# --------------------------------------------------------------------------
# geometry: sphere segments and necks as blocks
# --------------------------------------------------------------------------
@dataclass
class MeshParams:
    c0: float = 0.05     # first step at the corner = c0 * min(a, neck half-height)
    q: float = 1.35      # geometric growth ratio
    hmax: float = 0.08   # largest step, in units of the sphere radius
    hmax_rho: float = 0.15  # largest radial step under the neck, units of a
    n_fan: int = 8       # angular intervals of the fan block


def segment_blocks(R: float, a: float, sig: np.ndarray, g: np.ndarray,
                   n_fan: int, zmap: Callable) -> list[Block]:
    """Blocks of the sphere segment of radius R between its equator
    (local zeta = 0) and its cap plane (zeta = z0).  `sig` in [0,1]: nodes
    from the corner C down to the equator (as fractions of z0); `g` in
    [0,a]: radial distance from rho = a (nodes of the neck radius).
    zmap(zeta) -> global z."""
    z0 = math.sqrt(R * R - a * a)
    psiC = math.atan2(z0, a)

    def s1(S, T):            # S: g (rho = a - g), T: sigma
        return a - S, zmap(z0 * (1.0 - T))

    def fan(S, T):           # S: sigma from C, T: angular parameter 0..1
        Lx, Lz = a + 0 * S, z0 * (1.0 - S)
        psi = psiC * (1.0 - S)
        Ax, Az = R * np.cos(psi), R * np.sin(psi)
        Bx = a + T * (R - a)
        X = S * Bx + (1 - T) * Lx + T * Ax - S * (1 - T) * a - S * T * R
        Zl = (1 - T) * Lz + T * Az
        return X, zmap(Zl)
    t_fan = np.linspace(0.0, 1.0, n_fan + 1)
    return [Block(g, sig, s1), Block(sig, t_fan, fan, collapsed_s0=True)]


def half_blocks(a: float, level: int, mp: MeshParams):
    """Rojek's half geometry (r = 1): blocks, z of the neck mid-plane."""
    R = 1.0
    z0 = math.sqrt(R * R - a * a)
    H = 0.5 * neck_height_equal(a, R)
    d0 = mp.c0 * min(a, H)
    g = refine_1d(graded(a, d0, mp.q, mp.hmax_rho * a), level)
    sig = refine_1d(graded(z0, d0, mp.q, mp.hmax * R) / z0, level)
    zn = refine_1d(graded(H, d0, mp.q, mp.hmax * R), level)
    blocks = segment_blocks(R, a, sig, g, mp.n_fan * 2 ** level, lambda zeta: zeta)
    blocks.append(Block(g, zn, lambda S, T: (a - S, z0 + T)))
    return blocks, z0 + H


def pair_blocks(ri: float, rj: float, a: float, hn: float, level: int,
                mp: MeshParams):
    """Unequal pair: segment i (equator at z = 0), full neck, segment j
    (equator at the top).  Returns blocks and z of the top equator."""
    z0i = math.sqrt(ri * ri - a * a)
    z0j = math.sqrt(rj * rj - a * a)
    ztop = z0i + hn + z0j
    d0 = mp.c0 * min(a, 0.5 * hn)
    g = refine_1d(graded(a, d0, mp.q, mp.hmax_rho * a), level)
    sig_i = refine_1d(graded(z0i, d0, mp.q, mp.hmax * ri) / z0i, level)
    sig_j = refine_1d(graded(z0j, d0, mp.q, mp.hmax * rj) / z0j, level)
    half = graded(0.5 * hn, d0, mp.q, mp.hmax * ri)
    zn = refine_1d(np.concatenate([half, hn - half[-2::-1]]), level)
    nf = mp.n_fan * 2 ** level
    blocks = segment_blocks(ri, a, sig_i, g, nf, lambda zeta: zeta)
    blocks += segment_blocks(rj, a, sig_j, g, nf, lambda zeta: ztop - zeta)
    blocks.append(Block(g, zn, lambda S, T: (a - S, z0i + T)))
    return blocks, ztop


# --------------------------------------------------------------------------
# solver
# --------------------------------------------------------------------------
@BilinearForm
def laplace_axi(u, v, w):
    return dot(grad(u), grad(v)) * w.x[0]


def solve_conduction(M: MeshTri2, z_bot: float, z_top: float, scale: float):
    """u = 1 on z = z_bot, 0 on z = z_top, insulated elsewhere.
    Returns (E, u, basis) with E = int |grad u|^2 rho drho dz, so that
    K = 2 pi kappa E for dT = 1."""
    basis = Basis(M, ElementTriP2(), intorder=4)
    A = asm(laplace_axi, basis)
    tol = 1e-9 * scale
    fb = M.facets_satisfying(lambda x: np.abs(x[1] - z_bot) < tol)
    ft = M.facets_satisfying(lambda x: np.abs(x[1] - z_top) < tol)
    Db = basis.get_dofs(fb).all()
    Dt = basis.get_dofs(ft).all()
    u = np.zeros(basis.N)
    u[Db] = 1.0
    D = np.concatenate([Db, Dt])
    Ac, bc, xc, I = condense(A, x=u, D=D)
    # SPD system: symmetric-mode SuperLU with minimum-degree ordering on
    # A^T + A (4x faster than the default COLAMD here)
    lu = scipy.sparse.linalg.splu(Ac.tocsc(), permc_spec="MMD_AT_PLUS_A",
                                  options=dict(SymmetricMode=True))
    u[I] = lu.solve(bc)
    E = float(u @ (A @ u))
    return E, u, basis


def k_half(a_over_r: float, level: int, mp: MeshParams | None = None,
           return_fields: bool = False):
    """K_i / K_cyl (K_cyl = kappa pi r) of the half geometry at one level."""
    mp = mp or MeshParams()
    blocks, ztop = half_blocks(a_over_r, level, mp)
    M = build_mesh(blocks, 1.0)
    E, u, basis = solve_conduction(M, 0.0, ztop, 1.0)
    k = 2.0 * E                      # 2 pi kappa E / (kappa pi r), r = 1
    if return_fields:
        return k, M, u, basis
    return k


def k_pair(level: int, mp: MeshParams | None = None):
    """K_pair [W/K] of the paper's unequal copper pair at one level."""
    mp = mp or MeshParams()
    ri, rj = PAIR_RI / PAIR_RI, PAIR_RJ / PAIR_RI     # lengths in units of r_i
    a, hci, hcj, hn, _ = neck_radius(ri, rj, PAIR_H / PAIR_RI)
    blocks, ztop = pair_blocks(ri, rj, a, hn, level, mp)
    M = build_mesh(blocks, rj)
    E, _, basis = solve_conduction(M, 0.0, ztop, rj)
    return 2.0 * math.pi * PAIR_KAPPA * PAIR_RI * E, basis.N


# --------------------------------------------------------------------------
# convergence / Richardson
# --------------------------------------------------------------------------
def richardson(values: Sequence[float]):
    """Richardson extrapolation of the last three values of a sequence on
    meshes refined by 2 each time.  Returns (extrapolated, observed order p)."""
    k1, k2, k3 = values[-3:]
    d1, d2 = k1 - k2, k2 - k3
    if d1 == 0 or d2 == 0 or d1 / d2 <= 1.0:
        return k3, float("nan")
    p = math.log2(d1 / d2)
    return k3 - d2 / (2 ** p - 1), p


def corner_order(a_over_r: float) -> float:
    """Asymptotic order of the energy (conductance) error, in the mesh size,
    for uniform refinement: 2*pi/omega, omega = 3*pi/2 - asin(a/r) the
    interior angle of the re-entrant corner (Neumann on both sides)."""
    omega = 1.5 * math.pi - math.asin(a_over_r)
    return 2 * math.pi / omega


def converge_row(x: float, levels=LEVELS_FULL, mp=None, verbose=True):
    ks = []
    for L in levels:
        t0 = time.time()
        ks.append(k_half(x, L, mp))
        if verbose:
            print(f"  a/r={x:.3f} level {L}: K/Kcyl={ks[-1]:.8f} ({time.time()-t0:.1f}s)",
                  flush=True)
    kx, p = richardson(ks)
    return ks, kx, p


# --------------------------------------------------------------------------
# fe_fit:  f(x) = K_i/(kappa pi a) = 1 / D(x),  x = a/r,
#   D(x) = pi/4 + p1 x + p2 x ln x + p3 x^2 + p4 x (1 - sqrt(1 - x^2)),
#   p4 = 2/3 - pi/4 - p1 - p3,
# so that f(0+) = 4/pi (Holm constriction limit) and f(1) = 3/2 (at a = r
# the half geometry is a cylinder of radius r and length 2r/3).  The x ln x
# term carries the slow approach to the Holm limit (thin neck), the
# sqrt(1 - x^2) term the shrinking sphere segment.
# --------------------------------------------------------------------------
def fe_fit_D(x, coef):
    p1, p2, p3 = coef
    p4 = 2.0 / 3.0 - math.pi / 4 - p1 - p3
    x = np.asarray(x, dtype=float)
    return (math.pi / 4 + p1 * x + p2 * x * np.log(x) + p3 * x * x
            + p4 * x * (1.0 - np.sqrt(1.0 - x * x)))


def fe_fit_eval(x, coef):
    """Python twin of src/heat/fe_fit.rs::fe_fit_factor, for 0 < x <= 1."""
    return 1.0 / fe_fit_D(x, coef)


def fit_fe_law(x: np.ndarray, f: np.ndarray):
    """Minimax (relative) fit of p1..p3 to the converged table."""
    from scipy.optimize import minimize
    obj = lambda c: float(np.max(np.abs(fe_fit_eval(x, c) / f - 1)))  # noqa: E731
    c = np.array([0.25, -0.3, -0.2])
    opts = dict(maxiter=60000, xatol=1e-13, fatol=1e-15)
    for _ in range(6):
        c = minimize(obj, c, method="Nelder-Mead", options=opts).x
    return c


# --------------------------------------------------------------------------
# output
# --------------------------------------------------------------------------
def versions() -> str:
    import matplotlib
    import meshio
    return (f"python {sys.version.split()[0]}, numpy {np.__version__}, scipy {scipy.__version__}, "
            f"scikit-fem {skfem.__version__}, meshio {meshio.__version__}, "
            f"matplotlib {matplotlib.__version__}")


def write_csv(rows, mp: MeshParams, levels, path=CSV_PATH):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as fh:
        fh.write("# Conductance of half of Rojek et al. (2022) sintering geometry (equal spheres):\n")
        fh.write("#   spherical segment (equator .. section radius a) + half volume-conserving neck,\n")
        fh.write("#   T fixed on the equatorial plane and the neck mid-plane, curved surfaces insulated.\n")
        fh.write(f"# generated by validation/fe_conductance.py --full on {datetime.date.today().isoformat()}\n")
        fh.write(f"# {versions()}\n")
        fh.write("# FE: axisymmetric, P2 triangles on an isoparametric structured multi-block mesh graded\n")
        fh.write(f"#   towards the re-entrant corner (c0={mp.c0}, q={mp.q}, hmax={mp.hmax} r, "
                 f"hmax_rho={mp.hmax_rho} a, n_fan={mp.n_fan});\n")
        fh.write(f"#   mesh levels {list(levels)} (each level halves every parameter interval).\n")
        fh.write("# columns (all dimensionless; K_cyl = kappa*pi*r, r the sphere radius):\n")
        fh.write("#   a_over_r               neck radius / sphere radius\n")
        fh.write("#   hn_half_over_r         half neck height / r (volume-conserving neck)\n")
        fh.write("#   K_over_Kcyl_converged  Richardson extrapolation of the last three levels\n")
        fh.write("#   K_over_Kcyl_finest     value on the finest level\n")
        fh.write("#   observed_order         log2 of the ratio of successive differences (last three levels)\n")
        fh.write("#   ratio_to_linear_1064   K_over_Kcyl_converged / (1.064 a/r)  (paper eq. 40)\n")
        fh.write("#   f_converged            K_i/(kappa*pi*a) = K_over_Kcyl_converged / (a/r)\n")
        fh.write("#   ndofs_finest           P2 degrees of freedom on the finest level\n")
        fh.write("#   rel_err_est            |converged - extrapolation with the corner-limited order\n")
        fh.write("#                          2 pi/omega| / converged, plus |finest - converged| / converged\n")
        fh.write("#   K_level<L>             K/K_cyl on mesh level L\n")
        fh.write("a_over_r,hn_half_over_r,K_over_Kcyl_converged,K_over_Kcyl_finest,observed_order,"
                 "ratio_to_linear_1064,f_converged,ndofs_finest,rel_err_est,"
                 + ",".join(f"K_level{L}" for L in levels) + "\n")
        for r in rows:
            ks = r["ks"]
            kth = ks[-1] - (ks[-2] - ks[-1]) / (2 ** corner_order(r["x"]) - 1)
            err = (abs(r["kx"] - kth) + abs(ks[-1] - r["kx"])) / r["kx"]
            fh.write(f"{r['x']:.4f},{r['H']:.8e},{r['kx']:.9f},{r['kf']:.9f},{r['p']:.3f},"
                     f"{r['kx'] / (SLOPE_PAPER * r['x']):.6f},{r['kx'] / r['x']:.8f},{r['n']},"
                     f"{err:.2e}," + ",".join(f"{k:.9f}" for k in ks) + "\n")


def read_table(path=CSV_PATH):
    import csv
    with open(path) as fh:
        lines = [ln for ln in fh if not ln.startswith("#")]
    rd = csv.DictReader(lines)
    return [{k: float(v) for k, v in row.items()} for row in rd]


def write_vtu(x=0.3, level=0, path=None):
    import meshio
    path = path or os.path.join(DATA, f"half_geometry_a{x}.vtu")
    k, M, u, basis = k_half(x, level, return_fields=True)
    nv = M.nvertices
    pts = np.zeros((nv, 3))
    pts[:, :2] = M.doflocs[:, :nv].T
    # P1 sub-triangles of each P2 triangle (vertices + mid-edge nodes)
    npts = M.doflocs.shape[1]
    allp = np.zeros((npts, 3))
    allp[:, :2] = M.doflocs.T
    t = M.t
    e = M.t2f + nv
    tri6 = np.stack([t[0], t[1], t[2], e[0], e[1], e[2]], axis=1)
    mesh = meshio.Mesh(allp, [("triangle6", tri6)],
                       point_data={"T": u[:npts]})
    meshio.write(path, mesh, binary=True, compression="zlib")
    return path, k


def plot(rows, coef, pair=None, path=os.path.join(DATA, "conductance_half.png")):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    x = np.array([r["x"] for r in rows])
    k = np.array([r["kx"] for r in rows])
    xs = np.linspace(1e-4, 0.85, 200)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    ax1.plot(x, k, "o", label="FE (converged)")
    ax1.plot(xs, SLOPE_PAPER * xs, "-", label="Rojek eq. 40: 1.064 a/r")
    ax1.plot(xs, xs * fe_fit_eval(xs, coef), "--", label="fe_fit")
    ax1.set_xlabel("a / r")
    ax1.set_ylabel("K_i / (kappa pi r)")
    ax1.legend()
    ax1.grid(alpha=0.3)
    ax2.plot(x, k / x, "o", label="FE (converged)")
    ax2.axhline(SLOPE_PAPER, color="C1", label="1.064")
    ax2.axhline(HOLM, color="gray", ls=":", label="4/pi (Holm)")
    xs2 = np.linspace(0.01, 0.85, 200)
    ax2.plot(xs2, fe_fit_eval(xs2, coef), "--", color="C2", label="fe_fit")
    ax2.set_xlabel("a / r")
    ax2.set_ylabel("f = K_i / (kappa pi a)")
    ax2.legend()
    ax2.grid(alpha=0.3)
    fig.suptitle("Half sintering geometry (Rojek et al. 2022): FE vs linear law")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def run_pair(levels=LEVELS_FULL, mp=None, verbose=True):
    ks = []
    for L in levels:
        t0 = time.time()
        k, n = k_pair(L, mp)
        ks.append(k)
        if verbose:
            print(f"  pair level {L}: K_pair={k:.7f} W/K ndofs={n} ({time.time()-t0:.1f}s)",
                  flush=True)
    kx, p = richardson(ks)
    return ks, kx, p


PAIR_CSV = os.path.join(DATA, "conductance_pair.csv")


def write_pair_csv(ks, kx, p, levels, mp: MeshParams, path=PAIR_CSV):
    a, hci, hcj, hn, _ = neck_radius(PAIR_RI, PAIR_RJ, PAIR_H)
    with open(path, "w") as fh:
        fh.write("# Unequal copper pair of Rojek et al. (2022) section 6: r_i = 1 mm, r_j = 3 mm,\n")
        fh.write("#   h = 0.06 mm, kappa = 394 W/(m K); both sphere segments (equator .. cap plane) + full\n")
        fh.write("#   volume-conserving neck; T fixed on the two equatorial planes, rest insulated.\n")
        fh.write(f"# generated by validation/fe_conductance.py --full on {datetime.date.today().isoformat()}\n")
        fh.write(f"# {versions()}\n")
        fh.write(f"# mesh params c0={mp.c0}, q={mp.q}, hmax={mp.hmax} r, hmax_rho={mp.hmax_rho} a, "
                 f"n_fan={mp.n_fan}; levels {list(levels)}\n")
        fh.write(f"# a = {a:.10e} m, h_n = {hn:.10e} m (Newton on eq. 27)\n")
        fh.write("# quantity: K_pair [W/K]; level rows are mesh levels, 'converged' is Richardson\n")
        fh.write(f"# observed order {p:.3f}; paper FE 0.278033 W/K, linear law 0.2760354 W/K\n")
        fh.write("quantity,value\n")
        for L, k in zip(levels, ks):
            fh.write(f"K_pair_level{L},{k:.9f}\n")
        fh.write(f"K_pair_converged,{kx:.9f}\n")


def read_pair_csv(path=PAIR_CSV):
    out = {}
    with open(path) as fh:
        for ln in fh:
            if ln.startswith("#") or ln.startswith("quantity"):
                continue
            k, v = ln.strip().split(",")
            out[k] = float(v)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="regenerate table, fit, plot, vtu")
    ap.add_argument("--pair", action="store_true", help="unequal pair only")
    ap.add_argument("--row", type=float, help="one a/r value, all levels")
    ap.add_argument("--levels", type=int, nargs="+", default=list(LEVELS_FULL))
    ap.add_argument("--refit", action="store_true", help="fit + plot from the stored table")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes for --full")
    args = ap.parse_args(argv)
    mp = MeshParams()
    levels = tuple(args.levels)
    if args.row is not None:
        ks, kx, p = converge_row(args.row, levels, mp)
        print(f"a/r={args.row}: converged {kx:.8f}, order {p:.3f} "
              f"(corner theory {corner_order(args.row):.3f}), f={kx/args.row:.6f}")
        return
    if args.pair or args.full:
        a, *_ = neck_radius(PAIR_RI, PAIR_RJ, PAIR_H)
        print(f"pair: a = {a:.10e} m")
        ks, kx, p = run_pair(levels, mp)
        print(f"pair: K_pair converged {kx:.7f} W/K (order {p:.3f}); paper FE {PAIR_K_PAPER_FE}, "
              f"diff {100*(kx/PAIR_K_PAPER_FE-1):+.3f} %; linear {PAIR_K_LINEAR}, "
              f"diff {100*(kx/PAIR_K_LINEAR-1):+.3f} %")
        if levels == LEVELS_FULL:
            write_pair_csv(ks, kx, p, levels, mp)
    if args.refit:
        rows = [dict(x=r["a_over_r"], kx=r["K_over_Kcyl_converged"]) for r in read_table()]
        refit_and_plot(rows)
        return
    if not args.full:
        return
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(max_workers=args.jobs) as ex:
        res = list(ex.map(converge_row, A_OVER_R_TABLE, [levels] * len(A_OVER_R_TABLE),
                          [mp] * len(A_OVER_R_TABLE)))
    rows = []
    for x, (ks, kx, p) in zip(A_OVER_R_TABLE, res):
        rows.append(dict(x=x, H=0.5 * neck_height_equal(x), kx=kx, kf=ks[-1], p=p, ks=ks))
    for r in rows:   # ndofs of the finest level
        blocks, _ = half_blocks(r["x"], levels[-1], mp)
        M = build_mesh(blocks, 1.0)
        r["n"] = M.doflocs.shape[1]
    write_csv(rows, mp, levels)
    refit_and_plot(rows)
    print("wrote", write_vtu(0.3, 0)[0])


def refit_and_plot(rows):
    x = np.array([r["x"] for r in rows])
    f = np.array([r["kx"] for r in rows]) / x
    coef = fit_fe_law(x, f)
    dev = fe_fit_eval(x, coef) / f - 1
    print("fe_fit coefficients p1..p3:", ", ".join(f"{c:.10f}" for c in coef),
          f"p4 = {2/3 - math.pi/4 - coef[0] - coef[2]:.10f}",
          f"max |dev| = {100*np.abs(dev).max():.4f} %")
    sel = x <= 0.7 + 1e-9
    k = f * x
    c = float((x[sel] @ k[sel]) / (x[sel] @ x[sel]))
    print(f"least-squares slope over a/r <= 0.7: c = {c:.5f} (paper 1.064, diff {100*(c/1.064-1):+.2f} %)")
    print("wrote", plot(rows, coef))


if __name__ == "__main__":
    main()
