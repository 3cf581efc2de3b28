#!/usr/bin/env python3
"""3-D periodic finite-element effective conductivity of small random
sintered packings, against sinterdem's pipe network (issue 23 item 4;
docs/validation-conductance.md "Random periodic packings").

Geometry (lengths in units of the mean radius): the union of all spheres and,
at every bond (overlapping pair), the volume-conserving cylindrical neck of
src/neck.rs / docs/heat-model.md (H9)-(H11) -- the geometry the pair
conductance fit was derived for (validation/fe_conductance.py): radius a,
between the two cut planes where each sphere's section radius equals a.  The
cylinder is extended a little into both spheres (inside them, so the union is
unchanged) to keep the OCC booleans away from coincident edges.  Periodic
images of every sphere and neck that reach into the box are added, the union
is cut to the box [0, L]^3 (gmsh OCC), and opposite faces get a periodic
mesh (gmsh setPeriodic).

FE: scikit-fem, isoparametric P2 tetrahedra (gmsh order-2 mesh, curved
boundaries), T = G.x + theta with theta periodic by DOF identification
(DOFs whose positions agree modulo L share one unknown), solid conductivity 1
(kappa_eff/kappa_s).  For the unit gradients e_k:
    kappa_kl = (1/V) (T_k)^T A T_l,   V = L^3,
the energy form, which for the diagonal is a Galerkin upper bound.  One
factorisation / AMG hierarchy serves the three gradients.

Mesh size: a callback, per neck  s = m min(s_max, a/n_a + g dist(neck rim));
m is the mesh factor, level L has m = 2^(1 - L/3) (the element size halves
every three levels: about twice the elements per level).
The converged value is the extrapolation f = f_inf + C h^p through the last
three levels with h = N_dof^(-1/3) (unequal ratios: p solved for).

Usage:
  python validation/fe_random.py --n 16 --eta 0.12 --levels 0 1 2
  python validation/fe_random.py --table --levels 0 1 2 3 4   # all cases -> validation/data/random_conductivity.csv
"""
from __future__ import annotations

import argparse
import datetime
import itertools
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from fractions import Fraction

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg
from scipy.spatial import cKDTree

import fe_conductance as fc
import random_packing as rp

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.path.join(HERE, "data")


# --------------------------------------------------------------------------
# necks of a packing
# --------------------------------------------------------------------------
def _fma(a, b, c):
    """a*b + c rounded once (exact rational arithmetic; math.fma needs Python 3.13)."""
    return float(Fraction(a) * Fraction(b) + Fraction(c))


def bond_length(v):
    """|v| of a 3-vector in one fixed arithmetic, sqrt(fma(z, z, fma(y, y, x*x))), on every machine.

    The stored FE tables were computed with np.linalg.norm, i.e. OpenBLAS's ddot, whose result
    depends on the kernel OpenBLAS picks for the processor: the default kernel on our machines
    evaluates exactly this fused chain (equal on all 1114 stored bonds), the Haswell kernel
    (OPENBLAS_CORETYPE=Haswell) rounds each product (different in 143 of 1114).  One ulp in a
    neck axis moves gmsh's periodic surface matching and gives another mesh (-0.2 to -0.4 % at
    level 0), so the geometry is computed without BLAS (docs/validation-conductance.md
    "Reference packings")."""
    x, y, z = (float(c) for c in v)
    return math.sqrt(_fma(z, z, _fma(y, y, x * x)))


def necks(pk: rp.Packing):
    """Per bond: centre c_i (of sphere i, unwrapped), unit axis n, radius a,
    distance t_i of the cut plane of i from c_i along n, neck height h_n."""
    out = []
    b = pk.branch()
    for (i, j), bv in zip(pk.bonds, b):
        d = bond_length(bv)
        ri, rj = pk.r[i], pk.r[j]
        h = ri + rj - d
        a, hc_s, hc_l, hn, _ = fc.neck_radius(ri, rj, h)
        hci, hcj = (hc_s, hc_l) if ri <= rj else (hc_l, hc_s)
        out.append(dict(i=int(i), j=int(j), ci=pk.x[i].copy(), n=bv / d, a=a,
                        ti=ri - hci, hn=hn, h=h, d=d))
    return out


