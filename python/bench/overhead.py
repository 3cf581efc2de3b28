"""Overhead of sinterdem.run over the in-process Rust run API (sinterdem::kinds::run).

    python python/bench/overhead.py [RUNS]      # from the repository root, package installed

For a pair run (cases/pair-copper.toml, plots off) it times `sinterdem.run(...)` in Python and
subtracts the wall time that `sinterdem::kinds::run` measures inside itself (RunSummary.wall_seconds:
the whole run, outputs included). The difference is the binding: case clone, GIL release, reading
summary.json and log.txt back, the result object. Medians over RUNS runs (default 200).
"""

import statistics
import sys
import tempfile
import time

import sinterdem

runs = int(sys.argv[1]) if len(sys.argv) > 1 else 200
for end in (10.0, 5000.0):
    case = sinterdem.Case.load("cases/pair-copper.toml")
    case["output.plot"] = False
    case["pair.end_time"] = end
    total, inner = [], []
    with tempfile.TemporaryDirectory() as d:
        for i in range(runs + 5):
            t0 = time.perf_counter()
            r = sinterdem.run(case, out=d, progress=False)
            t = time.perf_counter() - t0
            if i >= 5:  # warm-up
                total.append(t)
                inner.append(r.wall_seconds)
    mt, mi = statistics.median(total), statistics.median(inner)
    over = statistics.median([a - b for a, b in zip(total, inner)])
    print(f"pair, end_time = {end:g} s ({r.summary['steps']} steps): sinterdem.run {mt * 1e3:.3f} ms, "
          f"kinds::run {mi * 1e3:.3f} ms, overhead {over * 1e3:.3f} ms ({100 * over / mi:.1f} %), median of {runs}")
