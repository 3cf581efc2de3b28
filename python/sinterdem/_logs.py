"""The library's log and warnings in Python's own machinery.

Every info line a run writes to ``log.txt`` goes to the ``logging`` logger ``"sinterdem"``
(silent unless the application configures logging, e.g. ``logging.basicConfig(level="INFO")``);
every warning also goes through :mod:`warnings` as a :class:`SinterdemWarning` (printed once
per distinct text and place by Python's default filter; ``warnings.simplefilter("error",
sinterdem.SinterdemWarning)`` turns them into exceptions).
"""

from __future__ import annotations

import logging
import warnings

from . import _native

__all__ = ["SinterdemWarning", "logger"]

logger = logging.getLogger("sinterdem")
logger.addHandler(logging.NullHandler())


class SinterdemWarning(UserWarning):
    """A warning of a sinterdem run or check (the ``warning:`` lines of the command line and of ``log.txt``)."""


def capture() -> None:
    """Routes the library's events to this module (once per process; not at import, for the console command)."""
    _native.capture_log()


def flush(stacklevel: int = 3) -> None:
    """Passes the lines the library logged since the last call to ``logging``, and each distinct
    warning among them to ``warnings.warn`` (``stacklevel``: frames above ``flush`` to point at)."""
    seen = set()
    for level, text in _native.take_log():
        logger.log(level, text)
        if level == logging.WARNING and text not in seen:
            seen.add(text)
            warnings.warn(text, SinterdemWarning, stacklevel=stacklevel + 1)


class captured:
    """Context of one call into the library: capture on entry, flush on exit (also on an error).

    The warnings point at the user's line: the ``with`` is in a function the user called, or
    ``extra`` frames below it."""

    def __init__(self, extra: int = 0) -> None:
        self.extra = extra

    def __enter__(self) -> "captured":
        capture()
        return self

    def __exit__(self, *exc) -> None:
        # frames from warnings.warn: flush, __exit__, the function with the ``with``, ...
        flush(3 + self.extra)