# --------------------------------------------------------------------------
# geometry and mesh (gmsh)
class GeometryError(RuntimeError):
    pass


def inside(pk: rp.Packing, p):
    """Points p (n, 3) inside the union of spheres and neck cylinders (periodic)."""
    L = pk.L
    hit = np.zeros(len(p), dtype=bool)
    for c, r in zip(pk.x, pk.r):
        dv = p - c
        dv -= L * np.round(dv / L)
        hit |= np.einsum("ij,ij->i", dv, dv) < r * r
    for k in necks(pk):
        dv = p - (k["ci"] + k["n"] * k["ti"])
        dv -= L * np.round(dv / L)
        ax = np.einsum("ij,j->i", dv, k["n"])   # not BLAS (gemv): the same bits on every machine
        rad2 = np.einsum("ij,ij->i", dv, dv) - ax * ax
        hit |= (ax > 0) & (ax < k["hn"]) & (rad2 < k["a"] ** 2)
    return hit


def mc_volume(pk: rp.Packing, n=400_000, seed=7):
    """Monte-Carlo volume of the solid in the box and its standard error."""
    p = np.random.default_rng(seed).uniform(0, pk.L, (n, 3))
    f = inside(pk, p).mean()
    V = pk.L ** 3
    return f * V, math.sqrt(f * (1 - f) / n) * V



# --------------------------------------------------------------------------
def _images(center, radius, L):
    """Integer shifts s with the ball (center + L s, radius) meeting [0, L]^3."""
    out = []
    for s in itertools.product((-1, 0, 1), repeat=3):
        c = center + L * np.array(s)
        if np.all(c - radius < L) and np.all(c + radius > 0):
            out.append(np.array(s))
    return out


