"""sinterdem's VTU snapshots open in meshio (the reader ParaView users rely on through VTK)."""
import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(os.environ.get("SINTERDEM_BIN", ROOT / "target" / "release" / "sinterdem"))


@pytest.mark.skipif(not BIN.exists(), reason=f"sinterdem binary not built at {BIN}")
def test_heat_run_vtu_reads_back_in_meshio(tmp_path):
    import meshio

    out = tmp_path / "hp"
    subprocess.run(
        [str(BIN), "run", str(ROOT / "cases" / "hot-plate.toml"), "--out", str(out), "--quiet",
         "--set", "particles.cells=[2, 2, 3]", "--set", "time.end=5", "--set", "output.snapshots=2"],
        check=True, capture_output=True,
    )
    summary = json.loads((out / "summary.json").read_text())
    particles = meshio.read(out / "particles_000001.vtu")
    contacts = meshio.read(out / "contacts_000001.vtu")
    n = summary["particles"]
    assert particles.points.shape == (n, 3)
    temp = particles.point_data["temperature_K"]
    assert abs(temp.mean() - summary["mean_temperature_K"]) < 1e-6
    assert abs(temp.max() - summary["max_temperature_K"]) < 1e-6
    lines = contacts.cells_dict["line"]
    assert lines.shape == (summary["contacts"], 2)
    neck = contacts.cell_data["neck_radius_m"][0]
    assert neck.shape == (summary["contacts"],) and (neck > 0).all()
