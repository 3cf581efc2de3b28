"""The stepping API on an explicit_sinter protocol (sinterdem.Simulation) against sinterdem.run, bit
for bit; the state arrays; a stopping callback; finish() early; the setters it refuses; Ctrl-C in a
child interpreter for pair, generate and explicit_sinter runs (and with threads=n)."""

import math
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import sinterdem
from conftest import CASES, REPO, read_summary, strip_timing

# the bundled Luding case shortened as tests/bundled_cases.rs does: 40 particles, one pressure,
# one sintering time, every stage a few ms (a few thousand explicit steps)
SHORT = {
    "protocol.t_prepare": 0.003, "protocol.t_heat": 0.001, "protocol.t_sinter": [0.001], "protocol.t_cool": 0.001,
    "protocol.t_relax": 0.001, "protocol.t0_sinter": 0.001, "compression.max_strain": 0.005, "walls.pressures": [5e3],
    "sample.particles": 40,
}


def luding(**extra):
    c = sinterdem.Case.load(CASES / "luding-sintering-time.toml")
    for k, v in {**SHORT, **extra}.items():
        c[k] = v
    return c


def outputs(d):
    """The CSV files of an explicit_sinter run (history, compression, forces) by name, as bytes."""
    return {p.name: p.read_bytes() for p in sorted(d.glob("*.csv"))}


def same_run(a, b):
    fa, fb = outputs(a), outputs(b)
    assert sorted(fa) == sorted(fb)
    for name in fa:
        assert fa[name] == fb[name], name
    assert strip_timing(read_summary(a)) == strip_timing(read_summary(b))


def test_stepping_an_explicit_protocol_equals_run_bit_for_bit(tmp_path):
    # two sintering times: a branch is finished in the middle and the trunk goes on
    case = lambda: luding(**{"protocol.t_sinter": [0.001, 0.002]})  # noqa: E731
    res = sinterdem.run(case(), out=tmp_path / "run", progress=False)
    steps = sum(b["steps"] for b in res.summary["branches"])
    assert len(res.summary["branches"]) == 2 and "completed" not in res.summary
    sim = sinterdem.Simulation(case(), out=tmp_path / "step")
    assert sim.stage == ("prepare", 5e3, None) and sim.steps == 0 and sim.time == 0.0
    seen, times = set(), []
    while sim.step():
        seen.add(sim.stage[0])
        times.append(sim.time)
    assert seen == {"prepare", "heat", "sinter", "cool", "compress"}
    # the time of the sample being advanced: it goes back once, when the first branch is finished
    backs = [i for i in range(1, len(times)) if times[i] < times[i - 1]]
    assert len(backs) == 1
    stepped = sim.finish()
    same_run(res.out, stepped.out)
    # the explicit steps of the trunk are counted once: the branches' step counts are the
    # sample's clock (trunk up to the split plus its own), the protocol's count is every step
    assert sim.steps < steps
    # advance() to a time, then the rest in one call: the same steps again
    sim = sinterdem.Simulation(case(), out=tmp_path / "advance")
    sim.advance(to=0.0035)
    assert 0.0035 <= sim.time < 0.0036 and sim.stage[0] == "heat"
    sim.run()
    same_run(res.out, sim.result.out)
    assert sim.end == pytest.approx(0.003 + 0.001 + 0.002 + 0.001 + 0.001 + 0.005 / 5.0)


def test_explicit_state_arrays_shapes_dtypes_units(tmp_path):
    sim = sinterdem.Simulation(luding(), out=tmp_path)
    p0 = sim.particles
    n = 40
    assert p0["positions"].shape == (n, 3) and p0["positions"].dtype == np.float64
    assert p0["ids"].dtype == np.int64 and (p0["ids"] == np.arange(n)).all()
    r0 = p0["radii"]
    assert r0.shape == (n,) and 0.8e-3 * (1 - 1e-12) <= r0.min() and r0.max() <= 1.2e-3 * (1 + 1e-12)  # m: r_0 (1 ± 0.2)
    assert np.all(p0["temperatures"] == 353.15)  # K: temperature_cold
    assert p0["displacements"].shape == (n, 3) and not p0["displacements"].any()
    # the loose start: solid fraction sample.initial_fraction = 0.3 of the box
    assert sim.relative_density == pytest.approx(0.3, rel=1e-12)
    c0 = sim.contacts
    assert c0["pairs"].shape[1] == 2 and c0["pairs"].dtype == np.int64
    sim.advance(to=0.0045)  # compressed by the walls, in the hot sintering stage
    assert sim.stage[0] == "sinter" and sim.stage[2] == 0.001
    p, c = sim.particles, sim.contacts
    assert np.all(p["temperatures"] == 413.15)  # K: temperature_hot
    # Luding's eq. 9 (expansion 1e-4, t_melt = 393.15 K): r = r_ref (1 - α(T_m - T)) / (1 - α(T_m - T_cold))
    alpha, tm = 1e-4, 393.15
    np.testing.assert_allclose(p["radii"], r0 * (1 - alpha * (tm - 413.15)) / (1 - alpha * (tm - 353.15)), rtol=1e-14)
    np.testing.assert_array_equal(p["displacements"], p["positions"] - p0["positions"])
    assert 0.33 < sim.relative_density < 0.74  # compressed from the loose 0.3 (a few ms of it)
    m = len(c["forces"])
    assert m > 0 and c["pairs"].shape == (m, 2) and c["neck_radii"].shape == (m,)
    i, j = c["pairs"][:, 0], c["pairs"][:, 1]
    assert (i != j).all() and (i >= 0).all() and (j < n).all()
    # neck radius: the circle where the spheres intersect (0 at a gap)
    d = np.linalg.norm(p["positions"][i] - p["positions"][j], axis=1)
    ri, rj = p["radii"][i], p["radii"][j]
    x = (d * d + ri * ri - rj * rj) / (2 * d)
    a = np.where(d < ri + rj, np.sqrt(np.maximum(ri * ri - x * x, 0.0)), 0.0)
    np.testing.assert_allclose(c["neck_radii"], a, rtol=1e-12, atol=1e-18)
    assert (c["neck_radii"] < np.minimum(ri, rj)).all()
    # forces in N: below the whole wall load p·A ≈ 5e3 Pa × (8 mm)² ≈ 0.3 N; hot contacts pull
    # (Luding's attractive branch: negative)
    assert np.isfinite(c["forces"]).all() and np.abs(c["forces"]).max() < 0.3
    assert (c["forces"] < 0).any()
    sim.finish()


