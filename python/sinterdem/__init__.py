"""sinterdem: a coupled thermo-mechanical simulator of powder sintering, from Python.

The package calls the same Rust library as the ``sinterdem`` command line (which the wheel also
installs): a :class:`Case` is a case file plus ``--set`` overrides, :func:`run` is
``sinterdem run``, :func:`study` is ``sinterdem study``, :func:`calibrate` is
``sinterdem calibrate``. Errors are exceptions by class (:class:`ConfigError`,
:class:`ModelError`, :class:`SolveError`, :class:`IoError`, all :class:`Error`) with the
command line's text. See docs/python.md.

>>> import sinterdem
>>> case = sinterdem.Case.load("cases/pair-copper.toml")
>>> case["time.end"] = 600
>>> res = sinterdem.run(case, progress=False)
>>> res.summary["neck_ratio"], res.series["time_s"].iloc[-1]
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Union

from . import _native
from ._errors import ConfigError, Error, IoError, ModelError, SolveError

__all__ = [
    "Case", "RunResult", "CalibrationResult", "run", "study", "calibrate", "read_csv",
    "Error", "ConfigError", "ModelError", "SolveError", "IoError", "__version__",
]
__version__ = _native.__version__

PathLike = Union[str, "os.PathLike[str]"]


def _pandas():
    try:
        import pandas  # noqa: F401
    except ImportError:
        return None
    return pandas


def read_csv(path: PathLike, frame: Optional[bool] = None):
    """Reads a CSV that sinterdem wrote (``series.csv``, ``study.csv``, …).

    Numbers are parsed exactly as Rust wrote them (float64). Returns a pandas DataFrame when
    pandas is importable (or ``frame=True``), else a dict of column name → numpy array (text
    columns: lists of str).
    """
    names, cols = _native.read_csv(os.fspath(path))
    data = dict(zip(names, cols))
    pd = _pandas() if frame is not False else None
    if frame and pd is None:
        raise ImportError("pandas is not installed: pip install pandas")
    return pd.DataFrame(data, columns=names) if pd is not None else data


class Case:
    """A case: a case file's content plus ``--set`` overrides, in order.

    Build one with :meth:`Case.load` (a file; relative paths in it start at its folder),
    :meth:`Case.from_dict` or :meth:`Case.from_toml`. ``case["time.end"] = 60`` is exactly
    ``--set time.end=60`` (array elements by index, ``case["materials.0.name"]``); a dict value
    replaces the whole table (``case["thermal.furnace.profile"] = {"constant": 1293.0}``).
    ``case[key]`` reads a value of the case with its overrides.
    """

    def __init__(self, core: "_native.CaseCore") -> None:
        self._core = core

    @classmethod
    def load(cls, path: PathLike) -> "Case":
        """Reads a case file (TOML, SI units), as ``sinterdem run FILE`` does."""
        return cls(_native.CaseCore.load(os.fspath(path)))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], base_dir: Optional[PathLike] = None) -> "Case":
        """A case from a dict of the case file's tables; relative paths start at ``base_dir`` (default: the working directory)."""
        return cls(_native.CaseCore.from_dict(dict(d), os.fspath(base_dir or ".")))

    @classmethod
    def from_toml(cls, text: str, base_dir: Optional[PathLike] = None) -> "Case":
        """A case from TOML text; relative paths start at ``base_dir`` (default: the working directory)."""
        return cls(_native.CaseCore.from_toml(text, os.fspath(base_dir or ".")))

    @staticmethod
    def preset_material(name: str) -> Dict[str, Any]:
        """A bundled material (``"copper"``, ``"titanium"``) as a dict to edit and put in a case's ``materials`` list."""
        return _native.CaseCore.preset_material(name)

    def __setitem__(self, key: str, value: Any) -> None:
        self._core.set(key, value)

    def __getitem__(self, key: str) -> Any:
        return self._core.get(key)

    def __contains__(self, key: str) -> bool:
        try:
            self._core.get(key)
        except KeyError:
            return False
        return True

    def set(self, key: str, value: Any) -> "Case":
        """``case[key] = value``, returning the case (for chaining)."""
        self._core.set(key, value)
        return self

    def copy(self) -> "Case":
        """An independent copy (overrides included)."""
        return Case(self._core.copy())

    def check(self) -> str:
        """Validates the case as ``sinterdem check`` does (parse, ranges, scene) without running; returns its one-line description or raises :class:`ConfigError`."""
        return self._core.check()

    def to_toml(self) -> str:
        """The case with its overrides as TOML text (runnable with ``sinterdem run``)."""
        return self._core.to_toml()

    def to_dict(self) -> Dict[str, Any]:
        """The case with its overrides as a dict."""
        return self._core.to_dict()

    @property
    def overrides(self) -> List[str]:
        """The overrides so far, as the command line's ``--set`` arguments."""
        return list(self._core.overrides)

    @property
    def path(self) -> Optional[Path]:
        """The case file, when loaded from one."""
        p = self._core.path
        return Path(p) if p is not None else None

    @property
    def kind(self) -> str:
        """``kind`` of the case (default ``heat``)."""
        return self["kind"] if "kind" in self else "heat"

    def __repr__(self) -> str:
        src = f"{self.path}" if self.path else "<dict/text>"
        return f"Case({src}, kind={self.kind!r}, overrides={self.overrides!r})"


