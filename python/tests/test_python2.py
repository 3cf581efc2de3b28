"""Python conventions of issue 39 and the safety items of issue 38: callbacks (truthiness,
every_s), warnings and logging, validation at assignment, the conductivity/neck/materials/
generate bindings against the command line, state in memory, model errors from step(),
threads, nesting, a Simulation from another thread, one Ctrl-C per call."""

import json
import logging
import math
import threading
import warnings

import numpy as np
import pytest

import sinterdem
from conftest import CASES, cli_commands, run_cli

COPPER = {"time.end": 0.5, "output.snapshots": 0, "output.checkpoint_every": 0, "output.conductivity_at": []}


def copper(**extra):
    c = sinterdem.Case.load(CASES / "copper-compact.toml")
    for k, v in {**COPPER, **extra}.items():
        c[k] = v
    return c


def small_heat(**extra):
    """The hot plate on 2 x 2 x 2 cells for 20 s (a few ms of computing)."""
    c = sinterdem.Case.load(CASES / "hot-plate.toml")
    for k, v in {"particles.cells": [2, 2, 2], "time.end": 20.0, "output.snapshots": 0, **extra}.items():
        c[k] = v
    return c


# -- 1. callbacks ------------------------------------------------------------------------------

def test_a_numpy_false_stops_after_the_first_call(tmp_path):
    calls = []

    def cb(s):
        calls.append(s.steps)
        return np.False_

    res = sinterdem.Simulation(copper(), out=tmp_path).run(callback=cb)
    assert calls == [0]
    assert res.summary["completed"] is False and res.summary["stop_reason"] == "stopped by the callback"


def test_none_goes_on_and_every_s_calls_at_each_multiple_of_simulated_time(tmp_path):
    every_s = 5.0
    times = []
    res = sinterdem.Simulation(small_heat(), out=tmp_path).run(callback=lambda s: times.append(s.time), every_s=every_s)
    assert res.summary.get("completed", True) is True  # None (no return) goes on
    assert times[0] == 0.0 and times[-1] == pytest.approx(20.0)
    # one call at the first step reaching each multiple of every_s: the periods are consecutive
    periods = [math.floor(t / every_s + 1e-12) for t in times]
    assert periods == sorted(set(periods)) and periods == list(range(len(periods)))
    steps_total = res.summary["steps"]
    assert len(times) < steps_total + 1  # fewer calls than steps (dt = 1 s)
    with pytest.raises(sinterdem.ConfigError) as e:
        sinterdem.Simulation(small_heat(), out=tmp_path / "b").run(callback=print, every_s=-1.0)
    assert (e.value.key, e.value.value, e.value.unit) == ("every_s", -1.0, "s")


# -- 2. warnings and logging ---------------------------------------------------------------------

def test_a_warning_of_the_cli_is_a_sinterdem_warning_and_the_log_goes_to_logging(tmp_path, caplog):
    # 25 K for the initial temperature (°C written for K): the CLI warns, a heat run goes on
    case = small_heat(**{"particles.initial_temperature": 25.0, "time.end": 2.0})
    with caplog.at_level(logging.INFO, logger="sinterdem"):
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            res = sinterdem.run(case, out=tmp_path / "py", progress=False)
    ours = [str(x.message) for x in w if issubclass(x.category, sinterdem.SinterdemWarning)]
    assert ours and len(ours) == len(set(ours)), ours
    assert any("implausibly low" in m for m in ours)
    assert all(x.filename == __file__ for x in w if issubclass(x.category, sinterdem.SinterdemWarning))
    assert set(ours) == set(res.warnings)
    assert any(r.levelno == logging.INFO for r in caplog.records)  # the run's log lines
    for name, cmd in cli_commands():
        (tmp_path / name).mkdir()
        toml = tmp_path / name / "case.toml"
        toml.write_text(case.to_toml())
        p = run_cli(cmd, "run", str(toml), "--out", str(tmp_path / name / "out"))
        cli = [ln[len("warning: "):] for ln in p.stderr.splitlines() if ln.startswith("warning: ")]
        assert set(cli) == set(ours), name


