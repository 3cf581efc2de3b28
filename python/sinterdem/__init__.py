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
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Tuple, Union

if TYPE_CHECKING:  # numpy is imported where it is used: the command line does not need it
    import numpy as np

from . import _native
from ._errors import ConfigError, Error, IoError, ModelError, SolveError

__all__ = [
    "Case", "RunResult", "RveResult", "CalibrationResult", "Simulation", "run", "rve", "study", "calibrate", "read_csv",
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

    @property
    def times(self) -> "np.ndarray":
        """Times [s] of the snapshots (``particles.pvd``; empty for kinds without snapshots)."""
        import numpy as np

        from . import _snapshots

        return np.array([t for t, _ in _snapshots.pvd_entries(self.out / "particles.pvd")], dtype=float)

    def _snapshot(self, name: str, i: int) -> Dict[str, "np.ndarray"]:
        from . import _snapshots

        entries = _snapshots.pvd_entries(self.out / f"{name}.pvd")
        if not entries:
            raise IoError(f"{self.out}: no {name}.pvd: this {self.kind} run wrote no snapshots (output.snapshots = 0, or a kind without VTU output)")
        try:
            return _snapshots.read_vtu(entries[i][1])
        except IndexError:
            raise IndexError(f"snapshot {i}: the run wrote {len(entries)} (res.times)") from None

    def particles(self, i: int = -1) -> Dict[str, "np.ndarray"]:
        """The particles of snapshot ``i`` (default: the last), read from ``particles_NNNNNN.vtu``.

        Keys as ``Simulation.particles``: ``ids`` (N,) int, ``positions`` (N, 3) m, ``radii``
        (N,) m, ``temperatures`` (N,) K, ``displacements`` (N, 3) m (zeros for heat runs), and
        every other point array of the file under its own name (``coordination``, ``velocity_m_per_s``, …).
        """
        import numpy as np

        a = self._snapshot("particles", i)
        n = len(a["Points"])
        d = {
            "ids": a["id"].astype(np.int64) if "id" in a else np.arange(n, dtype=np.int64),
            "positions": np.asarray(a["Points"], dtype=float).reshape(n, 3),
            "radii": a["radius_m"],
            "temperatures": a.get("temperature_K", np.full(n, np.nan)),
            "displacements": a["displacement_m"] if "displacement_m" in a else np.zeros((n, 3)),
        }
        for k, v in a.items():
            if k not in ("Points", "id", "radius_m", "temperature_K", "displacement_m", "connectivity", "offsets", "types"):
                d[k] = v
        return d

    def contacts(self, i: int = -1) -> Dict[str, "np.ndarray"]:
        """The contacts of snapshot ``i`` (default: the last), read from ``contacts_NNNNNN.vtu``.

        Keys as ``Simulation.contacts``: ``pairs`` (M, 2) int, ``neck_radii`` (M,) m, ``forces``
        (M,) N (the applied load's normal force; zeros for heat runs), and every other cell
        array under its own name (``contact_shrinkage``, ``conductance_W_per_K``, …).
        """
        import numpy as np

        a = self._snapshot("contacts", i)
        pa, pb = a["particle_a"], a["particle_b"]
        m = len(pa)
        d = {
            "pairs": np.stack([pa, pb], axis=1).astype(np.int64).reshape(m, 2),
            "neck_radii": a["neck_radius_m"],
            "forces": a["normal_force_N"] if "normal_force_N" in a else np.zeros(m),
        }
        for k, v in a.items():
            if k not in ("Points", "particle_a", "particle_b", "neck_radius_m", "normal_force_N", "connectivity", "offsets", "types"):
                d[k] = v
        return d

    def __repr__(self) -> str:
        return f"RunResult(kind={self.kind!r}, out={str(self.out)!r}, wall_seconds={self.wall_seconds:.3g})"


def _as_case(case: Union[Case, Mapping[str, Any], PathLike]) -> Case:
    if isinstance(case, Case):
        return case
    if isinstance(case, Mapping):
        return Case.from_dict(case)
    return Case.load(case)


def _run_command(command: str, case: Union[Case, Mapping[str, Any], PathLike], out: Optional[PathLike], progress: bool,
                 threads: Optional[int]):
    c = _as_case(case)
    tmp = None
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="sinterdem-")
        out_path = Path(tmp.name)
    else:
        out_path = Path(out)
    line = _ProgressLine.make(progress)
    try:
        kind, wall, interrupted = getattr(c._core, command)(os.fspath(out_path), progress, threads, line)
    finally:
        if line is not None:
            line.close()
    if interrupted:
        raise KeyboardInterrupt(f"sinterdem.{command} interrupted: the outputs in {out_path} are written (summary.json: completed = false)")
    return out_path, kind, wall, tmp


def run(case: Union[Case, Mapping[str, Any], PathLike], out: Optional[PathLike] = None, progress: bool = True,
        threads: Optional[int] = None) -> RunResult:
    """Runs a case of any kind, as ``sinterdem run CASE --out OUT``, and returns a :class:`RunResult`.

    ``case`` is a :class:`Case`, a dict or a case file path. ``out=None`` writes into a
    temporary directory that lives as long as the result. ``progress`` shows the progress bar
    (on a terminal). ``threads`` limits the run to that many threads (default: all cores). The
    GIL is released while the run computes. Raises :class:`ConfigError`, :class:`ModelError`,
    :class:`SolveError` or :class:`IoError`.
    """
    return RunResult(*_run_command("run", case, out, progress, threads))


