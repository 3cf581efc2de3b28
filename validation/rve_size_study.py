"""Size and seed study of the periodic representative volume (issue 23; docs/rve.md
"Size and seed study").

For every size N and seed s, with the same copper powder (50 um, 1 +- 0.1, uniform):
1. the walled green body: `sinterdem generate` (gravity and tapping in a box with walls,
   cases/green-copper.toml in a cube); its interior laminae give the interior solid fraction
   phi_int (docs/packing.md (S7));
2. the periodic green body at the same solid fraction phi_int (cases/packing/periodic-copper.toml);
3. both sintered as cases/periodic-copper-rve.toml does (isothermal 1293 K, 1000 s, 7-DOF at
   every contact, new contacts): the periodic cell free (zero mean stress), the walled body with
   the compact's usual supports;
4. compared: the cell's shrinkage and relative density against the walled body's interior, whose
   strain is the least-squares affine map of its interior particles (centres at least 1.5 mean
   diameters from the initial bounding box) from the first to the last snapshot,
   x_end = F x_0 + c, shrinkage_k = 1 - F_kk, and whose density is phi_int / det F (particle
   volume is conserved by the model); and the periodic conductivity tensor against the walled
   faces method (both at the end, `output.conductivity_at`);
5. the block: the periodic green body itself, opened into a block with cut faces (no
   periodic_box) and sintered as the walled body is; its interior, measured as the walled
   interior, is the same packing recipe as the cell with the boundary of a compact
   (docs/rve.md, "Size and seed study": "The same recipe"). Skipped with --no-block.
With --recipe die the periodic green body is made by the die path (docs/packing.md (G9)) at the
target phi_int, the walled bodies of --out are reused, and the table is written as study-die.csv.

Writes DIR/study.csv (one row per size, seed and body) and prints the table of means and spreads
over seeds. Long: at 8000 particles a seed takes minutes. Run:
    python validation/rve_size_study.py --out out/rve-size --sizes 500 2000 8000 --seeds 1 2 3
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def sh(args, log):
    with open(log, "w") as f:
        r = subprocess.run(args, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(map(str, args))}; see {log}")


def interior_fraction(gen_dir):
    import pandas as pd

    lam = pd.read_csv(gen_dir / "laminae.csv")
    return float(lam[lam["interior"].astype(str).str.lower().isin(["true", "1"])]["relative_density"].mean())


def positions(packing_csv, h5):
    """Initial centres (the packing file) and the last snapshot's, in the same particle order (by id)."""
    import h5py
    import pandas as pd

    x0 = pd.read_csv(packing_csv)[["x_m", "y_m", "z_m"]].to_numpy()
    with h5py.File(h5) as f:
        g = f["particles"]["all"]
        x1 = np.asarray(g["position"]["value"][-1])
        ids = np.asarray(g["id"]) if isinstance(g["id"], h5py.Dataset) else np.asarray(g["id"]["value"][-1])
    out = np.empty_like(x1)
    out[ids.astype(int)] = x1
    return x0, out


def affine(x0, x1, d_mean):
    lo, hi = x0.min(axis=0), x0.max(axis=0)
    inside = np.all((x0 > lo + 1.5 * d_mean) & (x0 < hi - 1.5 * d_mean), axis=1)
    a = np.hstack([x0[inside], np.ones((inside.sum(), 1))])
    coef, *_ = np.linalg.lstsq(a, x1[inside], rcond=None)
    return coef[:3].T, int(inside.sum())


def cell_interior_fit(packing_csv, h5, box, shrink, d_mean):
    """The periodic cell measured as the walled and block interiors are: its end centres unwrapped
    about the cell's affine map (minimum image of the end box; the fluctuations are far below a
    box), then the least-squares affine map of the particles 1.5 mean diameters inside the
    initial bounding box, i.e. the block's interior particles. Differs from the box strain by the
    fit's weighting of the periodic fluctuation field (a few 1e-4 of the shrinkage)."""
    x0, x1 = positions(packing_csv, h5)
    box, shrink = np.asarray(box), np.asarray(shrink)
    aff = x0 * (1.0 - shrink)
    d = x1 - aff
    d -= box * (1.0 - shrink) * np.round(d / (box * (1.0 - shrink)))
    return affine(x0, aff + d, d_mean)