# -- 3. validation at assignment -----------------------------------------------------------------

def test_assignment_validates_at_once_with_every_field():
    case = sinterdem.Case.load(CASES / "pair-copper.toml")
    with pytest.raises(sinterdem.ConfigError) as e:
        case["pair.radius"] = -1.0
    assert (e.value.key, e.value.value, e.value.unit) == ("pair.radius", -1.0, "m")
    assert e.value.allowed == "[1e-8, 0.01]"
    with pytest.raises(sinterdem.ConfigError) as e:
        case["no.such.key"] = 1
    assert (e.value.key, e.value.value) == ("no.such.key", 1)
    assert e.value.allowed and e.value.unit is not None
    with pytest.raises(sinterdem.ConfigError) as e:
        case["solver.method"] = "euler"
    assert e.value.key == "solver.method" and e.value.value == "euler" and "dopri5" in e.value.allowed
    assert case.overrides == []  # refused assignments are not kept
    case["pair.radius"] = 30e-6
    assert case["pair.radius"] == 30e-6


# -- 4. the bindings against the command line ------------------------------------------------------

def test_conductivity_is_the_cli_tensor_bit_for_bit(tmp_path):
    path = CASES / "conductivity" / "periodic-random.toml"
    k = sinterdem.conductivity(path)
    assert k.tensor.shape == (3, 3) and k.tensor.dtype == np.float64
    for name, cmd in cli_commands():
        cli = json.loads(run_cli(cmd, "conductivity", str(path)).stdout)
        assert k.fields == cli, name
        assert np.array_equal(k.tensor, np.array(cli["kappa_eff_W_per_mK"])), name
    assert "Conductivity(" in repr(k)
    with pytest.raises(sinterdem.ConfigError, match="heat case"):
        sinterdem.conductivity(CASES / "copper-compact.toml")


def test_neck_and_materials_as_the_cli(tmp_path):
    n = sinterdem.neck(r1=25e-6, r2=20e-6, overlap=1e-6, kappa=400.0)
    for name, cmd in cli_commands():
        cli = json.loads(run_cli(cmd, "neck", "--r1", "25e-6", "--r2", "20e-6", "--overlap", "1e-6", "--kappa", "400").stdout)
        assert n.fields == cli, name
    # two equal spheres: Coble's a0 = √(2 r h) (docs/heat-model.md (H13)) lies above the
    # volume-conserving neck, which lies above the intersection circle r_c = √(r h − h²/4)
    r, h = 1e-5, 1e-8
    m = sinterdem.neck(r1=r, r2=r, overlap=h, kappa=1.0)
    assert m.a_coble == pytest.approx(math.sqrt(2 * r * h), rel=1e-12)
    assert math.sqrt(r * h - h * h / 4) < m.a < m.a_coble
    with pytest.raises(sinterdem.ConfigError) as e:
        sinterdem.neck(r1=-1.0, r2=1e-5, overlap=0.0, kappa=1.0)
    assert (e.value.key, e.value.unit) == ("--r1", "m")
    mats = sinterdem.materials()
    names = list(mats["name"])
    for name, cmd in cli_commands():
        lines = run_cli(cmd, "materials").stdout.splitlines()
        assert names == [ln.split(":")[0] for ln in lines if ln.strip()], name
    assert "copper" in names and (mats["melting_temperature_K"] > mats["calibrated_max_temperature_K"]).all()


def test_generate_returns_the_packing(tmp_path):
    case = sinterdem.Case.load(CASES / "green-copper.toml")
    case["packing.particles"] = 60
    res = sinterdem.generate(case, out=tmp_path / "g", progress=False)
    pk = res.packing
    assert len(pk) == res.summary["particles"] == 60
    assert (pk[[c for c in pk.columns if c.startswith("r")][0]] > 0).all()
    assert "GenerateResult(" in repr(res)
    with pytest.raises(sinterdem.ConfigError):
        sinterdem.generate(small_heat(), out=tmp_path / "h")


# -- 6. state in memory --------------------------------------------------------------------------

