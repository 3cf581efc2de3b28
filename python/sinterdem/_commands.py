"""The commands of the command line as functions: run, rve, generate, study, calibrate,
conductivity, neck, materials (docs/python.md)."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any, List, Mapping, Optional, Tuple, Union

from . import _logs, _native
from ._case import CaseLike, as_case
from ._errors import ConfigError, Error
from ._progress import ProgressLine
from ._results import CalibrationResult, Conductivity, GenerateResult, Neck, RunResult, RveResult
from ._tables import read_csv, to_frame

PathLike = Union[str, "os.PathLike[str]"]


def _out_dir(out: Optional[PathLike]) -> Tuple[Path, Optional[tempfile.TemporaryDirectory]]:
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="sinterdem-")
        return Path(tmp.name), tmp
    return Path(out), None


def _run_command(command: str, case: CaseLike, out: Optional[PathLike], progress: bool, threads: Optional[int]):
    c = as_case(case)
    out_path, tmp = _out_dir(out)
    line = ProgressLine.make(progress)
    try:
        with _logs.captured(extra=1):
            kind, wall, interrupted = getattr(c._core, command)(os.fspath(out_path), progress, threads, line)
    except Error as e:
        # what the run computed up to the error is in out_path (kept alive with the exception)
        if (out_path / "log.txt").exists():
            e.out = out_path
            e._tmp = tmp
        raise
    finally:
        if line is not None:
            line.close()
    if interrupted:
        raise KeyboardInterrupt(f"sinterdem.{command} interrupted: the outputs in {out_path} are written (summary.json: completed = false)")
    return out_path, kind, wall, tmp


def run(case: CaseLike, out: Optional[PathLike] = None, progress: bool = True, threads: Optional[int] = None) -> RunResult:
    """Runs a case of any kind, as ``sinterdem run CASE --out OUT``, and returns a :class:`RunResult`.

    ``case`` is a :class:`Case`, a dict or a case file path. ``out=None`` writes into a
    temporary directory that lives as long as the result. ``progress`` shows the progress bar
    (on a terminal; a line with ETA in a notebook). ``threads`` limits the run to that many
    threads, 1 to 4 per available core (at least 16), as the command line's ``--threads``
    (default: all cores). The GIL is released while the run computes; Ctrl-C stops this run (not runs in other threads) with its outputs written and
    raises ``KeyboardInterrupt``. Warnings go through :mod:`warnings`
    (:class:`SinterdemWarning`), the log through :mod:`logging` (logger ``"sinterdem"``).
    Raises :class:`ConfigError`, :class:`ModelError`, :class:`SolveError` or
    :class:`IoError`; for an error during the run, ``e.out`` is the output directory with
    what was computed (``series.csv``, ``summary.json`` with ``completed = false``).
    """
    return RunResult(*_run_command("run", case, out, progress, threads))


def rve(case: CaseLike, out: Optional[PathLike] = None, progress: bool = True, threads: Optional[int] = None) -> RveResult:
    """The constitutive data of a periodic compact, as ``sinterdem rve CASE --out OUT`` (docs/rve.md):
    the free run, branch runs under small stress perturbations at ``rve.at``, then
    ``constitutive.csv``, ``fit.json``, plots and ``summary.json``. Arguments and errors as
    :func:`run`; returns an :class:`RveResult`.
    """
    return RveResult(*_run_command("rve", case, out, progress, threads))


def generate(case: CaseLike, out: Optional[PathLike] = None, progress: bool = True, threads: Optional[int] = None) -> GenerateResult:
    """Generates a green packing (a ``kind = "generate"`` case), as ``sinterdem generate CASE
    --out OUT`` (docs/packing.md): ``packing.csv``, ``packing.vtu``, ``summary.json``.
    Arguments and errors as :func:`run`; returns a :class:`GenerateResult` whose ``packing``
    is the table and ``packing_file`` the file a case reads (``particles.file``)."""
    c = as_case(case)
    if c.kind != "generate":
        raise ConfigError(f'kind = "{c.kind}": sinterdem.generate takes a kind = "generate" case (sinterdem.run runs the others)',
                          key="kind", value=c.kind, allowed='"generate"', unit="")
    return GenerateResult(*_run_command("run", c, out, progress, threads))


def _file_for(spec: Union[Mapping[str, Any], PathLike], out: Path, name: str) -> str:
    """A study or calibration given as a dict is written as TOML into ``out``; its relative
    paths (``base``, ``cases``, data files) start at the working directory, as a :class:`Case`
    from a dict does: they are written absolute."""
    if isinstance(spec, Mapping):
        out.mkdir(parents=True, exist_ok=True)
        text = _native.dump_toml(_absolute(dict(spec)))
        p = out / name
        p.write_text(text, encoding="utf-8")
        return os.fspath(p)
    return os.fspath(spec)


# keys of study and calibration files whose string values are paths (docs/studies.md, docs/calibration.md)
_PATH_KEYS = {"base", "case", "cases", "file", "data", "packing", "experiments"}


def _absolute(d: Any, key: str = "") -> Any:
    """``d`` with the relative paths under :data:`_PATH_KEYS` made absolute from the working directory."""
    if isinstance(d, dict):
        return {k: _absolute(v, k) for k, v in d.items()}
    if isinstance(d, list):
        return [_absolute(v, key) for v in d]
    if isinstance(d, str) and key in _PATH_KEYS and d and not os.path.isabs(d) and os.path.exists(d):
        return os.path.abspath(d)
    return d


def study(path_or_dict: Union[Mapping[str, Any], PathLike], out: PathLike, engine: str = "local", jobs: Optional[int] = None,
          progress: bool = True, overrides: Optional[List[str]] = None):
    """Runs a study (``sinterdem study FILE --out OUT --engine ENGINE --jobs JOBS``) and returns ``study.csv``.

    ``path_or_dict``: a study file, or a dict of one (its relative paths start at the working
    directory, as a :class:`Case` from a dict). ``engine``: ``"local"`` or ``"slurm"`` (waits
    for the array). ``jobs``: runs at a time, 1 to 4 per available core (at least 16), as
    ``--jobs``. A study is resumable: calling it again runs only what is missing. Returns a DataFrame (dict of arrays without
    pandas) with one row per run.
    """
    out = Path(out)
    f = _file_for(path_or_dict, out, "study-input.toml")
    with _logs.captured():
        d = _native.study(f, os.fspath(out), engine, jobs, progress, list(overrides or []))
    return read_csv(Path(d) / "study.csv")


def calibrate(path_or_dict: Union[Mapping[str, Any], PathLike], out: PathLike, overrides: Optional[List[str]] = None,
              quiet: bool = False) -> CalibrationResult:
    """Fits a calibration file (``sinterdem calibrate FILE --out OUT``, docs/calibration.md); needs pandas.

    Its progress lines go to the ``logging`` logger ``"sinterdem"`` at INFO unless ``quiet``
    (``logging.basicConfig(level="INFO")`` shows them). Returns a
    :class:`CalibrationResult` with ``parameters``, ``sigma``, ``correlation`` (DataFrames) and
    ``material`` (a dict for a case's ``materials`` list).
    """
    out = Path(out)
    f = _file_for(path_or_dict, out, "calibration-input.toml")
    with _logs.captured():
        _native.calibrate(f, os.fspath(out), list(overrides or []), quiet)
    return CalibrationResult(out)


def conductivity(case: CaseLike) -> Conductivity:
    """The steady effective conductivity tensor of a heat case's packing, as ``sinterdem
    conductivity CASE`` (docs/heat-model.md): the same JSON fields, every one kept, and
    ``tensor`` (numpy 3×3, W/(m K)) equal bit for bit to what the command prints. The
    ``[conductivity]`` table of the case chooses the method. A compact's conductivity during
    its run: ``output.conductivity_at`` of the compact case."""
    c = as_case(case)
    if c.kind != "heat":
        raise ConfigError(f'kind = "{c.kind}": conductivity is computed on a heat case\'s packing (kind = "heat"); '
                          'a compact computes it during its run at output.conductivity_at = [times]',
                          key="kind", value=c.kind, allowed='"heat"', unit="")
    with _logs.captured():
        text = c._core.conductivity()
    return Conductivity(json.loads(text))


def neck(r1: float, r2: float, overlap: float, kappa: float, kappa2: Optional[float] = None, conductance: str = "fe_fit",
         factor: float = 1.064, contact_conductance: Optional[float] = None) -> Neck:
    """Neck geometry and pipe conductance of two spheres, as ``sinterdem neck`` (SI units):
    radii ``r1``, ``r2`` [m], overlap h = r1 + r2 − d [m], conductivities ``kappa``, ``kappa2``
    [W/(m K)] (default ``kappa``), ``conductance`` law ``"fe_fit"`` (the default, as the command) or ``"linear"`` (c_K = ``factor``);
    ``contact_conductance`` in series [W/K]. Returns a :class:`Neck`."""
    with _logs.captured():
        text = _native.neck(float(r1), float(r2), float(overlap), float(kappa),
                            None if kappa2 is None else float(kappa2), str(conductance), float(factor),
                            None if contact_conductance is None else float(contact_conductance))
    return Neck(json.loads(text))


def materials(frame: Optional[bool] = None):
    """The bundled materials library (docs/materials.md), one row per preset: name, description,
    the preset's density, heat capacity, conductivity (at ``properties_at_K``), elastic
    constants, the calibrated temperature range and melting temperature [K], the number of
    diffusion phases, the source. A DataFrame indexed by nothing (a dict of lists without pandas).
    ``Case.preset_material(name)`` gives one as a case's material."""
    rows = _native.materials()
    cols = list(rows[0]) if rows else []
    return to_frame({c: [r[c] for r in rows] for c in cols}, cols, frame)
