#!/usr/bin/env python3
"""FE of the extra packings used to check the multi-neck correction
(docs/validation-conductance.md "Random periodic packings", "Several necks per
sphere"): new seeds of the random recipe, not used in the derivation.
Writes validation/data/random_crowding.csv (same columns as
random_conductivity.csv).  Usage: python validation/crowding_fe.py [NAME ...]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fe_random as fr  # noqa: E402

NEW = {
    # validation seeds (not used in the derivation)
    "v-n16-h012-s2": (16, 0.12, 0.0, 2),
    "v-n16s-h012-s4": (16, 0.12, 0.15, 4),
    "v-n16-h006-s2": (16, 0.06, 0.0, 2),
    "v-n16s-h006-s4": (16, 0.06, 0.15, 4),
    "v-n16-h002-s2": (16, 0.02, 0.0, 2),
    "v-n16s-h002-s3": (16, 0.02, 0.15, 3),
    "v-n16-h012-s5": (16, 0.12, 0.0, 5),
    "v-n16s-h012-s7": (16, 0.12, 0.15, 7),
}
fr.CASES.update(NEW)
_network_kappa = fr.network_kappa


def _network_or_nan(pk, *args, **kw):
    """The binary's network, or NaN when it cannot run (an older binary without
    thermal.multi_neck): crowding_correction.py recomputes every network with
    its Python twin (equal to the binary to 1e-9, tested), so only the FE
    columns of these files are used."""
    try:
        return _network_kappa(pk, *args, **kw)
    except RuntimeError:
        import numpy as np
        return np.full((3, 3), np.nan), {"periodic_contacts": len(pk.bonds)}


fr.network_kappa = _network_or_nan
OUT = os.path.join(fr.DATA, os.environ.get("FE_OUT", "random_crowding.csv"))


def main(names, levels=tuple(int(v) for v in os.environ.get("FE_LEVELS", "1 2 3").split())):
    results = []
    for name in names:
        try:
            if not os.path.exists(os.path.join(fr.DATA, "random", name, "packing.csv")):
                fr.new_reference(name)     # a new case: its packing becomes the stored reference
            results.append(fr.run_case(name, levels))
        except Exception as e:  # a packing whose OCC union fails everywhere: report, go on
            print(f"{name}: FAILED {e}", flush=True)
            continue
        fr.write_table(results, OUT)
        r = results[-1]
        print(f"DONE {name} fe {r['diag_x']} mean {r['mean_x']:.6f} p {r['p']:.2f}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or list(NEW))
