#!/usr/bin/env python3
"""FE of larger random periodic cells (64 spheres) against the network
(docs/validation-conductance.md "Random periodic packings", "Larger cells
(64 spheres)"): do the per-axis deviations of the 16-sphere cells (up to 3 %)
shrink when the cell holds four times as many spheres?  Same recipe
(random_packing.make_packing) and FE (fe_random.run_case) as the 16-sphere
cases; fewer mesh levels (the cell is four times larger).
Writes validation/data/random_large.csv (same columns as
random_conductivity.csv; FE_OUT names another file under validation/data/, the
third case is in random_large_b.csv).  The network with the default law
(thermal.multi_neck = "fabric") is not a column of that file: it is recomputed
from the case toml the run writes, validation/data/random/<case>/fabric/<case>.toml
(`sinterdem conductivity ...`), and printed on the DONE line.
Usage: [FE_LEVELS="0 1 2 3"] python validation/large_cell_fe.py [NAME ...]
       python validation/large_cell_fe.py --report   # the doc's table from the CSV + the binary
(SINTERDEM_BIN: the binary, default target/release/sinterdem.)
"""
import csv
import glob
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fe_random as fr  # noqa: E402

import numpy as np  # noqa: E402

NEW = {
    # name: (n_spheres, eta, spread, seed)
    "n64-h006": (64, 0.06, 0.0, 1),
    "n64s-h012": (64, 0.12, 0.15, 1),
    # run later into random_large_b.csv (FE_OUT)
    "n64-h002": (64, 0.02, 0.0, 1),
}
fr.CASES.update(NEW)
OUT = os.path.join(fr.DATA, os.environ.get("FE_OUT", "random_large.csv"))


def main(names, levels=tuple(int(v) for v in os.environ.get("FE_LEVELS", "0 1 2 3").split())):
    results = []
    for name in names:
        try:
            if not os.path.exists(os.path.join(fr.DATA, "random", name, "packing.csv")):
                fr.new_reference(name)     # a new case: its packing becomes the stored reference
            r = fr.run_case(name, levels)
        except Exception as e:  # a packing whose OCC union fails everywhere: report, go on
            print(f"{name}: FAILED {e}", flush=True)
            continue
        results.append(r)
        fr.write_table(results, OUT)
        fab, none = np.diag(r["Kn_fab"]), np.diag(r["Kn_fit"])
        line = f"DONE {name} fe levels " + "; ".join(
            f"{i['level']}: {np.round(np.diag(K), 6).tolist()}" for K, i in zip(r["Ks"], r["infos"]))
        if "mean_x" in r:
            fe = r["diag_x"]
            line += (f" | extrap {np.round(fe, 6).tolist()} mean {r['mean_x']:.6f} p {r['p']:.2f}"
                     f" | fabric {np.round(fab, 6).tolist()} ({100 * (fab.sum() / fe.sum() - 1):+.2f} %;"
                     f" {', '.join(f'{100 * v:+.2f}' for v in fab / fe - 1)})"
                     f" | none {np.round(none, 6).tolist()} ({100 * (none.sum() / fe.sum() - 1):+.2f} %)")
        print(line, flush=True)


def _binary(toml):
    out = subprocess.run([fr.sinterdem_bin(), "-q", "conductivity", toml], capture_output=True,
                         text=True, timeout=300, check=True)
    return np.array(json.loads(out.stdout)["kappa_eff_over_kappa"])


