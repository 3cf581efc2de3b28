#!/usr/bin/env python3
"""The network's kappa_eff/kappa_s beside measured sintered compacts: the plot of
docs/validation-conductance.md "Measured compacts".

Reads validation/data/measured/compacts.csv (the measurements, PROVENANCE.md beside it) and
validation/data/measured_compacts_model.csv (the model rows, written by the Rust test
`measured_compacts_model_table`), and writes validation/data/measured_compacts.png.
The bulk properties the measured ratios use are the library's (src/models/diffusion7/materials.toml):
copper 401 and silver 429 W/(m K) at 300 K (Incropera Table A.1); copper 1.678e-8 (Matula 1979) and
silver 1.587e-8 Ohm m (CRC) at 293 K.

Usage: validation/.venv/bin/python validation/measured_compacts.py [--out PATH]
"""
import argparse
import csv
import os

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "data")
# the library's bulk values (see the docstring); the same numbers the Rust test reads from the library
KAPPA_S = {"copper": 401.0, "silver": 429.0}
RHO_E_S = {"copper": 1.678e-8, "silver": 1.587e-8}


def rows(path):
    with open(path, encoding="utf-8") as fh:
        return list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))


def measured():
    out = []
    for r in rows(os.path.join(DATA, "measured", "compacts.csv")):
        v = float(r["value"])
        ratio = v / KAPPA_S[r["material"]] if r["quantity"] == "thermal" else RHO_E_S[r["material"]] / v
        out.append((r, float(r["relative_density_min"]), float(r["relative_density_max"]), ratio))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(DATA, "measured_compacts.png"))
    a = ap.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    model = rows(os.path.join(DATA, "measured_compacts_model.csv"))
    rve = [m for m in model if m["source"].startswith("rve-")]
    loose = [m for m in model if not m["source"].startswith("rve-")]
    fig, ax = plt.subplots(figsize=(7.0, 5.0))
    phi = [float(m["solid_fraction"]) for m in rve]
    ax.plot(phi, [float(m["kappa_over_kappa_s"]) for m in rve], "k-o", ms=3,
            label="network, RVE densified from 0.60 (R_b = 0)")
    for col, ls, lab in (("kappa_rb_1e-8", "--", "R_b = 1e-8 m²K/W (d = 50 µm)"),
                         ("kappa_rb_1e-7", ":", "R_b = 1e-7 m²K/W (d = 50 µm)")):
        ax.plot(phi, [float(m[col]) for m in rve], "k" + ls, lw=1, label=lab)
    ax.plot([float(m["solid_fraction"]) for m in loose], [float(m["kappa_over_kappa_s"]) for m in loose],
            "ks", mfc="none", label="network, loosest FE-validated cells (h/r 0.02)")
    hs_phi = [0.45 + 0.005 * k for k in range(101)]
    ax.plot(hs_phi, [2 * p / (3 - p) for p in hs_phi], color="0.6", lw=1, label="Hashin–Shtrikman 2φ/(3 − φ)")
    vmark = {"pss2008": ("C0", "o"), "fang2024": ("C1", "^"), "kim2021": ("C2", "D"),
             "rosinski2005": ("C3", "v"), "agsinter": ("C4", "s")}
    seen = set()
    for r, lo, hi, ratio in measured():
        c, mk = vmark[r["source"]]
        kind = "κ" if r["quantity"] == "thermal" else "σ"
        lab = f"{r['source']} ({r['material']}, {kind})"
        ax.plot([lo, hi] if hi > lo else [lo], [ratio, ratio] if hi > lo else [ratio],
                color=c, marker=mk, ls="-" if hi > lo else "none", mfc=c if kind == "κ" else "none",
                label=None if lab in seen else lab)
        seen.add(lab)
    ax.set_xlabel("relative density (solid fraction)")
    ax.set_ylabel("κ_eff/κ_s  or  σ_eff/σ_s")
    ax.set_xlim(0.45, 0.95)
    ax.set_ylim(0.0, 0.9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title("Network (fe_fit + fabric, bound (H8d)) beside measured sintered compacts", fontsize=9)
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)
    print(a.out)


if __name__ == "__main__":
    main()