def test_series_shrinkage_and_particles_frame_in_memory(tmp_path):
    sim = sinterdem.Simulation(copper(), out=tmp_path)
    sim.advance(to=0.2)
    s = sim.series
    assert s["time_s"].iloc[-1] == pytest.approx(sim.time) or s["time_s"].iloc[-1] <= sim.time
    sh = sim.shrinkage
    assert sh.shape == (3,) and np.all(np.isfinite(sh))
    last = s.iloc[-1]
    if last["time_s"] == sim.time:
        assert np.array_equal(sh, [last["shrinkage_x"], last["shrinkage_y"], last["shrinkage_z"]])
        assert sim.relative_density == last["relative_density"]
    f = sim.particles_frame()
    assert len(f) == len(sim.particles["ids"]) and {"x_m", "y_m", "z_m", "radius_m"} <= set(f.columns)
    assert s["step"].dtype.kind == "i" if "step" in s else True
    res = sim.finish()
    with pytest.raises(sinterdem.Error, match=r"res\.particles\(-1\)"):
        sim.particles
    assert "RunResult(" in repr(res)


# -- 7. safety (issue 38) ------------------------------------------------------------------------

def test_self_referential_and_deep_values_are_config_errors():
    d = {}
    d["a"] = d
    with pytest.raises(sinterdem.ConfigError) as e:
        sinterdem.Case.from_dict(d)
    assert e.value.unit == "nesting levels"
    deep = []
    cur = deep
    for _ in range(100_000):
        nxt = []
        cur.append(nxt)
        cur = nxt
    case = sinterdem.Case.load(CASES / "pair-copper.toml")
    with pytest.raises(sinterdem.ConfigError):
        case["pair.radius"] = deep


def test_simulation_from_another_thread_raises_a_sinterdem_error(tmp_path):
    sim = sinterdem.Simulation(small_heat(), out=tmp_path)
    caught = []

    def other():
        try:
            sim.step()
        except BaseException as e:  # noqa: BLE001 - what reaches the user
            caught.append(e)

    t = threading.Thread(target=other)
    t.start()
    t.join()
    assert len(caught) == 1 and isinstance(caught[0], sinterdem.Error), caught
    assert sim.step() and sim.finish()


def test_threads_and_jobs_bounded_as_the_cli(tmp_path):
    import os
    for bad in (0, 10 ** 6, -1, 10 ** 30):  # -1 and 10**30 were pyo3 OverflowErrors
        with pytest.raises(sinterdem.ConfigError) as e:
            sinterdem.run(small_heat(), progress=False, threads=bad)
        assert e.value.key == "threads" and e.value.value == float(bad)
        with pytest.raises(sinterdem.ConfigError) as e:
            sinterdem.study(CASES / "studies" / "does-not-matter.toml", out=os.devnull + "-x", jobs=bad)
        assert e.value.key == "jobs"
    # the same bound as the command line's --threads (4 per available core, at least 16; it was
    # the core count in Python): 16 threads always run, and the refusal names the CLI's range
    res = sinterdem.run(small_heat(), progress=False, threads=16)
    assert res.summary["final_time_s"] == 20.0 and res.summary.get("completed", True) is True
    with pytest.raises(sinterdem.ConfigError) as e:
        sinterdem.run(small_heat(), progress=False, threads=10 ** 6)
    for _, cmd in cli_commands():
        p = run_cli(cmd, "-q", "run", str(CASES / "hot-plate.toml"), "--threads", "1000000", "--out", str(tmp_path / "cli"), check=False)
        assert p.returncode == 1 and e.value.allowed in p.stderr, (e.value.allowed, p.stderr)
    assert "4 per available core" in e.value.allowed


# a 10:1 copper pair as a compact: the small sphere is absorbed, the 7-DOF model leaves its
# domain after some hundred seconds (tests/compact.rs model_error_stops_the_run_with_a_summary)
TEN_TO_ONE = """kind = "compact"
[time]
end = 5000.0
dt = 1.0e-6
dt_max = 10.0
[output]
snapshots = 0
vtu = false
hdf5 = false
[[materials]]
name = "copper"
preset = "copper"
[particles]
source = "file"
file = "pair.csv"
[thermal]
mode = "isothermal"
furnace = { profile = { constant = 1293.0 } }
"""