class RveResult(RunResult):
    """What :func:`rve` returns: a :class:`RunResult` of the free periodic run plus

    - ``constitutive``: ``out/constitutive.csv`` (one row per ``rve.at`` time: relative density,
      sintering stress [Pa], bulk and uniaxial viscosities [Pa s], viscous Poisson ratio,
      conductivity tensor [W/(m K)]; docs/rve.md "Output") as a DataFrame (a dict of numpy arrays
      without pandas);
    - ``fit``: dict, ``out/fit.json`` (the continuum law fitted to the table).
    """

    def __init__(self, out: Path, kind: str, wall_seconds: float, tmp: Optional[tempfile.TemporaryDirectory] = None) -> None:
        super().__init__(out, kind, wall_seconds, tmp)
        with open(out / "fit.json", encoding="utf-8") as f:
            self.fit: Dict[str, Any] = json.load(f)
        self._constitutive = None

    @property
    def constitutive(self):
        """``constitutive.csv`` as a DataFrame or a dict of numpy arrays."""
        if self._constitutive is None:
            self._constitutive = read_csv(self.out / "constitutive.csv")
        return self._constitutive


def rve(case: Union[Case, Mapping[str, Any], PathLike], out: Optional[PathLike] = None, progress: bool = True,
        threads: Optional[int] = None) -> RveResult:
    """The constitutive data of a periodic compact, as ``sinterdem rve CASE --out OUT`` (docs/rve.md):
    the free run, branch runs under small stress perturbations at ``rve.at``, then
    ``constitutive.csv``, ``fit.json``, plots and ``summary.json``. Arguments and errors as
    :func:`run`; returns an :class:`RveResult`.
    """
    return RveResult(*_run_command("rve", case, out, progress, threads))


def _in_notebook() -> bool:
    """Whether we run in a Jupyter kernel (stderr is then the notebook's, not a terminal)."""
    return "ipykernel" in sys.modules and not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty())


class _ProgressLine:
    """The plain updating progress line of a notebook (the Rust bar draws on a terminal only)."""

    def __init__(self) -> None:
        self.last = ""

    @classmethod
    def make(cls, progress: bool) -> Optional["_ProgressLine"]:
        return cls() if progress and _in_notebook() else None

    def __call__(self, t: float, end: float) -> None:
        pct = 100.0 * t / end if end > 0 else 100.0
        text = f"sinterdem: t = {t:.6g} s of {end:.6g} s ({pct:5.1f} %)"
        if text != self.last:
            sys.stderr.write("\r" + text)
            sys.stderr.flush()
            self.last = text

    def close(self) -> None:
        if self.last:
            sys.stderr.write("\n")
            sys.stderr.flush()


