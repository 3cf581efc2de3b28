"""Every script in examples/ runs (shortened; headless matplotlib, or a printed reason without it)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

EXAMPLES = sorted(p for p in (REPO / "examples").glob("*.py") if not p.name.startswith("_"))


def test_there_are_examples():
    assert {p.name for p in EXAMPLES} >= {"copper_compact.py", "temperature_field.py", "temperature_sweep.py",
                                           "hold_until_density.py", "calibrated_compact.py"}


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(script, tmp_path):
    env = dict(os.environ, SINTERDEM_EXAMPLES_OUT=str(tmp_path), MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600)
    assert p.returncode == 0, f"{script.name} exited {p.returncode}\n{p.stdout}\n{p.stderr}"
    try:
        import matplotlib  # noqa: F401
        has_mpl = True
    except ImportError:
        has_mpl = False
    if "pyplot()" in script.read_text():
        if has_mpl:
            assert "plot: " in p.stdout and any(Path(tmp_path).glob("*.png")), p.stdout
        else:
            assert "plot skipped: matplotlib is not installed" in p.stdout, p.stdout
    if script.name == "hold_until_density.py":
        assert "furnace to 900 K" in p.stdout, p.stdout
