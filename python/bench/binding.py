"""The benchmarks of the Python binding quoted in docs/python.md "Cost of the binding".

    python python/bench/binding.py [compact|sweep|particles|all]    # from the repository root

- compact: `sinterdem.run` on the copper compact (cases/copper-compact.toml, time.end = 5 s,
  no snapshots) against the wall time the Rust run API measures inside itself, and the same
  run stepped from Python one `sim.step()` at a time;
- sweep: 1 000 pair runs (cases/pair-copper.toml, end_time = 10 s, 1 000 temperatures) as a
  Python loop over `sinterdem.run` and as one `sinterdem.study` (jobs = 2);
- particles: the cost of `sim.particles` and `sim.contacts` at about 10⁵ particles (the
  hot-plate heat case on a 30 × 30 × 28 fcc lattice: 100 800 particles).
(The pair-run overhead is python/bench/overhead.py.)
"""

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import sinterdem

CASES = Path("cases")


def compact(rounds=4):
    case = sinterdem.Case.load(CASES / "copper-compact.toml")
    for k, v in {"time.end": 5.0, "output.snapshots": 0, "output.checkpoint_every": 0, "output.conductivity_at": []}.items():
        case[k] = v
    total, inner, stepped = [], [], []
    with tempfile.TemporaryDirectory() as d:
        for _ in range(rounds):  # interleaved, so that a busy machine slows both alike
            t0 = time.perf_counter()
            r = sinterdem.run(case, out=d, progress=False)
            total.append(time.perf_counter() - t0)
            inner.append(r.wall_seconds)
            t0 = time.perf_counter()
            sim = sinterdem.Simulation(case, out=d)
            while sim.step():
                pass
            sim.finish()
            stepped.append(time.perf_counter() - t0)
    over = statistics.median([a - b for a, b in zip(total, inner)])
    mt, ms = statistics.median(total), statistics.median(stepped)
    print(f"copper compact, time.end = 5 s ({r.summary['steps']} steps): sinterdem.run {mt:.3f} s, overhead over kinds::run "
          f"{1e3 * over:.2f} ms ({100 * over / statistics.median(inner):.3f} %); stepped from Python (one sim.step() per step) "
          f"{ms:.3f} s ({100 * (ms - mt) / mt:+.1f} %); medians of {rounds}, runs {[round(x, 2) for x in total]} s, "
          f"stepped {[round(x, 2) for x in stepped]} s")


def sweep(n=1000):
    temps = list(np.linspace(1233.0, 1293.0, n))
    base = sinterdem.Case.load(CASES / "pair-copper.toml")
    base["pair.end_time"] = 10.0
    base["output.plot"] = False
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        necks = []
        for i, T in enumerate(temps):
            c = base.copy()
            c["temperature"] = {"constant": float(T)}
            necks.append(sinterdem.run(c, out=Path(d) / f"loop{i}", progress=False).summary["neck_ratio"])
        loop = time.perf_counter() - t0
        t0 = time.perf_counter()
        df = sinterdem.study({
            "title": "1000 pair runs",
            "base": str((CASES / "pair-copper.toml").resolve()),
            "overrides": ["pair.end_time=10.0"],
            "parameters": [{"key": "temperature.constant", "name": "T", "values": [float(T) for T in temps]}],
            "collect": {"summary": ["neck_ratio"]},
        }, Path(d) / "study", jobs=2, progress=False)
        study = time.perf_counter() - t0
        assert list(df["neck_ratio"]) == necks
    print(f"{n} pair runs (end_time = 10 s): Python loop over sinterdem.run {loop:.2f} s ({1e3 * loop / n:.2f} ms/run); "
          f"sinterdem.study(jobs=2) {study:.2f} s ({1e3 * study / n:.2f} ms/run); same neck ratios")


def particles():
    case = sinterdem.Case.load(CASES / "hot-plate.toml")
    case["particles.cells"] = [30, 30, 28]
    case["time.end"] = 1.0
    case["output.snapshots"] = 0
    t0 = time.perf_counter()
    sim = sinterdem.Simulation(case)
    prep = time.perf_counter() - t0
    sim.step()
    n = len(sim.particles["ids"])
    ts, tc = [], []
    for _ in range(20):
        t0 = time.perf_counter()
        p = sim.particles
        ts.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        c = sim.contacts
        tc.append(time.perf_counter() - t0)
    nbytes = sum(a.nbytes for a in p.values())
    print(f"{n} particles, {len(c['neck_radii'])} contacts (prepared in {prep:.1f} s): sim.particles {1e3 * statistics.median(ts):.2f} ms "
          f"({nbytes / 1e6:.1f} MB copied), sim.contacts {1e3 * statistics.median(tc):.2f} ms, median of 20")
    sim.finish()


what = sys.argv[1] if len(sys.argv) > 1 else "all"
for name, f in (("compact", compact), ("sweep", sweep), ("particles", particles)):
    if what in (name, "all"):
        f()