class RunResult:
    """What :func:`run` returns.

    - ``summary``: dict, the fields of ``out/summary.json``;
    - ``series``: ``out/series.csv`` as a pandas DataFrame (a dict of numpy arrays without pandas);
    - ``out``: the output directory (a temporary one, removed with this object, when ``run`` got ``out=None``);
    - ``warnings``: the run's warnings (``warning:`` lines of ``out/log.txt``);
    - ``kind``, ``wall_seconds``.
    """

    def __init__(self, out: Path, kind: str, wall_seconds: float, tmp: Optional[tempfile.TemporaryDirectory] = None) -> None:
        self.out = out
        self.kind = kind
        self.wall_seconds = wall_seconds
        self._tmp = tmp
        self._series = None
        with open(out / "summary.json", encoding="utf-8") as f:
            self.summary: Dict[str, Any] = json.load(f)
        log = out / "log.txt"
        lines = log.read_text(encoding="utf-8").splitlines() if log.exists() else []
        self.warnings: List[str] = [ln[len("warning: "):] for ln in lines if ln.startswith("warning: ")]

    @property
    def series(self):
        """``series.csv`` (one row per step or output time) as a DataFrame or a dict of numpy arrays."""
        if self._series is None:
            self._series = read_csv(self.out / "series.csv")
        return self._series

    def __repr__(self) -> str:
        return f"RunResult(kind={self.kind!r}, out={str(self.out)!r}, wall_seconds={self.wall_seconds:.3g})"


def _as_case(case: Union[Case, Mapping[str, Any], PathLike]) -> Case:
    if isinstance(case, Case):
        return case
    if isinstance(case, Mapping):
        return Case.from_dict(case)
    return Case.load(case)


def run(case: Union[Case, Mapping[str, Any], PathLike], out: Optional[PathLike] = None, progress: bool = True,
        threads: Optional[int] = None) -> RunResult:
    """Runs a case of any kind, as ``sinterdem run CASE --out OUT``, and returns a :class:`RunResult`.

    ``case`` is a :class:`Case`, a dict or a case file path. ``out=None`` writes into a
    temporary directory that lives as long as the result. ``progress`` shows the progress bar
    (on a terminal). ``threads`` limits the run to that many threads (default: all cores). The
    GIL is released while the run computes. Raises :class:`ConfigError`, :class:`ModelError`,
    :class:`SolveError` or :class:`IoError`.
    """
    c = _as_case(case)
    tmp = None
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="sinterdem-")
        out_path = Path(tmp.name)
    else:
        out_path = Path(out)
    kind, wall = c._core.run(os.fspath(out_path), progress, threads)
    return RunResult(out_path, kind, wall, tmp)