def stored(path=None):
    """case -> dict from the stored CSV and the binary run on the stored case files
    (validation/data/random/<case>/<case>.toml: multi_neck = "none";
    .../fabric/<case>.toml: "fabric")."""
    rows = []
    for p in ([path] if path else sorted(glob.glob(os.path.join(fr.DATA, "random_large*.csv")))):
        with open(p) as fh:
            rows += list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    out = {}
    for name in dict.fromkeys(r["case"] for r in rows):
        rs = [r for r in rows if r["case"] == name]
        lv = [r for r in rs if r["level"] != "extrap"]
        ex = [r for r in rs if r["level"] == "extrap"]
        diag = lambda r: np.array([float(r[f"fe_{c}"]) for c in ("xx", "yy", "zz")])  # noqa: E731
        folder = os.path.join(fr.DATA, "random", name)
        d = dict(levels=[r["level"] for r in lv], fe_levels=[diag(r) for r in lv],
                 ndofs=[int(r["ndofs"]) for r in lv],
                 t=[float(r["t_mesh_s"]) + float(r["t_solve_s"]) for r in lv],
                 h=float(rs[0]["mean_h_over_r"]), z=float(rs[0]["coordination_mean"]),
                 contacts=int(rs[0]["contacts"]),
                 none=np.diag(_binary(os.path.join(folder, f"{name}.toml"))),
                 fabric=np.diag(_binary(os.path.join(folder, "fabric", f"{name}.toml"))))
        if ex:
            d.update(fe=diag(ex[0]), mean_x=float(ex[0]["fe_mean"]), p=float(ex[0]["ndofs"]))
            # pessimistic: the last two levels with the corner-limited order 2 pi / omega of the
            # mean neck, omega = 3 pi / 2 - asin(a / r) (docs "Geometry and FE", "Convergence")
            pk = fr.stored_packing(name) if name in fr.CASES else None
            if pk is not None:
                ar = np.mean([k["a"] / min(pk.r[k["i"]], pk.r[k["j"]]) for k in fr.necks(pk)])
                pc = 2 * np.pi / (1.5 * np.pi - np.arcsin(ar))
                h2, h3 = (n ** (-1.0 / 3.0) for n in d["ndofs"][-2:])
                f2, f3 = d["fe_levels"][-2:]
                d.update(p_corner=pc, fe_corner=f3 - (f2 - f3) / ((h2 / h3) ** pc - 1))
        out[name] = d
    return out


def report(path=None):
    print("| case | necks | mean h/r | mean Z | FE levels (dofs): mean; xx, yy, zz | FE converged: mean; xx, yy, zz "
          "(change from finest) | network none: mean (dev.) | network fabric: mean; xx, yy, zz | "
          "dev. fabric: mean; per axis | dev. fabric against the extrapolation with p = 2 pi/omega: mean; per axis |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    f4 = lambda v: ", ".join(f"{x:.5f}" for x in v)  # noqa: E731
    for name, d in stored(path).items():
        lv = "<br>".join(f"L{l} ({n // 1000}k): {v.mean():.5f}; {f4(v)}"
                         for l, v, n in zip(d["levels"], d["fe_levels"], d["ndofs"]))
        if "fe" not in d:
            print(f"| {name} | {d['contacts']} | {d['h']:.3f} | {d['z']:.2f} | {lv} | (no extrapolation) | | | |")
            continue
        fe, fin, nn, fb = d["fe"], d["fe_levels"][-1], d["none"], d["fabric"]
        ch = fe / fin - 1
        print(f"| {name} | {d['contacts']} | {d['h']:.3f} | {d['z']:.2f} | {lv} | "
              f"{fe.mean():.5f}; {f4(fe)} ({100 * (fe.mean() / fin.mean() - 1):+.2f} %; "
              f"{', '.join(f'{100 * v:+.2f}' for v in ch)} %; p = {d['p']:.2f}) | "
              f"{nn.mean():.5f} ({100 * (nn.sum() / fe.sum() - 1):+.2f} %) | {fb.mean():.5f}; {f4(fb)} | "
              f"**{100 * (fb.sum() / fe.sum() - 1):+.2f} %**; "
              f"{', '.join(f'{100 * v:+.2f}' for v in fb / fe - 1)} % | "
              + (f"p = {d['p_corner']:.2f}: {100 * (fb.sum() / d['fe_corner'].sum() - 1):+.2f} %; "
                 f"{', '.join(f'{100 * v:+.2f}' for v in fb / d['fe_corner'] - 1)} % |" if "fe_corner" in d else " |"))


if __name__ == "__main__":
    if sys.argv[1:] == ["--report"]:
        report()
    else:
        main(sys.argv[1:] or list(NEW))
