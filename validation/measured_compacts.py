#!/usr/bin/env python3
"""The network's kappa_eff/kappa_s beside measured sintered compacts: the plot of
docs/validation-conductance.md "Measured compacts".

Reads validation/data/measured/compacts.csv (the measurements, PROVENANCE.md beside it) and
validation/data/measured_compacts_model.csv (the model rows, written by the Rust test
`measured_compacts_model_table`), and writes validation/data/measured_compacts.png.
The bulk properties the measured ratios use are the library's (src/models/diffusion7/materials.toml):
copper 401 and silver 429 W/(m K) at 300 K (Incropera Table A.1); copper 1.678e-8 (Matula 1979) and
silver 1.587e-8 Ohm m (CRC) at 293 K.

Usage: validation/.venv/bin/python validation/measured_compacts.py [--out PATH] [--table]
(--table prints the markdown table of the docs instead of drawing).
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


def model_at(rve, rho, col="kappa_over_kappa_s"):
    """The RVE rows' column `col` at solid fraction `rho`, linear between the rows."""
    pts = [(float(m["solid_fraction"]), float(m[col])) for m in rve]
    for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
        if x0 <= rho <= x1:
            return y0 + (y1 - y0) * (rho - x0) / (x1 - x0)
    raise ValueError(rho)


def matching_rb(rve, rho, ratio):
    """R_b [m^2 K/W] (for the model's d = 50 um copper) at which the RVE at `rho` reads `ratio`:
    log-linear between the R_b columns 0, 1e-8, 1e-7, 1e-6; None outside them."""
    import math
    cols = [(1e-8, "kappa_rb_1e-8"), (1e-7, "kappa_rb_1e-7"), (1e-6, "kappa_rb_1e-6")]
    prev = (None, model_at(rve, rho))
    for rb, col in cols:
        k = model_at(rve, rho, col)
        if k <= ratio <= prev[1]:
            if prev[0] is None:
                return None
            f = (prev[1] - ratio) / (prev[1] - k)
            return 10 ** (math.log10(prev[0]) + f * (math.log10(rb) - math.log10(prev[0])))
        prev = (rb, k)
    return None


def table(model):
    rve = [m for m in model if m["source"].startswith("rve-")]
    loose = [float(m["kappa_over_kappa_s"]) for m in model if not m["source"].startswith("rve-")]
    print("| source | material, process | quantity | ρ | measured | measured/bulk | model at that ρ | model/measured | R_b matching it (d = 50 µm) |")
    print("|---|---|---|---|---|---|---|---|---|")
    bands = {}
    for r, lo, hi, ratio in measured():
        if r["source"] == "agsinter":
            bands.setdefault(r["quantity"], []).append((r, lo, hi, ratio))
            continue
        rho = f"{lo:g}" if hi == lo else f"{lo:g}–{hi:g}"
        val = f"{r['value']} {r['unit']}"
        if r["source"] == "fang2024":
            mod = f"{min(loose):.3f}–{max(loose):.3f} (loose FE cells, ρ 0.51–0.57; mean {sum(loose) / len(loose):.3f})"
            rel = f"{min(loose) / ratio:.2f}–{max(loose) / ratio:.2f} (mean {sum(loose) / len(loose) / ratio:.2f})"
            rb = "—"
        else:
            ks = [model_at(rve, x) for x in sorted({lo, hi})]
            mod = " / ".join(f"{k:.3f}" for k in ks)
            rel = " / ".join(f"{k / ratio:.2f}" for k in ks)
            rbs = [matching_rb(rve, x, ratio) for x in sorted({lo, hi})]
            rb = " / ".join("—" if x is None else f"{x:.1e}" for x in rbs) + " m²·K/W" if r["quantity"] == "thermal" else "— (not applied to a current)"
        print(f"| {r['source']} | {r['material']}, {r['process']} | {r['quantity']} ({r['method']}) | {rho} | {val} | {ratio:.4f} | {mod} | {rel} | {rb} |")


    for q, band in bands.items():
        r, lo, hi = band[0][0], band[0][1], band[0][2]
        ratios = sorted(x[3] for x in band)
        vals = sorted(float(x[0]["value"]) for x in band)
        print(f"| {r['source']} | {r['material']}, {r['process']} | {q} ({r['method']}), a band | {lo:g}–{hi:g} | {vals[0]:g}–{vals[-1]:g} {r['unit']} "
              f"| {ratios[0]:.3f}–{ratios[-1]:.3f} | {min(loose):.3f} (ρ 0.56) – {model_at(rve, hi):.3f} (ρ {hi:g}) "
              f"| the band's top is {model_at(rve, hi) / ratios[-1]:.2f} times below the model at ρ {hi:g} | — |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(DATA, "measured_compacts.png"))
    ap.add_argument("--table", action="store_true")
    a = ap.parse_args()
    if a.table:
        table(rows(os.path.join(DATA, "measured_compacts_model.csv")))
        return
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
    bands = {}
    for r, lo, hi, ratio in measured():
        if r["source"] == "agsinter":
            bands.setdefault(r["quantity"], []).append((lo, hi, ratio))
            continue
        c, mk = vmark[r["source"]]
        kind = "κ" if r["quantity"] == "thermal" else "σ"
        lab = f"{r['source']} ({r['material']}, {kind})"
        ax.plot([lo, hi] if hi > lo else [lo], [ratio, ratio] if hi > lo else [ratio],
                color=c, marker=mk, ls="-" if hi > lo else "none", mfc=c if kind == "κ" else "none",
                label=None if lab in seen else lab)
        seen.add(lab)
    for q, band in bands.items():
        lo, hi = band[0][0], band[0][1]
        r = [x[2] for x in band]
        ax.fill_between([lo, hi], [min(r)] * 2, [max(r)] * 2, color="C4", alpha=0.12 if q == "thermal" else 0.22,
                        label=f"agsinter (silver, {'κ' if q == 'thermal' else 'σ'}): a band of ranges")
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
