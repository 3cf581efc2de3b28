"""sinterdem.study and sinterdem.calibrate: the files they write, read back as DataFrames."""

import json

import numpy as np
import pandas as pd
import pytest

import sinterdem
from conftest import CASES, cli_commands, run_cli, strip_timing

TEMPS = [1233.0, 1263.0, 1293.0]


def test_study_from_a_dict_returns_one_row_per_run(tmp_path):
    spec = {
        "title": "pair temperatures",
        "base": str(CASES / "pair-copper.toml"),
        "overrides": ["pair.end_time=200.0", "output.plot=false"],
        "parameters": [{"key": "temperature.constant", "name": "temperature_K", "values": TEMPS}],
        "collect": {"summary": ["neck_ratio", "shrinkage"]},
    }
    df = sinterdem.study(spec, tmp_path / "study", jobs=2, progress=False)
    assert isinstance(df, pd.DataFrame)
    assert len(df) == 3
    assert sorted(df["temperature_K"].tolist()) == TEMPS
    # each row is the run a user starts alone
    for t in TEMPS:
        case = sinterdem.Case.load(CASES / "pair-copper.toml")
        case["pair.end_time"] = 200.0
        case["output.plot"] = False
        case["temperature.constant"] = t
        r = sinterdem.run(case, progress=False)
        row = df[df["temperature_K"] == t]
        assert row["neck_ratio"].iloc[0] == r.summary["neck_ratio"]
        assert row["shrinkage"].iloc[0] == r.summary["shrinkage"]
    assert np.all(np.diff(df.sort_values("temperature_K")["neck_ratio"].to_numpy()) > 0)


def test_study_file_equals_the_command_line(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(
        f'title = "t"\nbase = "{CASES / "pair-copper.toml"}"\noverrides = ["pair.end_time=50.0"]\n'
        '[[parameters]]\nkey = "pair.radius"\nvalues = [2.0e-5, 3.0e-5]\n[collect]\nsummary = ["neck_ratio"]\n'
    )
    df = sinterdem.study(spec, tmp_path / "py", progress=False)
    assert len(df) == 2
    name, cmd = cli_commands()[-1]
    run_cli(cmd, "study", str(spec), "--out", str(tmp_path / name), "-q")
    cli = sinterdem.read_csv(tmp_path / name / "study.csv")
    assert list(cli.columns) == list(df.columns)
    assert cli["neck_ratio"].tolist() == df["neck_ratio"].tolist()


CALIB_SETS = ["optimiser.swarm_size=4", "optimiser.swarm_iterations=1", "optimiser.local_iterations=2"]


def test_calibrate_reads_back_parameters_sigma_correlation_material(tmp_path):
    f = CASES / "calibration" / "titanium-synthetic.toml"
    res = sinterdem.calibrate(f, tmp_path / "py", overrides=CALIB_SETS)
    keys = ["beta.d0_gb", "beta.q_gb", "beta.d0_surface", "beta.q_surface"]
    assert list(res.parameters.index) == keys
    assert list(res.correlation.index) == keys and list(res.correlation.columns) == keys
    assert np.allclose(np.diag(res.correlation.to_numpy()), 1.0)
    assert list(res.sigma.index) == keys and "sigma" in res.sigma.columns
    assert res.material["name"] == "titanium-ivannikov2022"
    assert "phases" in res.material
    name, cmd = cli_commands()[-1]
    sets = [a for s in CALIB_SETS for a in ("--set", s)]
    run_cli(cmd, "calibrate", str(f), "--out", str(tmp_path / name), "-q", *sets)
    cli = json.loads((tmp_path / name / "calibration.json").read_text())
    for k in keys:
        assert res.parameters.loc[k, "value"] == cli["parameters"][k]["value"]
        assert res.sigma.loc[k, "sigma"] == cli["parameters"][k]["sigma"]
    assert res.chi2 == cli["chi2"]
    # the fitted material goes straight into a pair case
    mat = dict(res.material)
    case = sinterdem.Case.from_dict({
        "kind": "pair",
        "materials": [mat],
        "pair": {"material": mat["name"], "radius": 2.5e-5, "end_time": 60.0},
        "temperature": {"constant": 1273.0},
    })
    assert case.check() == "pair case"
