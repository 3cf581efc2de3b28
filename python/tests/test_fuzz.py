"""The Python API's fuzzer (issue 38, "Python as safe as the CLI"): a child interpreter makes random
calls with hostile values, and the test asserts what the issue's red team found broken never
happens again.

The calls (``OPS``), on the bundled cases made small:

- ``Case.from_dict`` of a bundled case whose leaf (or a new key) is a hostile value: NaN, ±inf,
  -1, 0, 1e308, 5e-324, 2**63, a text, None, a bool, an empty list or table, a list nested 10 to
  100 000 deep, a dict or list that contains itself;
- ``case[key] = value`` with the same values, on the case's own keys and on odd ones;
- ``sinterdem.run`` of a small case with a hostile ``threads`` (0, -1, 10**6, 2.5, "2", True, …);
- a ``Simulation`` stepped from a thread other than its creator;
- signals: a run in a worker thread while the main thread's run is stopped by SIGINT (the main
  call raises ``KeyboardInterrupt``, the worker's run ends complete).

Asserted: the child interpreter is not killed by a signal (a crash: SIGSEGV, abort) and ends
within its guard (a hang); every exception is a ``sinterdem.Error`` (or the ``TypeError`` of a
value of a wrong Python type — None, 2.5 threads —, or the ``KeyboardInterrupt`` of a signal
sent; an ``OverflowError`` of an int beyond 64 bits was one and is now the key's ``ConfigError``), none
carries Rust panic text, none is a ``BaseException`` such as ``pyo3_runtime.PanicException``; a
call that returns gave what it promises (a run: ``completed`` with ``summary.json`` and
``series.csv``; the signalled run: ``completed = false``, ``stop_reason = "interrupted"``).

``SINTERDEM_PY_FUZZ_RUNS`` calls (default 150) within ``SINTERDEM_PY_FUZZ_SECONDS`` (default 30);
``SINTERDEM_FUZZ_SEED`` picks the stream (fixed default: reproducible). The counts are printed.
"""

import json
import os
import subprocess
import sys

from conftest import CASES

