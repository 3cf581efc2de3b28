"""A loop over temperatures in Python, and the same sweep as sinterdem.study (docs/python.md, step 5).

    python examples/temperature_sweep.py
"""

import tempfile
import time

import sinterdem
from _common import CASES, FULL, pyplot, OUT

temperatures = [1233.0, 1263.0, 1293.0]
end = 5000.0 if FULL else 600.0

# a Python loop: one run per temperature
t0 = time.perf_counter()
loop = {}
for T in temperatures:
    case = sinterdem.Case.load(CASES / "pair-copper.toml")
    case["pair.end_time"] = end
    case["output.plot"] = False
    case["temperature"] = {"constant": T}
    loop[T] = sinterdem.run(case, progress=False).summary["neck_ratio"]
t_loop = time.perf_counter() - t0

# the same as a study: one table, resumable, runs in parallel (jobs), and on Slurm with engine="slurm"
t0 = time.perf_counter()
with tempfile.TemporaryDirectory() as d:
    df = sinterdem.study({
        "title": "copper pair temperatures",
        "base": str(CASES / "pair-copper.toml"),
        "overrides": [f"pair.end_time={end}"],
        "parameters": [{"key": "temperature.constant", "name": "temperature_K", "values": temperatures}],
        "collect": {"summary": ["neck_ratio"]},
    }, d, progress=False)
t_study = time.perf_counter() - t0
study = dict(zip(df["temperature_K"], df["neck_ratio"]))
for T in temperatures:
    print(f"T = {T} K: neck ratio y1/R = {loop[T]:.6f} (loop), {study[T]:.6f} (study)")
    assert loop[T] == study[T], "a study's run is the run a user starts alone"
print(f"loop {t_loop:.2f} s, study {t_study:.2f} s")

plt = pyplot()
if plt is not None:
    fig, ax = plt.subplots(figsize=(4.5, 3.2))
    ax.plot(temperatures, [loop[T] for T in temperatures], "o-")
    ax.set_xlabel("T [K]")
    ax.set_ylabel(f"neck ratio y1/R at {end:g} s")
    fig.tight_layout()
    fig.savefig(OUT / "temperature_sweep.png", dpi=100)
    print(f"plot: {OUT / 'temperature_sweep.png'}")