def near_neighbours(gen_dir, periodic, d_mean=50e-6):
    """Neighbours per particle at gaps between 1e-3 and 2 % of the contact distance r_i + r_j in a
    green packing (the contacts that close during sintering); the walled body's interior only."""
    import pandas as pd
    from scipy.spatial import cKDTree

    p = pd.read_csv(gen_dir / "packing.csv")
    x, r = p[["x_m", "y_m", "z_m"]].to_numpy(), p["radius_m"].to_numpy()
    if periodic:
        box = np.asarray(json.load(open(gen_dir / "summary.json"))["box_size_m"])
        x = np.mod(x, box)
        tree, sel = cKDTree(x, boxsize=box), np.ones(len(x), bool)
    else:
        tree = cKDTree(x)
        lo, hi = x.min(axis=0), x.max(axis=0)
        sel = np.all((x > lo + 1.5 * d_mean) & (x < hi - 1.5 * d_mean), axis=1)
    pairs = tree.query_pairs(2.0 * r.max() * 1.03, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    d = x[j] - x[i]
    if periodic:
        d -= box * np.round(d / box)
    gap = np.linalg.norm(d, axis=1) / (r[i] + r[j]) - 1.0
    m = (gap >= 1e-3) & (gap < 2e-2)
    count = np.bincount(i[m], minlength=len(x)) + np.bincount(j[m], minlength=len(x))
    return float(count[sel].mean())


def kappa(summary):
    c = summary.get("conductivity") or []
    last = c[-1]
    k = last.get("kappa_eff_W_per_mK")
    k = np.asarray(k, dtype=float)
    return np.diag(k) if k.ndim == 2 else k


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--sizes", type=int, nargs="+", default=[500, 2000, 8000])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--end", type=float, default=1000.0)
    ap.add_argument("--bin", default=str(ROOT / "target/release/sinterdem"))
    ap.add_argument("--recipe", choices=["isotropic", "die"], default="isotropic",
                    help="packing.protocol.compaction of the periodic green body (docs/packing.md (G5), (G9))")
    ap.add_argument("--no-block", action="store_true", help="skip the block cut from the periodic packing")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="extra override of both sintering runs, e.g. contacts.detect_new=false (the green packings of --out are reused)")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    b = a.bin
    rows = []
    for n in a.sizes:
        for s in a.seeds:
            tag = f"n{n}-s{s}"
            k0 = len(rows)
            gw, gp = out / f"gen-walled-{tag}", out / f"gen-periodic-{tag}"
            if not (gw / "summary.json").exists():
                sh([b, "run", ROOT / "cases/green-copper.toml", "--out", gw, "--quiet", "--set", f"packing.particles={n}",
                    "--set", f"packing.seed={s}", "--set", "packing.box=[1.0,1.0,1.0]"], out / f"{tag}-gw.log")
            phi = interior_fraction(gw)
            if a.recipe == "die":
                gp = out / f"gen-periodic-die-{tag}"
            if not (gp / "summary.json").exists():
                # the die aims at phi (1 + 2 c_o) and unloads to about phi + 0.005 (G9)
                sh([b, "run", ROOT / "cases/packing/periodic-copper.toml", "--out", gp, "--quiet", "--set", f"packing.particles={n}",
                    "--set", f"packing.seed={s}", "--set", f"packing.target_solid_fraction={phi:.6f}",
                    *(["--set", 'packing.protocol.compaction="die"'] if a.recipe == "die" else [])], out / f"{tag}-gp.log")
            gen_p = json.load(open(gp / "summary.json"))
            box, phi_cell = gen_p["box_size_m"], gen_p["solid_fraction"]
            common = ["--set", f"time.end={a.end}", "--set", "output.snapshots=1", "--set", f"output.conductivity_at=[{a.end}]",
                      "--set", "output.checkpoint_every=0", *[x for kv in a.set for x in ("--set", kv)]]

            def sinter(run_dir, packing, particles_extra, mechanics, log_tag):
                """The sintering run of a green body (cases/periodic-copper-rve.toml), unless done."""
                if not (run_dir / "summary.json").exists():
                    sh([b, "run", ROOT / "cases/periodic-copper-rve.toml", "--out", run_dir, "--quiet",
                        "--set", f'particles={{source="file",file="{packing.resolve()}"{particles_extra}}}', *mechanics, *common],
                       out / f"{tag}-{log_tag}.log")
                return json.load(open(run_dir / "summary.json"))

            def row(body, phi0, summary, f, inside, nn):
                """A table row of a body measured by the affine map F of its interior (`inside` particles)."""
                k = kappa(summary)
                return dict(n=n, seed=s, body=body, phi0=phi0, shrink_x=1 - f[0, 0], shrink_y=1 - f[1, 1], shrink_z=1 - f[2, 2],
                            density=phi0 / np.linalg.det(f), kxx=k[0], kyy=k[1], kzz=k[2], near_neighbours=nn, interior=inside,
                            wall_s=sum(summary["timing_seconds"].values()))

            walls = ["--set", 'mechanics={boundary="walls"}']
            rp, rw = out / f"run-periodic{'-die' if a.recipe == 'die' else ''}-{tag}", out / f"run-walled-{tag}"
            sp = sinter(rp, gp / "packing.csv", f",periodic_box={box}", [], "rp")
            sw = sinter(rw, gw / "packing.csv", "", walls, "rw")
            kp = kappa(sp)
            nn_cell = near_neighbours(gp, True)
            rows.append(dict(n=n, seed=s, body=f"periodic ({a.recipe})", phi0=phi_cell, shrink_x=sp["shrinkage_x"], shrink_y=sp["shrinkage_y"],
                             shrink_z=sp["shrinkage_z"], density=sp["relative_density"], kxx=kp[0], kyy=kp[1], kzz=kp[2], interior=n,
                             near_neighbours=nn_cell, wall_s=sum(sp["timing_seconds"].values())))
            cell_shrink = [sp["shrinkage_x"], sp["shrinkage_y"], sp["shrinkage_z"]]
            rows.append(row(f"periodic ({a.recipe}), interior fit", phi_cell, sp,
                            *cell_interior_fit(gp / "packing.csv", rp / "sinterdem.h5", box, cell_shrink, 50e-6), nn_cell))
            rows.append(row("walled interior", phi, sw, *affine(*positions(gw / "packing.csv", rw / "sinterdem.h5"), 50e-6),
                            near_neighbours(gw, False)))
            if not a.no_block and a.recipe == "isotropic":
                # the same periodic packing opened into a block with cut faces and sintered as the
                # walled body is: the same packing recipe, with the boundary of a compact
                rb = out / f"run-block-{tag}"
                sb = sinter(rb, gp / "packing.csv", "", walls, "rb")
                rows.append(row("block interior", phi_cell, sb, *affine(*positions(gp / "packing.csv", rb / "sinterdem.h5"), 50e-6), nn_cell))
            print(tag, *rows[k0:], sep="\n  ", flush=True)
    import pandas as pd

    df = pd.DataFrame(rows)
    df.to_csv(out / f"study{'-die' if a.recipe == 'die' else ''}.csv", index=False)
    df["shrink_mean"] = df[["shrink_x", "shrink_y", "shrink_z"]].mean(axis=1)
    df["kappa_mean"] = df[["kxx", "kyy", "kzz"]].mean(axis=1)
    g = df.groupby(["body", "n"])[["phi0", "shrink_mean", "density", "kappa_mean", "near_neighbours"]].agg(["mean", "std", "count"])
    pd.set_option("display.width", 200)
    print(g)
    g.to_csv(out / f"summary_by_size{'-die' if a.recipe == 'die' else ''}.csv")


if __name__ == "__main__":
    main()