def test_a_model_error_is_raised_by_the_step_that_met_it(tmp_path):
    (tmp_path / "pair.csv").write_text("x,y,z,r\n0,0,0,25e-6\n27.5e-6,0,0,2.5e-6\n")
    sim = sinterdem.Simulation(sinterdem.Case.from_toml(TEN_TO_ONE, base_dir=tmp_path), out=tmp_path / "out")
    steps = 0
    with pytest.raises(sinterdem.ModelError) as e:
        while sim.step():
            steps += 1
    assert sim.done and e.value.out == tmp_path / "out"
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["completed"] is False and "model error" in s["stop_reason"]
    assert 10.0 < s["final_time_s"] < 5000.0
    # the state the run reached stays readable after the error (was None: issue 39)
    assert sim.time == s["final_time_s"] and sim.end == 5000.0
    assert sim.steps == s["steps"]
    rho = sim.relative_density
    assert rho is not None and 0.0 < rho <= 1.0
    assert sim.shrinkage is not None and len(sim.shrinkage) == 3
    with pytest.raises(sinterdem.ModelError):
        sim.finish()  # the same error again, no result


CTRL_C = """
import sys, threading, sinterdem
def case(end):
    c = sinterdem.Case.load(sys.argv[1])
    for k, v in {"time.end": end, "output.checkpoint_every": 0, "output.conductivity_at": [], "output.snapshots": 0}.items():
        c[k] = v
    return c
res = {}
def worker():
    try:
        r = sinterdem.run(case(1.5), out=sys.argv[2], progress=False)
        res["A"] = (r.summary["completed"], r.summary.get("stop_reason"))
    except BaseException as e:
        res["A"] = repr(e)
t = threading.Thread(target=worker)
t.start()
print("started", flush=True)
try:
    sinterdem.run(case(5000.0), out=sys.argv[3], progress=False)
    print("B finished", flush=True)
except KeyboardInterrupt:
    print("B interrupted", flush=True)
t.join()
print("A:", res["A"], flush=True)
"""


