"""The progress line of a notebook (the Rust bar draws on a terminal only)."""

from __future__ import annotations

import shutil
import sys
import time
from typing import Optional


def in_notebook() -> bool:
    """Whether we run in a Jupyter kernel (stderr is then the notebook's, not a terminal)."""
    return "ipykernel" in sys.modules and not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty())


def eta_text(seconds: float) -> str:
    """``12 s``, ``3 min 05 s``, ``1 h 02 min``."""
    s = int(round(max(seconds, 0.0)))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


class ProgressLine:
    """One updating line: simulated time, percentage, wall time and ETA (from the wall time per
    simulated second so far), cut to the width of the output."""

    def __init__(self) -> None:
        self.last = ""
        self.start = time.monotonic()
        self.width = shutil.get_terminal_size((100, 20)).columns - 1

    @classmethod
    def make(cls, progress: bool) -> Optional["ProgressLine"]:
        return cls() if progress and in_notebook() else None

    def text(self, t: float, end: float) -> str:
        frac = min(max(t / end, 0.0), 1.0) if end > 0 else 1.0
        wall = time.monotonic() - self.start
        eta = f", ETA {eta_text(wall * (1.0 - frac) / frac)}" if 0.0 < frac < 1.0 and wall > 1.0 else ""
        text = f"sinterdem: t = {t:.4g} s of {end:.4g} s ({100.0 * frac:5.1f} %), {eta_text(wall)}{eta}"
        return text[: self.width]

    def __call__(self, t: float, end: float) -> None:
        text = self.text(t, end)
        if text != self.last:
            pad = " " * max(len(self.last) - len(text), 0)
            sys.stderr.write("\r" + text + pad)
            sys.stderr.flush()
            self.last = text

    def close(self) -> None:
        if self.last:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self.last = ""
