"""sinterdem's output files read back in the tools users have: meshio (VTU, as ParaView through
VTK), h5py (the H5MD-layout HDF5 file, through the example of docs/outputs.md) and pandas (every
CSV of short runs of the bundled kinds, read with a plain `pandas.read_csv(path)`)."""
import json
import os
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(os.environ.get("SINTERDEM_BIN", ROOT / "target" / "release" / "sinterdem"))
needs_bin = pytest.mark.skipif(not BIN.exists(), reason=f"sinterdem binary not built at {BIN}")

# count columns: integers in every CSV (docs/outputs.md)
COUNT_COLUMNS = {"contacts", "steps", "particles", "rhs_evaluations", "radiation_iterations", "stage",
                 "particle_a", "particle_b", "id", "rejected", "rhs"}


def run(*args):
    subprocess.run([str(BIN), *map(str, args)], check=True, capture_output=True, cwd=ROOT)


@pytest.fixture(scope="module")
def heat_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("hp") / "hp"
    run("run", ROOT / "cases" / "hot-plate.toml", "--out", out, "--quiet",
        "--set", "particles.cells=[2, 2, 3]", "--set", "time.end=5", "--set", "output.snapshots=2",
        "--set", "output.hdf5=true")
    return out


@pytest.fixture(scope="module")
def compact_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cu") / "cu"
    run("run", ROOT / "cases" / "copper-compact.toml", "--out", out, "--quiet",
        "--set", "time.end=20", "--set", "output.snapshots=3", "--set", "output.hdf5=true",
        "--set", "output.conductivity_at=[]", "--set", "output.correction_histogram_at=[10.0]")
    return out


@needs_bin
def test_heat_run_vtu_reads_back_in_meshio(heat_run):
    import meshio

    out = heat_run
    summary = json.loads((out / "summary.json").read_text())
    particles = meshio.read(out / "particles_000001.vtu")
    contacts = meshio.read(out / "contacts_000001.vtu")
    n = summary["particles"]
    assert particles.points.shape == (n, 3)
    temp = particles.point_data["temperature_K"]
    assert abs(temp.mean() - summary["mean_temperature_K"]) < 1e-6
    assert abs(temp.max() - summary["max_temperature_K"]) < 1e-6
    assert (particles.point_data["id"] == np.arange(n)).all()
    lines = contacts.cells_dict["line"]
    assert lines.shape == (summary["contacts"], 2)
    assert (contacts.cell_data["particle_a"][0] == lines[:, 0]).all()
    assert (contacts.cell_data["particle_b"][0] == lines[:, 1]).all()
    # coordination = contacts per particle
    z = np.bincount(lines.ravel(), minlength=n)
    assert (particles.point_data["coordination"] == z).all()
    neck = contacts.cell_data["neck_radius_m"][0]
    assert neck.shape == (summary["contacts"],) and (neck > 0).all()
    assert "<DataArray" in (out / "particles_000001.vtu").read_text() and 'format="ascii"' not in (out / "particles_000001.vtu").read_text()


@needs_bin
def test_compact_run_vtu_vectors_and_names(compact_run):
    import meshio

    out = compact_run
    summary = json.loads((out / "summary.json").read_text())
    first = meshio.read(out / "particles_000000.vtu")
    last = meshio.read(out / "particles_000002.vtu")
    n = summary["particles"]
    u = last.point_data["displacement_m"]
    assert u.shape == (n, 3)
    assert np.allclose(first.point_data["displacement_m"], 0.0)
    # displacement = position - initial position
    assert np.allclose(last.points - first.points, u, rtol=0, atol=1e-18)
    assert np.abs(u).max() > 0
    c = meshio.read(out / "contacts_000002.vtu")
    assert c.cells_dict["line"].shape == (summary["contacts"], 2)
    for name in ["neck_radius_m", "contact_shrinkage", "dl_bar_m", "particle_a", "particle_b"]:
        assert c.cell_data[name][0].shape == (summary["contacts"],), name
    z = np.bincount(c.cells_dict["line"].ravel(), minlength=n)
    assert (last.point_data["coordination"] == z).all()
    assert abs(z.mean() - summary["coordination_mean"]) < 1e-12