def test_one_ctrl_c_stops_the_call_that_received_it_only(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    from conftest import REPO
    a, b = tmp_path / "a", tmp_path / "b"
    p = subprocess.Popen([sys.executable, "-c", CTRL_C, str(CASES / "copper-compact.toml"), str(a), str(b)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    assert p.stdout.readline().strip() == "started"
    deadline = time.time() + 120
    while time.time() < deadline:  # both runs stepping, the worker's not finished
        rows = [len((d / "series.csv").read_text().splitlines()) if (d / "series.csv").exists() else 0 for d in (a, b)]
        if min(rows) > 3:
            break
        time.sleep(0.02)
    assert not (a / "summary.json").exists(), "the worker's run ended before the signal: make it longer"
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=180)
    assert "B interrupted" in stdout and "A: (True, " in stdout, (stdout, stderr)


def test_a_rust_panic_reaches_python_as_one_sinterdem_error(tmp_path, capfd):
    # rve.interval = 1e-15 (inside its documented range) panicked in the branch runs (issue 38
    # item 6); whether it panics or is refused, a user gets a sinterdem.Error, no Rust text
    c = sinterdem.Case.load(CASES / "rve-copper.toml")
    for k, v in {"rve.at": [2.0], "time.end": 5.0, "output.conductivity_at": [0.0], "output.snapshots": 0}.items():
        c[k] = v
    try:
        c["rve.interval"] = 1e-15
        sinterdem.rve(c, out=tmp_path / "rve", progress=False)
    except sinterdem.Error as e:
        assert "\n" not in str(e) and "panicked" not in str(e)
    err = capfd.readouterr().err
    assert "panicked" not in err and "RUST_BACKTRACE" not in err, err


def test_the_hdf5_flag_says_what_the_build_writes(tmp_path):
    assert isinstance(sinterdem.HDF5, bool)
    sinterdem.run(small_heat(**{"time.end": 2.0, "output.snapshots": 2, "output.hdf5": True}), out=tmp_path, progress=False)
    assert bool(list(tmp_path.glob("*.h5"))) == sinterdem.HDF5


def test_run_into_the_case_folder_keeps_what_it_did_not_write(tmp_path):
    """Issue 38 item 1 from Python: ``sinterdem.run(case, out=DIR)`` replaces an earlier run in DIR
    as ``--force`` does, and removes exactly what that run wrote (``outputs.json``): the case, its
    packing, the user's notes, settings and a folder of theirs with a ``summary.json`` stay."""
    r, s = 32e-6, 2.0 * 32e-6 * 0.95
    rows = ["x,y,z,r"] + [f"{(i % 3) * s:e},{((i // 3) % 3) * s:e},{(i // 9) * s:e},{r:e}" for i in range(27)]
    (tmp_path / "pack.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "case.toml").write_text(
        '[time]\nend = 5.0\ndt = 1.0\n[[materials]]\nname = "titanium"\npreset = "titanium"\n[particles]\nsource = "file"\n'
        'file = "pack.csv"\ninitial_temperature = 293.15\n[thermal]\nmode = "network"\nconductance = "linear"\n'
        '[[thermal.fixed]]\nregion = { face = "z-" }\nprofile = { constant = 400.0 }\n')
    (tmp_path / "notes.txt").write_text("my notes")
    (tmp_path / "settings.json").write_text('{"mine": 1}')
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "summary.json").write_text('{"mine": true}')
    user = {p.relative_to(tmp_path): p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    for end in (5.0, 4.0):
        case = sinterdem.Case.load(tmp_path / "case.toml")
        case["time.end"] = end
        res = sinterdem.run(case, out=tmp_path, progress=False)
        assert res.summary["final_time_s"] == end
        for rel, data in user.items():
            assert (tmp_path / rel).read_bytes() == data, f"{rel} changed or removed"
    listed = json.loads((tmp_path / "outputs.json").read_text())["files"]
    assert "summary.json" in listed and "pack.csv" not in listed and "notes.txt" not in listed


def test_a_whole_number_beyond_64_bits_is_the_keys_config_error():
    """A Python int outside TOML's 64 bits was pyo3's bare OverflowError ("Python int too large to
    convert to C long", no key); found by python/tests/test_fuzz.py."""
    case = small_heat()
    for big in (2 ** 63, -(2 ** 63) - 1):
        with pytest.raises(sinterdem.ConfigError) as e:
            case["time.end"] = big
        assert e.value.key == "time.end" and "64-bit" in str(e.value) and e.value.value == float(big)
        with pytest.raises(sinterdem.ConfigError) as e:
            sinterdem.Case.from_dict({**case.to_dict(), "time": {"end": big, "dt": 1.0}})
        assert e.value.key == "time.end"


def test_electrical_conductivity_is_the_same_network(tmp_path):
    """`conductivity.quantity = "electrical"` from Python (issue 42): the same network with
    σ = 1/ρ_e(T) in place of κ (docs/heat-model.md), so σ_eff/σ equals κ_eff/κ of the thermal run
    on the bundled periodic case to round-off, and the fields are the command's bit for bit."""
    path = CASES / "conductivity" / "periodic-random.toml"
    case = sinterdem.Case.load(path)
    case["conductivity.quantity"] = "electrical"
    el = sinterdem.conductivity(case)
    th = sinterdem.conductivity(path)
    assert el.quantity == "electrical" and th.quantity == "thermal"
    assert np.allclose(el.relative, th.relative, rtol=1e-12, atol=1e-15)
    assert el.tensor[0, 0] == pytest.approx(el.relative[0, 0] * el.sigma_material, rel=1e-12)
    assert el.kappa_material is None and "sigma_eff/sigma" in repr(el)
    for name, cmd in cli_commands():
        cli = json.loads(run_cli(cmd, "conductivity", str(path), "--set", 'conductivity.quantity="electrical"').stdout)
        assert el.fields == cli, name
