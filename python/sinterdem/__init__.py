"""sinterdem: a coupled thermo-mechanical simulator of powder sintering, from Python.

The package calls the same Rust library as the ``sinterdem`` command line (which the wheel also
installs): a :class:`Case` is a case file plus ``--set`` overrides, :func:`run` is
``sinterdem run``, :func:`rve`, :func:`generate`, :func:`study`, :func:`calibrate`,
:func:`conductivity`, :func:`neck` and :func:`materials` the commands of the same names,
:class:`Simulation` a run stepped from Python. Errors are exceptions by class
(:class:`ConfigError`, :class:`ModelError`, :class:`SolveError`, :class:`IoError`, all
:class:`Error`) with the command line's text; warnings go through :mod:`warnings`
(:class:`SinterdemWarning`), the log through :mod:`logging` (logger ``"sinterdem"``).
See docs/python.md.

>>> import sinterdem
>>> case = sinterdem.Case.load("cases/pair-copper.toml")
>>> case["time.end"] = 600
>>> res = sinterdem.run(case, progress=False)
>>> res.summary["neck_ratio"], res.series["time_s"].iloc[-1]

Modules by concern: ``_case`` (cases), ``_commands`` (the commands), ``_simulation``
(stepping), ``_results`` (what they return), ``_tables`` (CSV), ``_logs`` (warnings and
logging), ``_progress`` (the notebook's progress line), ``_errors``, ``_snapshots`` (VTU).
"""

from __future__ import annotations

from . import _native
from ._case import Case
from ._commands import calibrate, conductivity, generate, materials, neck, rve, run, study
from ._errors import ConfigError, Error, IoError, ModelError, SolveError
from ._logs import SinterdemWarning
from ._results import CalibrationResult, Conductivity, GenerateResult, Neck, RunResult, RveResult
from ._simulation import Simulation
from ._tables import read_csv

__all__ = [
    "Case", "Simulation",
    "run", "rve", "generate", "study", "calibrate", "conductivity", "neck", "materials", "read_csv",
    "RunResult", "RveResult", "GenerateResult", "CalibrationResult", "Conductivity", "Neck",
    "Error", "ConfigError", "ModelError", "SolveError", "IoError", "SinterdemWarning", "__version__", "HDF5",
]
__version__ = _native.__version__
#: Whether this build writes HDF5 output (``output.hdf5``): built with ``--features h5``
#: (``bash scripts/pip-install.sh`` where libhdf5 is installed; docs/python.md "Install").
HDF5: bool = _native.HDF5


def __dir__():
    """The public names only (tab completion)."""
    return sorted(__all__)