def docs_example():
    """The h5py example of docs/outputs.md (the python block starting `# example: read sinterdem.h5`)."""
    text = (ROOT / "docs" / "outputs.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    code = [b for b in blocks if b.startswith("# example: read sinterdem.h5")]
    assert len(code) == 1, "docs/outputs.md lost its h5py example"
    return code[0]


@needs_bin
@pytest.mark.parametrize("which", ["compact", "heat"])
def test_docs_h5py_example_reads_the_file(which, compact_run, heat_run, capsys):
    out = compact_run if which == "compact" else heat_run
    h5 = out / "sinterdem.h5"
    if not h5.exists():
        log = (out / "log.txt").read_text()
        reason = "sinterdem was built without the h5 feature" if "HDF5 output is off" in log else f"no {h5} written"
        print(f"skipped: {reason}")
        pytest.skip(reason)
    import h5py

    code = docs_example().replace('path = "out/copper-compact/sinterdem.h5"', f"path = {str(h5)!r}")
    scope = {}
    exec(compile(code, "docs/outputs.md", "exec"), scope)
    summary = json.loads((out / "summary.json").read_text())
    assert scope["summary"] == summary
    assert len(scope["x"]) == summary["particles"]
    assert scope["n"] == summary["contacts"]
    assert scope["times"][-1] == summary["final_time_s"]
    assert abs(scope["mean_T"][-1] - summary["mean_temperature_K"]) < 1e-9
    assert (scope["pairs"] >= 0).all() and (scope["neck"] > 0).all()
    assert "[time]" in scope["case"]
    # a unit on every dataset; chunked and compressed time series
    with h5py.File(h5, "r") as f:
        missing = []
        f.visititems(lambda name, o: missing.append(name) if isinstance(o, h5py.Dataset) and "unit" not in o.attrs else None)
        assert not missing, missing
        v = f["particles/all/position/value"]
        assert v.chunks is not None and v.compression == "gzip"
        assert list(f["h5md"].attrs["version"]) == [1, 1]


def short_runs(tmp):
    """Short runs of the bundled kinds that write CSVs; returns their output directories."""
    outs = {}
    outs["heat"] = tmp / "heat"
    run("run", ROOT / "cases" / "hot-plate.toml", "--out", outs["heat"], "--quiet",
        "--set", "particles.cells=[2, 2, 3]", "--set", "time.end=5", "--set", "output.snapshots=0")
    outs["compact"] = tmp / "compact"
    run("run", ROOT / "cases" / "copper-compact.toml", "--out", outs["compact"], "--quiet",
        "--set", "time.end=5", "--set", "output.snapshots=0", "--set", "output.conductivity_at=[]",
        "--set", "output.correction_histogram_at=[1.0]")
    outs["pair"] = tmp / "pair"
    run("run", ROOT / "cases" / "pair-copper.toml", "--out", outs["pair"], "--quiet", "--set", "pair.end_time=10")
    outs["explicit"] = tmp / "explicit"
    run("run", ROOT / "cases" / "luding-sintering-time.toml", "--out", outs["explicit"], "--quiet",
        "--set", "protocol.t_sinter=[0.002]", "--set", "sample.particles=40")
    outs["generate"] = tmp / "generate"
    run("generate", ROOT / "cases" / "green-copper.toml", "--out", outs["generate"],
        "--set", "packing.particles=60")
    return outs


@needs_bin
def test_every_csv_reads_with_plain_pandas(tmp_path):
    import pandas as pd

    outs = short_runs(tmp_path)
    seen = []
    for kind, out in outs.items():
        csvs = sorted(out.glob("*.csv"))
        assert csvs, f"{kind}: no CSV written"
        for path in csvs:
            first = path.read_text().splitlines()[0]
            assert not first.startswith("#"), f"{path.name}: comment before the header"
            df = pd.read_csv(path)
            assert len(df) > 0, path.name
            assert all(re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", c) for c in df.columns), (path.name, list(df.columns))
            for col in df.columns:
                if col in COUNT_COLUMNS:
                    assert pd.api.types.is_integer_dtype(df[col]), f"{path.name}: {col} is {df[col].dtype}"
                elif col not in ("axis", "interior", "case", "method", "failure"):
                    assert pd.api.types.is_numeric_dtype(df[col]), f"{path.name}: {col} is {df[col].dtype}"
            seen.append(f"{kind}/{path.name}")
    print("read:", ", ".join(seen))
    assert any(s.startswith("compact/dl_bar") for s in seen) and "generate/packing.csv" in seen