CHILD = r'''
import json, math, os, random, signal, sys, threading, time
from pathlib import Path
import sinterdem

cases, out, runs, budget, seed = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
rng = random.Random(seed)
counts = {"calls": 0, "returned": 0, "refused": 0, "type_errors": 0, "interrupted": 0,
          "panics": 0, "wrong_exceptions": 0, "wrong_returns": 0, "by_op": {}}
problems = []
PANIC_TEXT = ("panicked at", "RUST_BACKTRACE", "stack backtrace", "PanicException")

SMALL = {
    "pair-copper.toml": {"pair.end_time": 20.0},
    "hot-plate.toml": {"particles.cells": [2, 2, 2], "time.end": 20.0, "output.snapshots": 0},
    "copper-compact.toml": {"time.end": 2.0, "output.snapshots": 0, "output.conductivity_at": [], "output.checkpoint_every": 0},
    "rve-copper.toml": {"time.end": 2.0, "rve.at": [2.0], "output.snapshots": 0, "output.conductivity_at": []},
    "green-copper.toml": {"packing.particles": 50},
    "luding-pressure.toml": {},
}

def nested(depth, inner):
    v = inner
    for _ in range(depth):
        v = [v]
    return v

def self_ref():
    if rng.random() < 0.5:
        d = {"a": 1.0}
        d["b"] = d
        return d
    l = [1.0]
    l.append(l)
    return l

def hostile():
    k = rng.randrange(18)
    return [float("nan"), float("inf"), -float("inf"), -1.0, 0, 0.0, 1e308, 5e-324, 2 ** 63, -(2 ** 63) - 1,
            "ten", None, True, [], {}, None, None, None][k] if k < 15 else (
        nested(rng.choice([10, 70, 5000, 100000]), 1.0) if k < 17 else self_ref())

def leaves(d, prefix=""):
    if isinstance(d, dict):
        for k, v in d.items():
            yield from leaves(v, f"{prefix}{k}.")
    elif isinstance(d, list) and d and not all(isinstance(x, (int, float)) for x in d):
        for i, v in enumerate(d):
            yield from leaves(v, f"{prefix}{i}.")
    else:
        yield prefix[:-1]

def small_case(name):
    c = sinterdem.Case.load(cases / name)
    for k, v in SMALL[name].items():
        c[k] = v
    return c

def odd_key(keys):
    return rng.choice(keys + ["", ".", "a..b", "materials.99.density", "time.end.x", "no.such.key", "materials.0", "time"])

def op_from_dict(n):
    name = rng.choice(list(SMALL))
    d = small_case(name).to_dict()
    keys = list(leaves(d))
    key = odd_key(keys).split(".")
    cur = d
    for part in key[:-1]:
        if isinstance(cur, dict):
            cur = cur.setdefault(part, {})
        elif isinstance(cur, list) and part.isdigit() and int(part) < len(cur):
            cur = cur[int(part)]
        else:
            break
    if isinstance(cur, dict):
        cur[key[-1] or "x"] = hostile()
    sinterdem.Case.from_dict(d, base_dir=cases)

def op_setitem(n):
    name = rng.choice(list(SMALL))
    c = small_case(name)
    c[odd_key(list(leaves(c.to_dict())))] = hostile()
    c.check()

def check_run(res, d):
    s = json.loads((Path(d) / "summary.json").read_text())
    if s.get("completed") is False or not (Path(d) / "summary.json").is_file():
        return f"returned but summary.json says completed = {s.get('completed')} ({s.get('stop_reason')})"
    if res.kind in ("heat", "compact", "pair") and not (Path(d) / "series.csv").is_file():
        return "returned without series.csv"
    return None

def op_run(n):
    name = rng.choice(["pair-copper.toml", "hot-plate.toml", "copper-compact.toml"])
    threads = rng.choice([None, 1, 2, 16, 0, -1, 10 ** 6, 10 ** 30, 2.5, "2", True])
    d = out / f"run-{n}"
    res = sinterdem.run(small_case(name), out=d, progress=False, threads=threads)
    return check_run(res, d)

def op_thread(n):
    sim = sinterdem.Simulation(small_case("hot-plate.toml"), out=out / f"sim-{n}")
    caught = []
    def other():
        try:
            sim.step()
        except BaseException as e:  # noqa: BLE001 - classified by the caller
            caught.append(e)
    t = threading.Thread(target=other)
    t.start()
    t.join()
    sim.finish()
    if not caught:
        return "a Simulation stepped from another thread did not refuse"
    raise caught[0]

def op_signal(n):
    worker_res = {}
    def worker():
        try:
            c = small_case("hot-plate.toml")
            c["time.end"] = 200.0
            d = out / f"worker-{n}"
            worker_res["r"] = (sinterdem.run(c, out=d, progress=False), d)
        except BaseException as e:  # noqa: BLE001
            worker_res["e"] = e
    t = threading.Thread(target=worker)
    t.start()
    c = small_case("copper-compact.toml")
    c["time.end"] = 2000.0
    d = out / f"main-{n}"
    timer = threading.Timer(rng.uniform(0.3, 1.0), lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        sinterdem.run(c, out=d, progress=False)
        timer.cancel()
        problem = "the signalled run returned (not KeyboardInterrupt)"
    except KeyboardInterrupt:
        # (no summary: the signal came while the case was being prepared, before a first step)
        s = json.loads((d / "summary.json").read_text()) if (d / "summary.json").is_file() else {"completed": False, "stop_reason": "interrupted"}
        problem = None if s.get("completed") is False and s.get("stop_reason") == "interrupted" else f"interrupted run's summary: {s.get('completed')}, {s.get('stop_reason')}"
    t.join()
    if "e" in worker_res:
        return f"the worker's run raised {type(worker_res['e']).__name__}: {worker_res['e']}"
    return problem or check_run(*worker_res["r"])

OPS = {"from_dict": op_from_dict, "setitem": op_setitem, "run": op_run, "thread": op_thread, "signal": op_signal}
WEIGHTS = {"from_dict": 6, "setitem": 6, "run": 3, "thread": 1, "signal": 1}
start = time.monotonic()
n = 0
while n < runs and time.monotonic() - start < budget:
    op = rng.choices(list(WEIGHTS), weights=list(WEIGHTS.values()))[0]
    counts["calls"] += 1
    counts["by_op"][op] = counts["by_op"].get(op, 0) + 1
    problem = None
    try:
        problem = OPS[op](n)
        counts["returned"] += 1
        if problem:
            counts["wrong_returns"] += 1
    except sinterdem.Error as e:
        counts["refused"] += 1
        if any(t in str(e) for t in PANIC_TEXT):
            counts["panics"] += 1
            problem = f"Rust panic text in {type(e).__name__}: {str(e)[:300]}"
    except TypeError as e:
        counts["type_errors"] += 1
        if any(t in str(e) for t in PANIC_TEXT):
            counts["panics"] += 1
            problem = f"Rust panic text in {type(e).__name__}: {str(e)[:300]}"
    except KeyboardInterrupt:
        counts["interrupted"] += 1
        if op != "signal":
            problem = "KeyboardInterrupt without a signal"
    except BaseException as e:  # noqa: BLE001 - what the test is about
        panic = type(e).__name__ == "PanicException" or any(t in str(e) for t in PANIC_TEXT)
        counts["panics" if panic else "wrong_exceptions"] += 1
        problem = f"{type(e).__module__}.{type(e).__name__}: {str(e)[:300]}"
    if problem:
        problems.append(f"call {n} ({op}): {problem}")
    n += 1
counts["seconds"] = time.monotonic() - start
print(json.dumps({"counts": counts, "problems": problems}))
'''


def test_python_api_fuzz_never_crashes_hangs_or_panics(tmp_path):
    runs = int(float(os.environ.get("SINTERDEM_PY_FUZZ_RUNS", "150")))
    budget = float(os.environ.get("SINTERDEM_PY_FUZZ_SECONDS", "30"))
    seed = int(float(os.environ.get("SINTERDEM_FUZZ_SEED", "38")))
    guard = budget + 120.0
    try:
        p = subprocess.run([sys.executable, "-c", CHILD, str(CASES), str(tmp_path), str(runs), str(budget), str(seed)],
                           capture_output=True, text=True, timeout=guard)
    except subprocess.TimeoutExpired as e:
        raise AssertionError(f"hang: the fuzzing interpreter ran past {guard} s; stderr tail: {str(e.stderr)[-2000:]}") from None
    assert p.returncode >= 0, f"crash: the fuzzing interpreter was killed by signal {-p.returncode}; stderr tail:\n{p.stderr[-3000:]}"
    assert p.returncode == 0, f"the fuzzing interpreter failed (exit {p.returncode}):\n{p.stderr[-3000:]}"
    report = json.loads(p.stdout.strip().splitlines()[-1])
    c = report["counts"]
    print("python fuzz:", json.dumps(c))
    assert c["calls"] >= min(runs, 10), c
    assert not report["problems"], "\n".join(report["problems"]) + f"\ncounts: {c}"
    assert c["panics"] == c["wrong_exceptions"] == c["wrong_returns"] == 0, c