class Simulation:
    """A heat, compact or explicit_sinter run one step at a time (Yade's ``O.step()`` / ``PyRunner`` use).

    ``sim = Simulation(case, out=None)`` prepares the case and writes the outputs due at t = 0
    (``out=None``: a temporary directory that lives with ``sim`` and its result). Then:

    - ``sim.step()``: one accepted step (the outputs due in it are written); returns whether the
      run goes on; ``sim.advance(to=t)`` steps until the time reaches ``t`` [s] (steps are never
      shortened for it, so a stepped run is the uninterrupted run, bit for bit);
    - ``sim.time`` [s], ``sim.steps``, ``sim.end`` [s], ``sim.done``, ``sim.relative_density``
      (compact; explicit_sinter: the solid fraction of the sample being advanced);
      ``sim.stage`` (explicit_sinter: ``(stage, pressure [Pa], t_sinter [s] or None)``);
    - explicit_sinter: one step is one explicit step of the sample the protocol is advancing (the
      trunk, or the branch that cools and is compressed); ``sim.time`` is that sample's time, so
      it goes back when a branch is finished and restarts at 0 for each pressure, and ``sim.end``
      is the end of the longest branch (docs/python.md);
    - ``sim.particles`` / ``sim.contacts``: dicts of numpy arrays of the state now (copies, SI
      units; docs/python.md gives their cost);
    - ``sim.set_furnace_temperature(T)`` [K]: the furnace held at T from now on (the same as
      the furnace profile written as a table with a jump now);
      ``sim.set_applied_stress(sigma)`` [Pa]: the same for a compact's ``[load]`` (an
      explicit_sinter run has neither: its temperature history is its protocol and its wall
      pressures are its list of experiments: :class:`ConfigError`);
    - ``sim.run(callback=f, every=n)``: steps to the end, calling ``f(sim)`` every ``n`` steps;
      ``f`` returning ``False`` stops the run (``stop_reason = "stopped by the callback"``);
    - ``sim.finish()``: writes ``summary.json`` and returns a :class:`RunResult` (a run not at
      its end time is marked ``completed = false``, ``stop_reason = "stopped by the caller"``).

    Steps run with the GIL released. Ctrl-C during a step stops the run after that step, writes
    the outputs (``completed = false``, ``stop_reason = "interrupted"``) and raises
    ``KeyboardInterrupt``. Also a context manager: ``with Simulation(case) as sim: …`` finishes on exit.
    """

    def __init__(self, case: Union[Case, Mapping[str, Any], PathLike], out: Optional[PathLike] = None, progress: bool = False) -> None:
        c = _as_case(case)
        self._tmp = None
        if out is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="sinterdem-")
            self.out = Path(self._tmp.name)
        else:
            self.out = Path(out)
        self.case = c
        self._line = _ProgressLine.make(progress)
        self._core = _native.SimulationCore(c._core, os.fspath(self.out), progress, self._line)
        self.kind: str = self._core.kind
        self.result: Optional[RunResult] = None
        self._final: Optional[tuple] = None  # (time, steps, end, relative density) once finished

    def _guard(self, f, *args):
        try:
            return f(*args)
        except KeyboardInterrupt:
            self.finish()
            raise

    def step(self) -> bool:
        """One accepted step; returns ``True`` while the run goes on."""
        return self._guard(self._core.step)

    def advance(self, to: float) -> bool:
        """Steps until ``time >= to`` [s] or the end; returns ``True`` while the run goes on."""
        return self._guard(self._core.advance, float(to))

    def run(self, callback: Optional[Callable[["Simulation"], Any]] = None, every: int = 1) -> "RunResult":
        """Steps to the end, calling ``callback(self)`` every ``every`` steps (and once at the
        start); a callback returning ``False`` stops the run there. Returns :meth:`finish`."""
        if every < 1:
            raise ConfigError(f"every = {every}: expected a number of steps >= 1", key="every", value=every, allowed="[1, inf)")
        going = not self.done
        if callback is not None and going and callback(self) is False:
            return self._stop_by_callback()
        while going:
            going = self._guard(self._core.steps, int(every)) if callback is not None else self._guard(self._core.steps, 1 << 62)
            if callback is not None and callback(self) is False and going:
                return self._stop_by_callback()
        return self.finish()

    def _stop_by_callback(self) -> "RunResult":
        self._core.stop("stopped by the callback")
        return self.finish()

    @property
    def time(self) -> float:
        """Current time [s]."""
        return self._final[0] if self._final else self._core.time

    @property
    def steps(self) -> int:
        """Accepted steps so far."""
        return self._final[1] if self._final else self._core.step_count

    @property
    def end(self) -> float:
        """End time of the case [s]."""
        return self._final[2] if self._final else self._core.end

    @property
    def done(self) -> bool:
        """Whether the run is over (only :meth:`finish` is left)."""
        return self.result is not None or self._core.done

    @property
    def relative_density(self) -> Optional[float]:
        """Relative density of the compact now [1] (``None`` for heat runs)."""
        return self._final[3] if self._final else self._core.relative_density

    @property
    def stage(self) -> Optional[Tuple[str, float, Optional[float]]]:
        """explicit_sinter: where the protocol is, ``(stage, pressure [Pa], t_sinter [s] or None)``,
        stage one of ``prepare``, ``heat``, ``sinter``, ``cool``, ``compress``, ``done``; ``None``
        for heat and compact runs."""
        return self._final[4] if self._final else self._core.stage

    @property
    def particles(self) -> Dict[str, "np.ndarray"]:
        """The particles now: ``ids`` (N,) int64, ``positions`` (N, 3) m, ``radii`` (N,) m,
        ``temperatures`` (N,) K, ``displacements`` (N, 3) m (a copy)."""
        return self._core.particles()

    @property
    def contacts(self) -> Dict[str, "np.ndarray"]:
        """The contacts now: ``pairs`` (M, 2) int64, ``neck_radii`` (M,) m, ``forces`` (M,) N (a copy)."""
        return self._core.contacts()

    def set_furnace_temperature(self, temperature: float) -> None:
        """Holds the furnace (gas and walls; isothermal runs: every particle) at ``temperature`` [K] from now on."""
        self._core.set_furnace_temperature(float(temperature))

    def set_applied_stress(self, stress: float) -> None:
        """Holds the applied stress of a compact's ``[load]`` at ``stress`` [Pa] (compressive positive) from now on."""
        self._core.set_applied_stress(float(stress))

    def finish(self) -> "RunResult":
        """Writes ``summary.json`` (and the plots) and returns the :class:`RunResult`; later calls return the same result."""
        if self.result is None:
            self._final = (self._core.time, self._core.step_count, self._core.end, self._core.relative_density, self._core.stage)
            wall = self._core.finish()
            if self._line is not None:
                self._line.close()
            self.result = RunResult(self.out, self.kind, wall or 0.0, self._tmp)
        return self.result

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc) -> None:
        self.finish()

    def __repr__(self) -> str:
        state = "finished" if self.result is not None else f"t = {self.time:.6g} s of {self.end:.6g} s, {self.steps} steps"
        return f"Simulation(kind={self.kind!r}, {state}, out={str(self.out)!r})"


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
