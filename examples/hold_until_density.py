"""Stepping with a callback: hold the furnace until a relative density is reached, then cool
(docs/python.md, step 6; Yade's PyRunner use).

    python examples/hold_until_density.py
"""

import sinterdem
from _common import CASES, FULL, pyplot, OUT

case = sinterdem.Case.load(CASES / "copper-compact.toml")
case["time.end"] = 5000.0 if FULL else 3.0
case["output.checkpoint_every"] = 0
case["output.conductivity_at"] = []
case["output.snapshots"] = 2

sim = sinterdem.Simulation(case)
rho0 = sim.relative_density
# the target: a density gain that this (shortened) run reaches about half-way
target = rho0 + (0.03 if FULL else 2.0e-4)
history = []


def hold_then_cool(s):
    """Called every 10 steps: record, and cool the furnace once the target density is reached."""
    history.append((s.time, s.relative_density))
    if s.relative_density >= target and not hasattr(s, "cooled_at"):
        s.cooled_at = s.time
        s.set_furnace_temperature(900.0)     # K: sintering all but stops
        print(f"t = {s.time:.4g} s: relative density {s.relative_density:.5f} >= {target:.5f}: furnace to 900 K")
    return True                              # False would stop the run here


res = sim.run(callback=hold_then_cool, every=10)
print(f"{res.summary['steps']} steps; relative density {rho0:.5f} -> {res.summary['relative_density']:.5f}; "
      f"cooled at t = {getattr(sim, 'cooled_at', None)} s")

plt = pyplot()
if plt is not None:
    t, rho = zip(*history)
    fig, ax = plt.subplots(figsize=(4.5, 3.2))
    ax.plot(t, rho)
    ax.axhline(target, ls="--", c="gray")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("relative density")
    fig.tight_layout()
    fig.savefig(OUT / "hold_until_density.png", dpi=100)
    print(f"plot: {OUT / 'hold_until_density.png'}")
