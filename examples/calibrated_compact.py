"""A calibrated material reused in a compact (docs/python.md, step 7).

    python examples/calibrated_compact.py
"""

import tempfile
from pathlib import Path

import sinterdem
from _common import CASES, FULL

with tempfile.TemporaryDirectory() as d:
    # a quick fit (the full one: drop the overrides; docs/calibration.md)
    quick = [] if FULL else ["optimiser.swarm_size=4", "optimiser.swarm_iterations=1", "optimiser.local_iterations=2"]
    fit = sinterdem.calibrate(CASES / "calibration" / "titanium-synthetic.toml", Path(d) / "fit", overrides=quick)
    print(fit.parameters[["value", "sigma", "unit"]])
    # fit.material is the calibrated diffusion data ([[materials]] entry: name, phases, …); the
    # thermal and elastic values come from the preset it was fitted against
    material = {**sinterdem.Case.preset_material("titanium-ivannikov2022"), **fit.material}

    case = sinterdem.Case.load(CASES / "titanium-compact-e14b.toml")
    case["materials"] = [material]                # the calibrated titanium instead of the preset
    case["time.end"] = 10320.0 if FULL else 0.2
    case["output.checkpoint_every"] = 0
    case["output.snapshots"] = 0
    case["output.correction_histogram_at"] = []
    res = sinterdem.run(case, out=Path(d) / "compact", progress=False)
    s = res.summary
    print(f"titanium compact with the calibrated material: {s['steps']} steps to {s['final_time_s']} s, "
          f"mean neck ratio {s['neck_ratio']:.4f}, relative density {s['relative_density']:.5f}")
