"""The exceptions of sinterdem, one class per error family of the library (docs/python.md).

Every exception carries the text the command line prints after ``error:``; the command line
exits with a distinct code per class (docs/outputs.md, "Exit codes").
"""

from __future__ import annotations

import re
from typing import Optional

__all__ = ["Error", "ConfigError", "ModelError", "SolveError", "IoError"]

_LOCATED = re.compile(r"^(?P<file>[^\n]+?):(?P<line>\d+):(?P<col>\d+): ")


class Error(Exception):
    """Any sinterdem error. ``str(e)`` is the command line's message; ``exit_code`` its exit code;
    ``out`` the output directory of the run that failed (None for errors before a run): what
    the run computed up to the error is there (``series.csv``, ``summary.json`` with
    ``completed = false`` and the error, ``log.txt``)."""

    exit_code = 1
    out = None

    def __init__(self, message: str, *, key: Optional[str] = None, value: Optional[float] = None,
                 allowed: Optional[str] = None, unit: Optional[str] = None,
                 file: Optional[str] = None, line: Optional[int] = None) -> None:
        super().__init__(message)
        self.message = message
        self.key = key
        self.value = value
        self.allowed = allowed
        self.unit = unit
        if file is None:
            m = _LOCATED.match(message)
            if m:
                file, line = m.group("file"), int(m.group("line"))
        self.file = file
        self.line = line


class ConfigError(Error):
    """A case (or study, calibration) file or value that is malformed or out of range.

    Attributes: ``key`` (dotted case key, when the error names one), ``value`` (the rejected
    number), ``allowed`` (the allowed range, e.g. ``"(0, inf)"``), ``unit``, ``file`` and
    ``line`` (where the key is in the case file, when the case came from a file).
    """

    exit_code = 1


class ModelError(Error):
    """A physical model left its domain of validity (e.g. a neck larger than the smaller particle)."""

    exit_code = 3


class SolveError(Error):
    """A linear or nonlinear solve failed (not SPD, no convergence, non-finite result)."""

    exit_code = 4


class IoError(Error):
    """Reading or writing a file failed."""

    exit_code = 5
