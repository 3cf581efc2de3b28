"""The plot of docs/validation-conductance.md "Measured compacts" (validation/measured_compacts.py):
its bulk values are the library's, and it draws from the stored CSVs (into a temporary file)."""
import os
import subprocess
import sys
import tomllib

import measured_compacts as mc

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def library():
    with open(os.path.join(ROOT, "src", "models", "diffusion7", "materials.toml"), "rb") as fh:
        return {m["name"]: m for m in tomllib.load(fh)["materials"]}


def at(table, t):
    for (t0, v0), (t1, v1) in zip(table, table[1:]):
        if t0 <= t <= t1:
            return v0 + (v1 - v0) * (t - t0) / (t1 - t0)
    raise ValueError(t)


def test_bulk_values_are_the_librarys():
    lib = library()
    for name in ("copper", "silver"):
        tables = lib[name]["tables"]
        assert abs(at(tables["conductivity_table"], 300.0) - mc.KAPPA_S[name]) < 1e-9
        assert abs(at(tables["electrical_resistivity_table"], 293.15) / mc.RHO_E_S[name] - 1) < 2e-3


def test_every_measured_row_has_a_ratio_and_the_plot_draws(tmp_path):
    rows = mc.measured()
    assert {r["source"] for r, *_ in rows} == {"pss2008", "fang2024", "kim2021", "rosinski2005", "agsinter"}
    assert all(0 < ratio < 1 and 0 < lo <= hi < 1 for _, lo, hi, ratio in rows)
    out = tmp_path / "m.png"
    subprocess.run([sys.executable, os.path.join(ROOT, "validation", "measured_compacts.py"), "--out", str(out)], check=True)
    assert out.stat().st_size > 10_000