def build_mesh(pk: rp.Packing, m=1.0, n_a: float = 5.0, grow: float = 0.5,
               s_max: float = 0.45, order: int = 2, ext: float = 0.25,
               verbose: bool = False, threads: int = 1):
    """The geometry is built once; for each mesh factor in `m` (a number or a
    list) returns (X node coordinates by gmsh tag, T element node tags
    (nt, 4 or 10), solid volume of the geometry) -- a list if m is a list."""
    ms = list(m) if isinstance(m, (list, tuple)) else [m]
    import gmsh
    L = pk.L
    nk = necks(pk)
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 1 if verbose else 0)
        gmsh.option.setNumber("General.NumThreads", threads)
        gmsh.model.add("packing")
        occ = gmsh.model.occ
        ents = []
        for i, (c, r) in enumerate(zip(pk.x, pk.r)):
            for s in _images(c, r, L):
                cc = c + L * s
                ents.append((3, occ.addSphere(*cc, r)))
        for k in nk:
            a, n = k["a"], k["n"]
            e = ext * a
            p0 = k["ci"] + n * (k["ti"] - e)
            length = k["hn"] + 2 * e
            mid = p0 + 0.5 * length * n
            rad = math.hypot(0.5 * length, a)
            for s in _images(mid, rad, L):
                q = p0 + L * s
                ents.append((3, occ.addCylinder(*q, *(n * length), a)))
        box = occ.addBox(0, 0, 0, L, L, L)
        fused, _ = occ.fuse(ents[:1], ents[1:])
        solid, _ = occ.intersect(fused, [(3, box)])
        occ.synchronize()
        # periodic faces: match the surfaces of face k = 0 with those of k = L
        eps = 1e-7 * L
        for k in range(3):
            bb_lo = [-eps, -eps, -eps, L + eps, L + eps, L + eps]
            bb_lo[3 + k] = eps
            bb_hi = [-eps, -eps, -eps, L + eps, L + eps, L + eps]
            bb_hi[k] = L - eps
            s_lo = gmsh.model.getEntitiesInBoundingBox(*bb_lo, 2)
            s_hi = gmsh.model.getEntitiesInBoundingBox(*bb_hi, 2)
            hi_boxes = {t: np.array(gmsh.model.getBoundingBox(2, t)) for _, t in s_hi}
            tr = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
            tr[4 * k + 3] = L
            used = set()
            for _, t in s_lo:
                bl = np.array(gmsh.model.getBoundingBox(2, t))
                bl[k] += L
                bl[3 + k] += L
                best, bt = None, 1e30
                for th, bh in hi_boxes.items():
                    dd = np.max(np.abs(bh - bl))
                    if dd < bt:
                        best, bt = th, dd
                if best is None or bt > 1e-5 * L or best in used:
                    raise RuntimeError(f"periodic face {k}: no partner for surface {t} ({bt})")
                used.add(best)
                gmsh.model.mesh.setPeriodic(2, [best], [t], tr)
            if len(used) != len(s_hi):
                raise RuntimeError(f"periodic face {k}: {len(s_hi)} upper vs {len(s_lo)} lower surfaces")
        # size field
        C = np.array([k["ci"] + k["n"] * (k["ti"] + 0.5 * k["hn"]) for k in nk])
        N = np.array([k["n"] for k in nk])
        A = np.array([k["a"] for k in nk])
        H = np.array([k["hn"] for k in nk])
        fac = [1.0]

        def size(dim, tag, x, y, z, lc):
            m = fac[0]
            p = np.array([x, y, z])
            dv = p - C
            dv -= L * np.round(dv / L)
            ax = np.einsum("ij,ij->i", dv, N)
            rad = np.sqrt(np.maximum(np.einsum("ij,ij->i", dv, dv) - ax * ax, 0.0))
            dist = np.hypot(rad - A, np.maximum(np.abs(ax) - 0.5 * H, 0.0))
            return float(m * min(s_max, np.min(A / n_a + grow * dist)))
        gmsh.model.mesh.setSizeCallback(size)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        # the size callback is Python: sample it sparsely along the curves
        gmsh.option.setNumber("Mesh.LcIntegrationPrecision", 1e-3)
        vol = sum(gmsh.model.occ.getMass(3, t) for _, t in gmsh.model.getEntities(3))
        vmc, vse = mc_volume(pk)
        if abs(vol - vmc) > 4 * vse + 2e-3 * vmc:
            raise GeometryError(f"OCC solid volume {vol:.5f} != Monte-Carlo {vmc:.5f} "
                                f"+- {vse:.5f}: boolean failed")
        out = []
        for m in ms:
            fac[0] = m
            gmsh.model.mesh.clear()
            gmsh.model.mesh.generate(3)
            if order == 2:
                gmsh.model.mesh.setOrder(2)
            tags, coords, _ = gmsh.model.mesh.getNodes()
            etype = 11 if order == 2 else 4
            _, enodes = gmsh.model.mesh.getElementsByType(etype)
            X = np.zeros((int(tags.max()) + 1, 3))
            X[tags] = coords.reshape(-1, 3)
            nn = 10 if order == 2 else 4
            out.append((X, enodes.reshape(-1, nn).astype(np.int64), vol))
    finally:
        gmsh.finalize()
    return out