def _file_for(spec: Union[Mapping[str, Any], PathLike], out: Path, name: str) -> str:
    """A study or calibration given as a dict is written as TOML into ``out`` (relative paths in it then start at the working directory: write them absolute)."""
    if isinstance(spec, Mapping):
        out.mkdir(parents=True, exist_ok=True)
        text = _native.dump_toml(dict(spec))
        p = out / name
        p.write_text(text, encoding="utf-8")
        return os.fspath(p)
    return os.fspath(spec)


def study(path_or_dict: Union[Mapping[str, Any], PathLike], out: PathLike, engine: str = "local", jobs: Optional[int] = None,
          progress: bool = True, overrides: Optional[List[str]] = None):
    """Runs a study (``sinterdem study FILE --out OUT --engine ENGINE --jobs JOBS``) and returns ``study.csv``.

    ``path_or_dict``: a study file, or a dict of one (``base`` and ``cases`` paths in a dict
    resolve from ``out``: give them absolute). ``engine``: ``"local"`` or ``"slurm"`` (waits for
    the array). A study is resumable: calling it again runs only what is missing. Returns a
    DataFrame (dict of arrays without pandas) with one row per run.
    """
    out = Path(out)
    f = _file_for(path_or_dict, out, "study-input.toml")
    d = _native.study(f, os.fspath(out), engine, jobs, progress, list(overrides or []))
    return read_csv(Path(d) / "study.csv")


class CalibrationResult:
    """What :func:`calibrate` returns, read back from the files ``sinterdem calibrate`` writes.

    - ``parameters``: DataFrame indexed by key (value, sigma, unit, log, sigma_log10, min, max, start);
    - ``sigma``: DataFrame indexed by key (sigma, sigma_log10);
    - ``correlation``: DataFrame, keys × keys;
    - ``material``: the calibrated ``[[materials]]`` entry as a dict, ready for a case's ``materials`` list;
    - ``report``: the whole ``calibration.json``; ``out``: the directory.
    """

    def __init__(self, out: Path) -> None:
        import pandas as pd

        self.out = out
        with open(out / "calibration.json", encoding="utf-8") as f:
            self.report: Dict[str, Any] = json.load(f)
        order = self.report["parameter_order"]
        self.parameters = pd.DataFrame.from_dict(self.report["parameters"], orient="index").loc[order]
        cols = [c for c in ("sigma", "sigma_log10") if c in self.parameters.columns]
        self.sigma = self.parameters[cols].copy()
        self.correlation = pd.DataFrame(self.report["correlation"], index=order, columns=order)
        text = (out / "material.toml").read_text(encoding="utf-8")
        self.material_file: Dict[str, Any] = _native.parse_toml(text, os.fspath(out / "material.toml"))
        mats = self.material_file.get("materials", [])
        self.material: Dict[str, Any] = mats[0] if mats else {}
        self.chi2 = self.report.get("chi2")
        self.warnings: List[str] = list(self.report.get("warnings", []))

    def __repr__(self) -> str:
        return f"CalibrationResult(out={str(self.out)!r}, chi2={self.chi2!r}, parameters={list(self.parameters.index)!r})"


def calibrate(path_or_dict: Union[Mapping[str, Any], PathLike], out: PathLike, overrides: Optional[List[str]] = None,
              quiet: bool = True) -> CalibrationResult:
    """Fits a calibration file (``sinterdem calibrate FILE --out OUT``, docs/calibration.md); needs pandas.

    Returns a :class:`CalibrationResult` with ``parameters``, ``sigma``, ``correlation``
    (DataFrames) and ``material`` (a dict for a case's ``materials`` list).
    """
    out = Path(out)
    f = _file_for(path_or_dict, out, "calibration-input.toml")
    _native.calibrate(f, os.fspath(out), list(overrides or []), quiet)
    return CalibrationResult(out)
