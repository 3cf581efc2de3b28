"""The stepping API (sinterdem.Simulation) against sinterdem.run, bit for bit; state arrays;
callbacks; the furnace and stress setters against the same change written as a table;
Ctrl-C in a child interpreter; res.times / particles / contacts."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import sinterdem
from conftest import CASES, REPO, read_summary, strip_timing

# the flagship case, shortened: 0.5 s of sintering at 1293 K, a few hundred steps
COPPER = {"time.end": 0.5, "output.snapshots": 3, "output.checkpoint_every": 0, "output.conductivity_at": []}
HEAT = {"time.end": 20.0, "output.snapshots": 3}


def copper(**extra):
    c = sinterdem.Case.load(CASES / "copper-compact.toml")
    for k, v in {**COPPER, **extra}.items():
        c[k] = v
    return c


def heat(**extra):
    c = sinterdem.Case.load(CASES / "hot-plate.toml")
    for k, v in {**HEAT, **extra}.items():
        c[k] = v
    return c


def same_run(a, b):
    """Same series.csv (bytes) and summary.json (apart from wall times)."""
    assert (a / "series.csv").read_bytes() == (b / "series.csv").read_bytes()
    assert strip_timing(read_summary(a)) == strip_timing(read_summary(b))


@pytest.mark.parametrize("make", [copper, heat], ids=["copper-compact", "hot-plate"])
def test_stepping_equals_run_bit_for_bit(tmp_path, make):
    res = sinterdem.run(make(), out=tmp_path / "run", progress=False)
    sim = sinterdem.Simulation(make(), out=tmp_path / "step")
    n = 0
    while sim.step():
        n += 1
    assert sim.done and n + 1 == sim.steps == res.summary["steps"]
    stepped = sim.finish()
    same_run(res.out, stepped.out)
    assert stepped.summary.get("completed", True) is True
    # advance() to a time, then the rest in one call: the same steps again
    sim = sinterdem.Simulation(make(), out=tmp_path / "advance")
    sim.advance(to=0.4 * sim.end)
    assert 0.4 * sim.end <= sim.time < sim.end
    sim.run()
    same_run(res.out, sim.result.out)
    # the snapshots: times, and the last one equals the state the run ended in
    assert len(res.times) == 3 and res.times[0] == 0.0 and res.times[-1] == pytest.approx(sim.end)


def test_state_arrays_shapes_dtypes_units(tmp_path):
    sim = sinterdem.Simulation(copper(), out=tmp_path)
    p0 = sim.particles
    n = len(p0["ids"])
    assert n == 805  # cases/data/green-copper.csv
    assert p0["positions"].shape == (n, 3) and p0["positions"].dtype == np.float64
    assert p0["displacements"].shape == (n, 3) and not p0["displacements"].any()
    assert p0["ids"].dtype == np.int64 and (p0["ids"] == np.arange(n)).all()
    r = p0["radii"]
    assert r.shape == (n,) and 1e-6 < r.min() <= r.max() < 1e-3  # m: copper powder, tens of µm
    assert np.all(p0["temperatures"] == 1293.0)  # K: isothermal at the furnace
    c0 = sim.contacts
    m = len(c0["neck_radii"])
    assert c0["pairs"].shape == (m, 2) and c0["pairs"].dtype == np.int64 and m > n  # a green compact
    assert (c0["pairs"] >= 0).all() and (c0["pairs"] < n).all()
    assert (c0["neck_radii"] > 0).all() and (c0["neck_radii"] < r.max()).all()
    assert c0["forces"].shape == (m,) and not c0["forces"].any()  # no [load]
    rho0 = sim.relative_density
    res = sim.run()
    last_p, last_c = res.particles(-1), res.contacts(-1)
    # the necks grew and the compact shrank
    assert res.summary["relative_density"] > rho0
    assert np.median(last_c["neck_radii"]) > np.median(c0["neck_radii"])
    # the last snapshot (VTU, read back by sinterdem's reader) is the state at the end
    assert last_p["positions"].shape == (n, 3)
    assert np.abs(last_p["displacements"]).max() > 0
    assert last_c["pairs"].shape[1] == 2


def test_snapshot_reader_matches_the_live_state(tmp_path):
    sim = sinterdem.Simulation(copper(**{"time.end": 0.2, "output.snapshots": 2}), out=tmp_path)
    sim.advance(to=1.0)
    live_p, live_c = sim.particles, sim.contacts
    res = sim.finish()
    snap_p, snap_c = res.particles(-1), res.contacts(-1)
    for k in ("ids", "positions", "radii", "temperatures", "displacements"):
        np.testing.assert_array_equal(snap_p[k], live_p[k], err_msg=k)
    for k in ("pairs", "neck_radii", "forces"):
        np.testing.assert_array_equal(snap_c[k], live_c[k], err_msg=k)
    with pytest.raises(IndexError):
        res.particles(7)


def test_a_callback_stops_the_run(tmp_path):
    sim = sinterdem.Simulation(copper(), out=tmp_path)
    seen = []

    def cb(s):
        seen.append(s.steps)
        return s.steps < 12

    res = sim.run(callback=cb, every=4)
    assert seen == [0, 4, 8, 12]
    assert res.summary["steps"] == 12 and res.summary["completed"] is False
    assert res.summary["stop_reason"] == "stopped by the callback"
    assert res.summary["final_time_s"] < 0.5
    s = res.series
    assert s["time_s"].iloc[-1] == res.summary["final_time_s"]  # the last state has its row


@pytest.mark.parametrize("make,key", [(copper, "thermal.furnace.profile"), (heat, "thermal.furnace.profile")], ids=["compact", "heat"])
def test_set_furnace_temperature_equals_a_profile_table(tmp_path, make, key):
    t0 = make()[key]["constant"]
    sim = sinterdem.Simulation(make(), out=tmp_path / "step")
    sim.advance(to=0.3 * sim.end)
    t1 = sim.time
    sim.set_furnace_temperature(t0 + 60.0)
    stepped = sim.run()
    table = make()
    table[key] = {"table": [[0.0, t0], [t1, t0], [t1, t0 + 60.0]]}
    res = sinterdem.run(table, out=tmp_path / "table", progress=False)
    same_run(res.out, stepped.out)
    # and the change did something: not the run at t0 throughout
    plain = sinterdem.run(make(), out=tmp_path / "plain", progress=False)
    assert strip_timing(plain.summary) != strip_timing(res.summary)


def test_set_applied_stress_equals_a_stress_table(tmp_path):
    def loaded():
        return copper(**{"load": {"mode": "uniaxial", "axis": "z", "stress": 1.0e6}})

    sim = sinterdem.Simulation(loaded(), out=tmp_path / "step")
    sim.advance(to=0.2)
    t1 = sim.time
    sim.set_applied_stress(5.0e6)
    forces = sim.contacts["forces"]
    stepped = sim.run()
    table = copper(**{"load": {"mode": "uniaxial", "axis": "z", "stress_table": [[0.0, 1.0e6], [t1, 1.0e6], [t1, 5.0e6]]}})
    res = sinterdem.run(table, out=tmp_path / "table", progress=False)
    same_run(res.out, stepped.out)
    assert forces.any()
    assert res.summary["load"]["applied_stress_Pa"] == 5.0e6


def test_setters_without_a_furnace_or_load_raise_config_errors(tmp_path):
    sim = sinterdem.Simulation(copper(), out=tmp_path)
    with pytest.raises(sinterdem.ConfigError, match="no applied load"):
        sim.set_applied_stress(1e6)
    with pytest.raises(sinterdem.ConfigError, match="furnace temperature"):
        sim.set_furnace_temperature(-5.0)
    sim.finish()
    with pytest.raises(sinterdem.ConfigError, match="only heat, compact and explicit_sinter"):
        sinterdem.Simulation(CASES / "pair-copper.toml")


def test_finish_early_marks_the_run_incomplete(tmp_path):
    with sinterdem.Simulation(copper(), out=tmp_path) as sim:
        for _ in range(3):
            sim.step()
    s = sim.result.summary
    assert s["completed"] is False and s["stop_reason"] == "stopped by the caller" and s["steps"] == 3


CHILD = textwrap.dedent("""
    import sys, sinterdem
    case = sinterdem.Case.load(sys.argv[1])
    case["time.end"] = 5000.0
    case["output.checkpoint_every"] = 0
    case["output.conductivity_at"] = []
    print("started", flush=True)
    try:
        sinterdem.run(case, out=sys.argv[2], progress=False)
    except KeyboardInterrupt as e:
        print("KeyboardInterrupt:", e, flush=True)
        sys.exit(130)
    print("finished without interrupt", flush=True)