def mesh_to_skfem(X, T):
    from skfem import MeshTet1, MeshTet2
    verts = np.unique(T[:, :4])
    inv = -np.ones(X.shape[0], dtype=np.int64)
    inv[verts] = np.arange(len(verts))
    t = inv[T[:, :4]].T
    p = X[verts].T.copy()
    # orientation: positive volume
    v = np.einsum("ij,ij->j", np.cross((p[:, t[1]] - p[:, t[0]]).T, (p[:, t[2]] - p[:, t[0]]).T).T,
                  p[:, t[3]] - p[:, t[0]])
    t[[1, 2]] = np.where(v < 0, t[[2, 1]], t[[1, 2]])
    m1 = MeshTet1(p, t)
    if T.shape[1] == 4:
        return m1
    M = MeshTet2.from_mesh(m1)
    # gmsh tet10 mid nodes 4..9 sit on the edges (0,1) (1,2) (0,2) (0,3) (2,3) (1,3)
    # (gmsh.model.mesh.getElementProperties(11))
    pairs = [(0, 1), (1, 2), (0, 2), (0, 3), (2, 3), (1, 3)]
    Tv = inv[T[:, :4]]
    key = {}
    nv = m1.nvertices
    for q, (u, w) in enumerate(pairs):
        lo = np.minimum(Tv[:, u], Tv[:, w])
        hi = np.maximum(Tv[:, u], Tv[:, w])
        for l_, h_, pos in zip(lo.tolist(), hi.tolist(), X[T[:, 4 + q]]):
            key[(l_, h_)] = pos
    E = M.edges
    dl = M.doflocs.copy()
    straight = dl.copy()
    for e in range(E.shape[1]):
        dl[:, nv + e] = key[(int(E[0, e]), int(E[1, e]))]
    # gmsh's curved mid nodes can invert a few elements at the thin necks:
    # straighten every edge of an element whose Jacobian determinant drops
    # below a fifth of its straight value anywhere (vertices, edge mid-points,
    # centroid); a handful of elements, the boundary there is the chord
    Xr = np.array([[0, 1, 0, 0, .5, .5, 0, 0, .5, 0, .25],
                   [0, 0, 1, 0, 0, .5, .5, 0, 0, .5, .25],
                   [0, 0, 0, 1, 0, 0, 0, .5, .5, .5, .25]], float)
    d0 = m1._mapping().detDF(Xr)[:, :1]
    nfix = 0
    for _ in range(10):
        Mc = MeshTet2(dl, M.t)
        ratio = Mc._mapping().detDF(Xr) / d0
        bad = np.flatnonzero(np.min(ratio, axis=1) < 0.2)
        if len(bad) == 0:
            break
        ed = M.t2e[:, bad].ravel()
        dl[:, nv + ed] = straight[:, nv + ed]
        nfix += len(bad)
    else:
        raise RuntimeError("could not repair inverted P2 elements")
    Mc.n_straightened = nfix
    return Mc


