"""A temperature field: the hot-plate heat case, its last snapshot plotted (docs/python.md, step 4).

    python examples/temperature_field.py
"""

import sinterdem
from _common import CASES, FULL, pyplot, OUT

case = sinterdem.Case.load(CASES / "hot-plate.toml")
case["time.end"] = 900.0 if FULL else 60.0
case["output.snapshots"] = 4
res = sinterdem.run(case, progress=False)
p = res.particles(-1)                       # positions (N, 3) m, temperatures (N,) K
z, T = p["positions"][:, 2], p["temperatures"]
print(f"t = {res.times[-1]} s: T from {T.min():.2f} K (top) to {T.max():.2f} K (plate), {len(T)} particles")

plt = pyplot()
if plt is not None:
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    for i, t in enumerate(res.times):
        q = res.particles(i)
        ax[0].plot(q["positions"][:, 2] * 1e6, q["temperatures"], ".", ms=2, label=f"t = {t:g} s")
    ax[0].set_xlabel("z [µm]")
    ax[0].set_ylabel("T [K]")
    ax[0].legend()
    x = p["positions"]
    mid = abs(x[:, 1] - x[:, 1].mean()) < p["radii"].mean()
    sc = ax[1].scatter(x[mid, 0] * 1e6, x[mid, 2] * 1e6, c=T[mid], s=12, cmap="inferno")
    fig.colorbar(sc, ax=ax[1], label="T [K]")
    ax[1].set_xlabel("x [µm]")
    ax[1].set_ylabel("z [µm]")
    fig.tight_layout()
    fig.savefig(OUT / "temperature_field.png", dpi=100)
    print(f"plot: {OUT / 'temperature_field.png'}")