def test_a_callback_stops_an_explicit_protocol(tmp_path):
    sim = sinterdem.Simulation(luding(), out=tmp_path)
    seen = []

    def cb(s):
        seen.append(s.steps)
        return s.steps < 150

    res = sim.run(callback=cb, every=50)
    assert seen == [0, 50, 100, 150]
    s = res.summary
    assert s["completed"] is False and s["stop_reason"] == "stopped by the callback"
    assert s["stopped_at"]["steps"] == 150 and s["stopped_at"]["stage"] == "prepare" and s["branches"] == []
    h = res.out / "history_stopped.csv"
    rows = sinterdem.read_csv(h)
    assert rows["time_s"].iloc[-1] <= s["stopped_at"]["time_s"]


def test_finish_early_and_the_setters_explicit_sinter_refuses(tmp_path):
    with sinterdem.Simulation(luding(), out=tmp_path) as sim:
        for _ in range(3):
            sim.step()
        with pytest.raises(sinterdem.ConfigError, match="temperature history is the protocol"):
            sim.set_furnace_temperature(400.0)
        with pytest.raises(sinterdem.ConfigError, match="walls.pressures"):
            sim.set_applied_stress(1e4)
    s = sim.result.summary
    assert s["completed"] is False and s["stop_reason"] == "stopped by the caller" and s["stopped_at"]["steps"] == 3
    assert sim.stage[0] == "prepare"


CHILD = textwrap.dedent("""
    import sys, sinterdem
    case = sinterdem.Case.load(sys.argv[1])
    for kv in sys.argv[4:]:
        k, v = kv.split("=", 1)
        case[k] = sinterdem._native.parse_toml("v = " + v, "<set>")["v"]
    threads = int(sys.argv[3]) or None
    print("started", flush=True)
    try:
        sinterdem.run(case, out=sys.argv[2], progress=False, threads=threads)
    except KeyboardInterrupt as e:
        print("KeyboardInterrupt:", e, flush=True)
        sys.exit(130)
    print("finished without interrupt", flush=True)
""")


@pytest.mark.parametrize("name,threads,sets", [
    ("pair-copper.toml", 0, ["pair.end_time=50000.0", 'solver.method="rosenbrock4"', "solver.rtol=1e-12", "output.plot=false"]),
    ("green-copper.toml", 0, []),
    ("luding-sintering-time.toml", 0, ["output.checkpoint_every=0"]),
    ("luding-sintering-time.toml", 2, ["output.checkpoint_every=0"]),
], ids=["pair", "generate", "explicit_sinter", "explicit_sinter-threads2"])
def test_sigint_to_a_child_interpreter(tmp_path, name, threads, sets):
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-c", CHILD, str(CASES / name), str(out), str(threads), *sets],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    assert p.stdout.readline().strip() == "started"
    deadline = time.time() + 120
    while time.time() < deadline and not (out / "log.txt").exists():
        time.sleep(0.02)
    time.sleep(0.3)  # into the run's loop
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 130, (stdout, stderr)
    assert "KeyboardInterrupt" in stdout
    s = read_summary(out)
    assert s["completed"] is False and s["stop_reason"] == "interrupted"
    if name.startswith("pair"):
        assert 0 < s["final_time_s"] < 50000.0
        series = sinterdem.read_csv(out / "series.csv")
        assert math.isclose(series["time_s"].iloc[-1], s["final_time_s"], rel_tol=1e-9)
    elif name.startswith("green"):
        assert s["thresholds_met"] is False
        assert len(sinterdem.read_csv(out / "packing.csv")["x_m"]) == 805
    else:
        assert s["stopped_at"]["steps"] > 0
        assert (out / "history_stopped.csv").exists() or (out / "compression_stopped.csv").exists()
