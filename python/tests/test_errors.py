"""Each exception class from a matching bad input, with the command line's text and exit code."""

import pytest

import sinterdem
from conftest import CASES, cli_commands, run_cli


def test_classes_form_one_hierarchy():
    for c in (sinterdem.ConfigError, sinterdem.ModelError, sinterdem.SolveError, sinterdem.IoError):
        assert issubclass(c, sinterdem.Error) and issubclass(c, Exception)
    assert [c.exit_code for c in (sinterdem.ConfigError, sinterdem.ModelError, sinterdem.SolveError, sinterdem.IoError)] == [1, 3, 4, 5]


def test_out_of_range_from_a_file_has_key_value_allowed_file_line(tmp_path):
    text = (CASES / "pair-copper.toml").read_text().replace("radius = 25.0e-6", "radius = -25.0e-6")
    f = tmp_path / "bad.toml"
    f.write_text(text)
    case = sinterdem.Case.load(f)
    with pytest.raises(sinterdem.ConfigError) as ei:
        sinterdem.run(case, out=tmp_path / "out", progress=False)
    e = ei.value
    assert e.key == "pair.radius"
    assert e.value == -25.0e-6
    assert e.allowed == "[1e-8, 0.01]" and e.unit == "m"
    assert e.file == str(f)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith("radius ="))
    assert e.line == line
    for name, cmd in cli_commands():
        p = run_cli(cmd, "run", str(f), "--out", str(tmp_path / name), "-q", check=False)
        assert p.returncode == 1, name
        assert p.stderr.strip().splitlines()[-1] == f"error: {e}", name


def test_an_override_out_of_range_says_it_was_set(tmp_path):
    case = sinterdem.Case.load(CASES / "pair-copper.toml")
    with pytest.raises(sinterdem.ConfigError) as ei:
        case["solver.rtol"] = -1.0
        case.check()
    e = ei.value
    assert e.key == "solver.rtol" and e.value == -1.0 and e.file is None
    assert "set by --set solver.rtol=-1.0" in str(e)
    assert case.overrides == [] or case.overrides == ["solver.rtol=-1.0"]


def test_unknown_key_and_syntax_error():
    case = sinterdem.Case.from_dict({"kind": "pair", "pair": {"material": "copper", "radius": 1e-5, "radiuss": 2}})
    with pytest.raises(sinterdem.ConfigError, match="radiuss"):
        case.check()
    with pytest.raises(sinterdem.ConfigError) as ei:
        sinterdem.Case.from_toml("kind = \"pair\"\n[pair\nradius = 1")
    assert ei.value.line == 2
    with pytest.raises(sinterdem.ConfigError, match="kind"):
        sinterdem.Case.from_dict({"kind": "nonsense"}).check()


def test_model_error_from_a_tiny_second_particle(tmp_path):
    case = sinterdem.Case.load(CASES / "pair-copper.toml")
    case["pair.end_time"] = 10.0
    case["pair.radius_b"] = 1e-7
    with pytest.raises(sinterdem.ModelError) as ei:
        sinterdem.run(case, out=tmp_path / "py", progress=False)
    for name, cmd in cli_commands():
        p = run_cli(cmd, "run", str(CASES / "pair-copper.toml"), "--out", str(tmp_path / name), "-q",
                    "--set", "pair.end_time=10.0", "--set", "pair.radius_b=1e-07", check=False)
        assert p.returncode == 3, (name, p.stderr)
        assert p.stderr.strip().splitlines()[-1] == f"error: {ei.value}", name


def test_io_error_from_a_missing_file(tmp_path):
    with pytest.raises(sinterdem.IoError) as ei:
        sinterdem.Case.load(tmp_path / "missing.toml")
    assert "missing.toml" in str(ei.value)
    for name, cmd in cli_commands():
        p = run_cli(cmd, "check", str(tmp_path / "missing.toml"), check=False)
        assert p.returncode == 5, name
        assert p.stderr.strip().splitlines()[-1] == f"error: {ei.value}", name


def test_type_error_for_values_toml_cannot_hold():
    case = sinterdem.Case.load(CASES / "pair-copper.toml")
    with pytest.raises(TypeError):
        case["pair.radius"] = None


def test_solve_error_from_an_exhausted_step_budget(tmp_path):
    case = sinterdem.Case.load(CASES / "green-copper.toml")
    case["packing.protocol.max_steps"] = 100
    with pytest.raises(sinterdem.SolveError, match="step budget") as ei:
        sinterdem.run(case, out=tmp_path / "py", progress=False)
    for name, cmd in cli_commands():
        p = run_cli(cmd, "generate", str(CASES / "green-copper.toml"), "--out", str(tmp_path / name), "-q",
                    "--set", "packing.protocol.max_steps=100", check=False)
        assert p.returncode == 4, name
        assert p.stderr.strip().splitlines()[-1] == f"error: {ei.value}", name


def test_usage_error_exits_2():
    for name, cmd in cli_commands():
        assert run_cli(cmd, "run", "--no-such-flag", check=False).returncode == 2, name
