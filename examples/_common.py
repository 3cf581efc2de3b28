"""Shared by the examples: the repository's cases folder, and matplotlib when it is installed.

Every example runs from any working directory; plots go to ``examples/out/`` (headless
backend). Without matplotlib an example prints why it skips its plot and carries on.
"""

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "cases"
OUT = Path(os.environ.get("SINTERDEM_EXAMPLES_OUT", ROOT / "examples" / "out"))
# the walkthrough's runs are shortened here so that the tests run every example in seconds;
# SINTERDEM_EXAMPLES_FULL=1 runs the lengths docs/python.md quotes
FULL = os.environ.get("SINTERDEM_EXAMPLES_FULL") == "1"


def pyplot():
    """matplotlib.pyplot with the headless Agg backend, or None (with the reason printed)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:
        print(f"plot skipped: matplotlib is not installed ({e}); pip install matplotlib")
        return None
    OUT.mkdir(parents=True, exist_ok=True)
    return plt
