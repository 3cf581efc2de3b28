"""The notebook gallery (examples/*.ipynb) runs headless: each notebook is executed in memory by
nbclient in a temporary working directory (nothing is written into the tree: the executed
notebook is not saved), its cells' own asserts checking what it shows."""

import time

import pytest

from conftest import REPO

NOTEBOOKS = sorted((REPO / "examples").glob("*.ipynb"))


def test_the_gallery_is_there():
    assert {p.stem for p in NOTEBOOKS} >= {"temperature_sweep", "stepping_callback", "rve_table", "library_powder", "study", "calibration"}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("matplotlib")
    pytest.importorskip("ipykernel")
    monkeypatch.setenv("SINTERDEM_REPO", str(REPO))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.read(path, as_version=4)
    assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code"), f"{path.name} is stored with outputs"
    t0 = time.monotonic()
    nbclient.NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    wall = time.monotonic() - t0
    errors = [o for c in nb.cells for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors, errors
    assert wall < 120, f"{path.name}: {wall:.0f} s"
    assert not list(tmp_path.glob("*.ipynb"))
