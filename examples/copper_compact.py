"""A copper compact built from a dict, run, and plotted (docs/python.md, steps 2-4).

    python examples/copper_compact.py
"""

import sinterdem
from _common import CASES, FULL, pyplot, OUT

# 1. the case as a dict: the flagship copper compact (cases/copper-compact.toml) spelled out
case = sinterdem.Case.from_dict({
    "kind": "compact",
    "title": "copper compact from Python",
    "time": {"end": 5000.0 if FULL else 2.0, "dt": 1.0e-6, "strategy": 2, "dt_max": 10.0, "alpha": 1.5},
    "output": {"snapshots": 3, "series_every": 1, "checkpoint_every": 0},
    "materials": [{"name": "copper", "preset": "copper"}],
    "particles": {"source": "file", "file": "data/green-copper.csv"},
    "thermal": {"mode": "isothermal", "furnace": {"profile": {"constant": 1293.0}}},
    "contacts": {"detect_new": True, "detect_every": 5, "gap_tolerance": 1.0e-3, "neck": "volume_conserving"},
    "solver": {"method": "dopri5", "rtol": 1.0e-5},
    "mechanics": {"constrain_planes": True, "plane_margin": 1.01, "solver": "auto"},
}, base_dir=CASES)                      # the packing file's path starts at cases/
print(case.check())                     # "compact case, 805 particles, … contacts"

# 2. run it
res = sinterdem.run(case, progress=False)
s = res.summary
print(f"{s['steps']} steps to t = {s['final_time_s']} s: relative density {s['relative_density_initial']:.4f} -> "
      f"{s['relative_density']:.4f}, shrinkage z {s['shrinkage_z']:.3e}, mean neck ratio {s['neck_ratio']:.4f}")

# 3. shrinkage over time (series.csv) and the particles of the last snapshot
series = res.series
p = res.particles(-1)
print(f"{len(res.times)} snapshots at t = {list(res.times)} s; last: {len(p['ids'])} particles, "
      f"largest displacement {abs(p['displacements']).max():.3e} m")

plt = pyplot()
if plt is not None:
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    for axis in "xyz":
        ax[0].plot(series["time_s"], series[f"shrinkage_{axis}"], label=axis)
    ax[0].set_xlabel("t [s]")
    ax[0].set_ylabel("shrinkage ΔL/L0")
    ax[0].legend()
    x, d = p["positions"], p["displacements"]
    sc = ax[1].scatter(x[:, 0] * 1e6, x[:, 2] * 1e6, c=d[:, 2] * 1e9, s=8, cmap="coolwarm")
    fig.colorbar(sc, ax=ax[1], label="u_z [nm]")
    ax[1].set_xlabel("x [µm]")
    ax[1].set_ylabel("z [µm]")
    fig.tight_layout()
    fig.savefig(OUT / "copper_compact.png", dpi=100)
    print(f"plot: {OUT / 'copper_compact.png'}")