# --------------------------------------------------------------------------
# periodic solve
# --------------------------------------------------------------------------
def periodic_map(doflocs, L, tol=1e-7):
    """Index of the representative of every DOF under the identification
    x ~ x + L e_k (positions equal modulo L)."""
    x = doflocs.T
    N = len(x)
    near = np.any((x < tol * L) | (x > L * (1 - tol)), axis=1)
    idx = np.flatnonzero(near)
    w = x[idx].copy()
    w[w > L * (1 - tol)] -= L
    rep = np.arange(N)
    if len(idx):
        tree = cKDTree(w)
        pairs = tree.query_pairs(1e-6 * L, output_type="ndarray")
        parent = np.arange(len(idx))

        def find(a):
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a
        for a, b in pairs:
            ra, rb = find(a), find(b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
        roots = np.array([find(a) for a in range(len(idx))])
        rep[idx] = idx[roots]
    return rep


def solve_kappa(M, L, verbose=False, p2=True):
    from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, asm
    from skfem.helpers import dot, grad
    elem = ElementTetP2() if p2 else ElementTetP1()
    basis = Basis(M, elem, intorder=4)

    @BilinearForm
    def lap(u, v, w):
        return dot(grad(u), grad(v))
    A = asm(lap, basis).tocsr()
    X = basis.doflocs
    N = basis.N
    rep = periodic_map(X, L)
    uniq, red = np.unique(rep, return_inverse=True)
    P = sp.csr_matrix((np.ones(N), (np.arange(N), red)), shape=(N, len(uniq)))
    # pairs of identified DOFs: their positions differ by a lattice vector
    d = X[:, np.arange(N)] - X[:, uniq[red]]
    if np.max(np.abs(d - L * np.round(d / L))) > 1e-6 * L:
        raise RuntimeError("periodic identification: positions do not match")
    n_ident = N - len(uniq)
    Ar = (P.T @ A @ P).tocsr()
    # connected solid: one constant mode; pin the first reduced DOF
    keep = np.arange(1, Ar.shape[0])
    Ak = Ar[keep][:, keep].tocsc()
    G = [X[k] for k in range(3)]
    rhs = [-(P.T @ (A @ g))[keep] for g in G]
    t0 = time.time()
    if Ak.shape[0] <= 8_000:
        lu = scipy.sparse.linalg.splu(Ak, permc_spec="MMD_AT_PLUS_A",
                                      options=dict(SymmetricMode=True))
        sols = [lu.solve(b) for b in rhs]
        how = "splu"
    else:
        import pyamg
        ml = pyamg.smoothed_aggregation_solver(Ak.tocsr(), symmetry="symmetric")
        sols = []
        for b in rhs:
            res = []
            x = ml.solve(b, tol=1e-10, accel="cg", maxiter=500, residuals=res)
            sols.append(x)
        how = f"amg-cg ({len(res)} it)"
    ts = time.time() - t0
    Ts = []
    for g, s in zip(G, sols):
        th = np.zeros(Ar.shape[0])
        th[keep] = s
        Ts.append(g + P @ th)
    V = L ** 3
    K = np.array([[float(Ts[k] @ (A @ Ts[l])) / V for l in range(3)] for k in range(3)])
    # flux average as a check: (1/V) int grad T_k dV  (equals the energy form
    # for the exact periodic solution; FE: the same up to solver tolerance)
    if verbose:
        print(f"    dofs {N} (reduced {len(uniq)}, identified {n_ident}), solve {how} {ts:.1f}s",
              flush=True)
    return K, dict(ndofs=int(len(uniq)), ntets=int(M.t.shape[1]), solver=how)


def mesh_factor(level):
    return 2.0 ** (1.0 - level / 3.0)


def fe_kappa_levels(pk, levels, order=2, verbose=False, **kw):
    """kappa_eff/kappa_s on the mesh levels (one geometry, remeshed): lists
    of 3x3 tensors and info dicts.  order=2: isoparametric P2 (gmsh's curved
    order-2 mesh); order=1: P1 on straight tetrahedra."""
    import copy
    Ks, infos = [], []
    rng = np.random.default_rng(1000 + int(pk.meta.get("seed", 0)))
    for level in levels:
        # The geometry is rebuilt per level.  OCC booleans occasionally fail
        # (caught by the Monte-Carlo volume check), and gmsh's periodic
        # surface meshing occasionally mismatches the curves of a surface
        # cut by two box faces ("curve .. has n vertices, whereas
        # correspondant .. has m"); kappa_eff does not depend on a translation
        # of the periodic packing, so that level is redone on a translated copy.
        t0 = time.time()
        q = copy.deepcopy(pk)
        for attempt in range(10):
            try:
                (X, T, vol), = build_mesh(q, m=[mesh_factor(level)], order=order, **kw)
                break
            except Exception as e:       # GeometryError or gmsh's meshing exception
                if verbose:
                    print(f"  level {level}: {str(e)[:120]}; translating the packing", flush=True)
                q.x = np.mod(q.x + rp._best_translation(q, rng, tries=50), q.L)
                _, s2 = rp._min_image(q.x, q.L, q.bonds[:, 0], q.bonds[:, 1])
                q.shifts = s2.astype(int)
        else:
            raise RuntimeError(f"level {level}: geometry/mesh failed in every translation")
        tm = time.time() - t0
        M = mesh_to_skfem(X, T)
        t1 = time.time()
        K, info = solve_kappa(M, pk.L, verbose, p2=(order == 2))
        info.update(straightened=int(getattr(M, "n_straightened", 0)), level=level,
                    translations=attempt,
                    mesh_factor=mesh_factor(level), t_mesh=tm, t_solve=time.time() - t1,
                    solid_volume_fraction=vol / pk.L ** 3)
        if verbose:
            print(f"  level {level}: tets {info['ntets']} dofs {info['ndofs']} "
                  f"geometry+mesh {tm:.1f}s solve {info['t_solve']:.1f}s  "
                  f"diag {np.diag(K)}", flush=True)
        Ks.append(K)
        infos.append(info)
    return Ks, infos


def extrapolate(hs, fs):
    """f = f_inf + C h^p through three (h, f) points (h decreasing); p from
    the ratio of differences with unequal refinement ratios (bisection).
    Returns (f_inf, p); p = nan and f_inf = last value if not monotone."""
    h1, h2, h3 = hs
    f1, f2, f3 = fs
    d12, d23 = f1 - f2, f2 - f3
    if d12 == 0 or d23 == 0 or (d12 > 0) != (d23 > 0):
        return f3, float("nan")
    R = d12 / d23

    def g(p):
        return (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - R
    lo, hi = 0.05, 12.0
    if g(lo) * g(hi) > 0:
        return f3, float("nan")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if g(lo) * g(mid) <= 0:
            hi = mid
        else:
            lo = mid
    p = 0.5 * (lo + hi)
    C = d23 / (h2 ** p - h3 ** p)
    return f3 - C * h3 ** p, p


# --------------------------------------------------------------------------
# the network (sinterdem binary)
# --------------------------------------------------------------------------
def sinterdem_bin():
    return os.environ.get("SINTERDEM_BIN", os.path.join(ROOT, "target", "release", "sinterdem"))


def network_kappa(pk, folder, name, conductance="fe_fit", multi_neck="none"):
    """The binary's periodic kappa_eff/kappa_s; multi_neck "none" (the pair's half
    for every neck: the table's net_* columns) or "fabric" (docs/heat-model.md
    (H8a)-(H8c), sinterdem's default)."""
    toml = rp.write_case(pk, folder, name, conductance=conductance, multi_neck=multi_neck)
    out = subprocess.run([sinterdem_bin(), "-q", "conductivity", toml], capture_output=True,
                         text=True, timeout=300)
    if out.returncode != 0:
        out = subprocess.run([sinterdem_bin(), "conductivity", toml], capture_output=True,
                             text=True, timeout=300)
    if out.returncode != 0:
        raise RuntimeError(f"sinterdem conductivity {toml}: {out.stderr}")
    res = json.loads(out.stdout)
    return np.array(res["kappa_eff_over_kappa"]), res


# --------------------------------------------------------------------------
# one case
# --------------------------------------------------------------------------
CASES = {
    # name: (n, eta, spread, seed)
    "n16-h002": (16, 0.02, 0.0, 1),
    "n16-h006": (16, 0.06, 0.0, 3),   # seed 1: the OCC union fails in every translation
    "n16-h012": (16, 0.12, 0.0, 1),
    "n16s-h002": (16, 0.02, 0.15, 2),
    "n16s-h006": (16, 0.06, 0.15, 2),
    "n16s-h012": (16, 0.12, 0.15, 2),
}


def stored_packing(name):
    """The reference geometry of case `name`: validation/data/random/<name>/packing.csv (the
    packing its stored FE was computed on; random_packing.load_packing).  make_packing's
    L-BFGS path depends on the BLAS kernels of the machine (OPENBLAS_CORETYPE), so the tests
    never regenerate a packing they compare with stored numbers."""
    folder = os.path.join(DATA, "random", name)
    meta = None
    if name in CASES:
        n, eta, spread, seed = CASES[name]
        meta = dict(n=n, eta=eta, spread=spread, seed=seed)
    return rp.load_packing(folder, meta)


def run_case(name, levels=(0, 1, 2), verbose=True, order=2, packing=None, workdir=None):
    """FE on `levels` and the binary's networks of case `name`.  `packing`: the geometry
    (default: the stored reference, stored_packing); `workdir`: where the network's case files
    go (default: a new temporary folder; never the stored data)."""
    pk = stored_packing(name) if packing is None else packing
    st = rp.stats(pk)
    Ks, infos = fe_kappa_levels(pk, levels, order=order, verbose=verbose)
    folder = workdir or tempfile.mkdtemp(prefix=f"sinterdem-fe-{name}-")
    Kn_fit, res = network_kappa(pk, folder, name, "fe_fit")
    Kn_lin, _ = network_kappa(pk, os.path.join(folder, "linear"), name, "linear")
    Kn_fab, _ = network_kappa(pk, os.path.join(folder, "fabric"), name, "fe_fit", "fabric")
    if res["periodic_contacts"] != st["contacts"]:
        raise RuntimeError(f"network sees {res['periodic_contacts']} contacts, packing has {st['contacts']}")
    if verbose:
        print(f"{name}: {json.dumps(st)}", flush=True)
        print(f"  network fe_fit diag {np.diag(Kn_fit)}; linear diag {np.diag(Kn_lin)}", flush=True)
    hs = [info["ndofs"] ** (-1.0 / 3.0) for info in infos]
    out = dict(name=name, stats=st, Kn_fit=Kn_fit, Kn_lin=Kn_lin, Kn_fab=Kn_fab, Ks=Ks, infos=infos)
    if len(levels) >= 3:
        tr = [np.trace(K) / 3 for K in Ks[-3:]]
        mean_x, p = extrapolate(hs[-3:], tr)
        diag_x = [extrapolate(hs[-3:], [K[k, k] for K in Ks[-3:]])[0] for k in range(3)]
        out.update(mean_x=mean_x, p=p, diag_x=np.array(diag_x), hs=hs)
    return out


def new_reference(name, folder=None):
    """A maintainer's step, never run by the tests: generate case `name` with make_packing and
    store it as the reference (folder/packing.csv, folder/<name>.toml and the linear/, fabric/
    variants; default validation/data/random/<name>).  The FE table of the case must then be
    recomputed on the stored files (run_case reads them back)."""
    folder = folder or os.path.join(DATA, "random", name)
    pk = rp.make_packing(*CASES[name])
    rp.write_case(pk, folder, name, conductance="fe_fit", multi_neck="none")
    rp.write_case(pk, os.path.join(folder, "linear"), name, conductance="linear", multi_neck="none")
    rp.write_case(pk, os.path.join(folder, "fabric"), name, conductance="fe_fit", multi_neck="fabric")
    rp.write_exact(pk, folder)
    return rp.load_packing(folder, pk.meta)


TABLE = os.path.join(DATA, "random_conductivity.csv")
COLUMNS = ["case", "n", "spread", "seed", "contacts", "mean_h_over_r", "min_h_over_r",
           "max_h_over_r", "coordination_mean", "solid_fraction_fe", "level", "ndofs", "ntets",
           "straightened", "t_mesh_s", "t_solve_s", "fe_xx", "fe_yy", "fe_zz", "fe_xy", "fe_xz",
           "fe_yz", "fe_mean", "net_fit_xx", "net_fit_yy", "net_fit_zz", "net_fit_xy",
           "net_fit_mean", "net_lin_mean"]


def case_rows(r):
    """CSV rows of one run_case result: one per level plus 'extrap'."""
    st = r["stats"]
    n, eta, spread, seed = CASES[r["name"]]
    Kf, Kl = r["Kn_fit"], r["Kn_lin"]
    base = [r["name"], n, spread, seed, st["contacts"], st["mean_h_over_r"], st["min_h_over_r"],
            st["max_h_over_r"], st["coordination_mean"]]
    net = [Kf[0, 0], Kf[1, 1], Kf[2, 2], Kf[0, 1], np.trace(Kf) / 3, np.trace(Kl) / 3]
    rows = []
    for K, info in zip(r["Ks"], r["infos"]):
        rows.append(base + [info["solid_volume_fraction"], info["level"], info["ndofs"],
                            info["ntets"], info["straightened"], round(info["t_mesh"], 1),
                            round(info["t_solve"], 1), K[0, 0], K[1, 1], K[2, 2], K[0, 1],
                            K[0, 2], K[1, 2], np.trace(K) / 3] + net)
    if "mean_x" in r:
        d = r["diag_x"]
        rows.append(base + [float("nan"), "extrap", r["p"], "", "", "", "", d[0], d[1], d[2],
                            "", "", "", r["mean_x"]] + net)
    return rows


def write_table(results, path=TABLE):
    import gmsh
    import pyamg
    import skfem
    with open(path, "w") as fh:
        fh.write("# 3-D periodic FE kappa_eff/kappa_s of random sintered packings vs sinterdem's network\n")
        fh.write(f"# generated by validation/fe_random.py --table on {datetime.date.today().isoformat()}; "
                 f"gmsh {gmsh.__version__}, scikit-fem {skfem.__version__}, pyamg {pyamg.__version__}\n")
        fh.write("# packings: validation/random_packing.py make_packing(n, eta, spread, seed), stored as the "
                 "reference in validation/data/random/<case>/ and read back from there\n")
        fh.write("# FE: union of spheres + volume-conserving neck cylinders, periodic P2 (isoparametric), "
                 "energy form; level L: mesh factor 2^(1 - L/3)\n")
        fh.write("# row level=extrap: f_inf of f = f_inf + C h^p through the last three levels, "
                 "h = ndofs^(-1/3); its 'ndofs' column holds the observed order p of the mean\n")
        fh.write("# net_fit_*: sinterdem conductivity with thermal.conductance = fe_fit, multi_neck = none; net_lin_mean: linear (1.064), none\n")
        fh.write(",".join(COLUMNS) + "\n")
        for r in results:
            for row in case_rows(r):
                fh.write(",".join(f"{v:.7g}" if isinstance(v, (float, np.floating)) else str(v)
                                  for v in row) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--case", default="n16-h012")
    ap.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--order", type=int, default=2)
    ap.add_argument("--table", action="store_true", help="all CASES -> " + TABLE)
    ap.add_argument("--cases", nargs="+", help="with --table: only these")
    ap.add_argument("--new-reference", action="store_true",
                    help="regenerate the case's packing with make_packing and store it as the "
                         "reference in validation/data/random/<case>/ (then recompute its FE)")
    a = ap.parse_args(argv)
    if a.new_reference:
        for name in (a.cases or [a.case]):
            pk = new_reference(name)
            print(f"{name}: stored {pk.meta['stored']}: {json.dumps(rp.stats(pk))}")
        return
    if a.table:
        results = []
        for name in (a.cases or list(CASES)):
            results.append(run_case(name, tuple(a.levels), order=a.order))
            write_table(results, TABLE if not a.cases else TABLE.replace(".csv", "_partial.csv"))
        return
    r = run_case(a.case, tuple(a.levels), order=a.order)
    for K, info in zip(r["Ks"], r["infos"]):
        print(info["level"], info["ndofs"], np.round(K, 6).tolist())
    if "mean_x" in r:
        mn = np.trace(r["Kn_fit"]) / 3
        print(f"FE mean extrapolated {r['mean_x']:.6f} (p = {r['p']:.2f}); network fe_fit "
              f"{mn:.6f} ({100 * (mn / r['mean_x'] - 1):+.2f} %), linear "
              f"{np.trace(r['Kn_lin']) / 3:.6f}")


if __name__ == "__main__":
    main()