""")


def test_sigint_to_a_child_interpreter_leaves_readable_outputs(tmp_path):
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-c", CHILD, str(CASES / "copper-compact.toml"), str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    assert p.stdout.readline().strip() == "started"
    # wait until the run is stepping (series rows appear), then Ctrl-C
    deadline = time.time() + 120
    while time.time() < deadline:
        f = out / "series.csv"
        if f.exists() and len(f.read_text().splitlines()) > 5:
            break
        time.sleep(0.1)
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 130, (stdout, stderr)
    assert "KeyboardInterrupt" in stdout
    s = read_summary(out)
    assert s["completed"] is False and s["stop_reason"] == "interrupted"
    assert 0 < s["final_time_s"] < 5000.0
    series = sinterdem.read_csv(out / "series.csv")
    assert series["time_s"].iloc[-1] == s["final_time_s"]
    assert (out / "particles.pvd").exists()  # the last state is kept as a snapshot


def test_a_notebook_gets_a_plain_progress_line(tmp_path, monkeypatch, capsys):
    import types

    monkeypatch.setitem(sys.modules, "ipykernel", types.ModuleType("ipykernel"))
    sinterdem.run(copper(), out=tmp_path / "nb", progress=True)
    err = capsys.readouterr().err
    assert "\rsinterdem: t = " in err and " s of 0.5 s (" in err, err[-500:]
    sinterdem.run(copper(), out=tmp_path / "quiet", progress=False)
    assert "sinterdem: t = " not in capsys.readouterr().err


@pytest.mark.parametrize("name,sets", [
    ("hot-plate.toml", ["time.end=5.0", "output.snapshots=2", "output.hdf5=false"]),  # the package has no HDF5
    ("green-copper.toml", ["packing.particles=60"]),
    ("luding-sintering-time.toml", ["protocol.t_prepare=0.003", "protocol.t_heat=0.001", "protocol.t_sinter=[0.001]", "protocol.t_cool=0.001",
                                    "protocol.t_relax=0.001", "compression.max_strain=0.005", "walls.pressures=[5e3]", "sample.particles=40",
                                    "protocol.t0_sinter=0.001"]),
], ids=["heat", "generate", "explicit_sinter"])
def test_every_kind_through_run_equals_the_command_line(tmp_path, name, sets):
    from conftest import cli_commands, run_cli

    case = sinterdem.Case.load(CASES / name)
    for s in sets:
        k, v = s.split("=", 1)
        case[k] = sinterdem._native.parse_toml(f"v = {v}", "<set>")["v"]
    res = sinterdem.run(case, out=tmp_path / "py", progress=False)
    name_, cmd = cli_commands()[-1]
    args = [a for s in sets for a in ("--set", s)]
    run_cli(cmd, "run", str(CASES / name), "--out", str(tmp_path / name_), "-q", *args)
    cli = strip_timing(read_summary(tmp_path / name_))
    py = strip_timing(res.summary)
    for d in (cli, py):
        d.pop("wall_time", None)  # generate's wall time [s]
    assert cli == py
    for f in ("series.csv",):
        if (res.out / f).exists():
            assert (tmp_path / name_ / f).read_bytes() == (res.out / f).read_bytes()
