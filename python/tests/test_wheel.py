"""The wheel of `maturin build --release`, installed into a fresh venv with cargo off PATH, is a
complete installation: the `sinterdem` command and the module run a pair case.

scripts/test-all.sh builds the wheel once and passes it as SINTERDEM_WHEEL."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import CASES, read_summary, strip_timing

WHEEL = os.environ.get("SINTERDEM_WHEEL")


@pytest.mark.skipif(not WHEEL, reason="SINTERDEM_WHEEL not set (scripts/test-all.sh builds the wheel and sets it)")
def test_wheel_runs_a_pair_case_without_cargo(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    py = venv / "bin" / "python"
    # numpy is the wheel's only dependency; a pair run's summary does not need it, so the
    # install works offline (--no-deps) and proves the extension needs nothing else
    subprocess.run([str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", WHEEL], check=True)
    # PATH without any directory that holds cargo or rustc
    dirs = [d for d in os.environ.get("PATH", "").split(os.pathsep)
            if d and not (Path(d) / "cargo").exists() and not (Path(d) / "rustc").exists()]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CARGO", "RUSTUP"))}
    env["PATH"] = os.pathsep.join([str(venv / "bin"), *dirs])
    assert shutil.which("cargo", path=env["PATH"]) is None
    out_cli = tmp_path / "cli"
    p = subprocess.run(["sinterdem", "run", str(CASES / "pair-copper.toml"), "--out", str(out_cli), "-q",
                        "--set", "pair.end_time=600.0"], env=env, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert shutil.which("sinterdem", path=env["PATH"]) == str(venv / "bin" / "sinterdem")
    out_py = tmp_path / "py"
    code = ("import sinterdem, json, sys; c = sinterdem.Case.load(sys.argv[1]); c['pair.end_time'] = 600.0; "
            "r = sinterdem.run(c, out=sys.argv[2], progress=False); print(json.dumps(r.summary))")
    p = subprocess.run([str(py), "-c", code, str(CASES / "pair-copper.toml"), str(out_py)], env=env,
                       capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    summary = json.loads(p.stdout)
    assert 0.2 < summary["neck_ratio"] < 0.404
    assert strip_timing(summary) == strip_timing(read_summary(out_cli))
