"""What the commands return: results read back from the files a run writes, with a helpful ``repr``."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Dict, List, Optional

from . import _native
from ._errors import IoError
from ._tables import read_csv, to_frame

if TYPE_CHECKING:
    import numpy as np

# summary.json fields worth a glance in a repr, in this order (those present)
_GLANCE = ("neck_ratio", "relative_density", "final_relative_density", "shrinkage", "particles", "contacts", "steps", "time_s", "end_time_s")


def _glance(summary: Dict[str, Any]) -> str:
    parts = []
    for k in _GLANCE:
        v = summary.get(k)
        if isinstance(v, float):
            parts.append(f"{k}={v:.4g}")
        elif isinstance(v, int) and not isinstance(v, bool):
            parts.append(f"{k}={v}")
    return ", ".join(parts[:4])


class RunResult:
    """What :func:`sinterdem.run` returns.

    - ``summary``: dict, the fields of ``out/summary.json``;
    - ``series``: ``out/series.csv`` as a pandas DataFrame (a dict of numpy arrays without pandas);
    - ``out``: the output directory (a temporary one, removed with this object, when ``run`` got ``out=None``);
    - ``warnings``: the run's warnings (``warning:`` lines of ``out/log.txt``; they also went
      through :mod:`warnings` as :class:`sinterdem.SinterdemWarning`);
    - ``completed``, ``stop_reason`` (from the summary), ``kind``, ``wall_seconds``;
    - ``particles(i)``, ``contacts(i)``, ``times``: the snapshots.
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
    def completed(self) -> Optional[bool]:
        """Whether the run reached its end (``summary.json`` ``completed``)."""
        return self.summary.get("completed")

    @property
    def stop_reason(self) -> Optional[str]:
        """Why the run stopped (``summary.json`` ``stop_reason``)."""
        return self.summary.get("stop_reason")

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

    def particles_frame(self, i: int = -1):
        """:meth:`particles` as one table (a DataFrame, or a dict without pandas): vectors split
        into ``x_m, y_m, z_m`` and ``ux_m, uy_m, uz_m`` columns, one row per particle."""
        return particles_table(self.particles(i))

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
        state = "completed" if self.completed else f"stopped: {self.stop_reason!r}" if self.completed is False else ""
        glance = _glance(self.summary)
        bits = ", ".join(b for b in (f"kind={self.kind!r}", state, glance, f"wall_seconds={self.wall_seconds:.3g}", f"out={str(self.out)!r}") if b)
        return f"{type(self).__name__}({bits})"


def particles_table(p: Dict[str, Any]):
    """The particle dict of a snapshot or of ``Simulation.particles`` as columns."""
    cols: Dict[str, Any] = {"id": p["ids"]}
    pos = p["positions"]
    cols.update({"x_m": pos[:, 0], "y_m": pos[:, 1], "z_m": pos[:, 2], "radius_m": p["radii"], "temperature_K": p["temperatures"]})
    disp = p["displacements"]
    cols.update({"ux_m": disp[:, 0], "uy_m": disp[:, 1], "uz_m": disp[:, 2]})
    for k, v in p.items():
        if k in ("ids", "positions", "radii", "temperatures", "displacements"):
            continue
        if getattr(v, "ndim", 1) == 2:
            for j in range(v.shape[1]):
                cols[f"{k}_{j}"] = v[:, j]
        else:
            cols[k] = v
    return to_frame(cols, list(cols))


class RveResult(RunResult):
    """What :func:`sinterdem.rve` returns: a :class:`RunResult` of the free periodic run plus

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

    def __repr__(self) -> str:
        rows = len(self.constitutive["time_s"]) if "time_s" in self.constitutive else len(next(iter(self.constitutive.values()), []))
        return f"RveResult(kind={self.kind!r}, {rows} constitutive rows, fit={sorted(self.fit)[:4]!r}, wall_seconds={self.wall_seconds:.3g}, out={str(self.out)!r})"


class GenerateResult(RunResult):
    """What :func:`sinterdem.generate` returns: a :class:`RunResult` plus ``packing``, the
    generated ``out/packing.csv`` (x, y, z, radius [m]; a case reads it with
    ``particles.source = "file"``) as a DataFrame (a dict of arrays without pandas)."""

    @property
    def packing(self):
        """``packing.csv`` as a DataFrame or a dict of numpy arrays."""
        return read_csv(self.out / "packing.csv")

    @property
    def packing_file(self) -> Path:
        """The path of ``packing.csv`` (for ``case["particles.file"]``)."""
        return self.out / "packing.csv"


class _JsonResult:
    """A JSON object a command prints, kept whole (``fields``) and readable as a dict."""

    def __init__(self, fields: Dict[str, Any]) -> None:
        self.fields = fields

    def __getitem__(self, k: str) -> Any:
        return self.fields[k]

    def __contains__(self, k: str) -> bool:
        return k in self.fields

    def keys(self):
        return self.fields.keys()

    def to_dict(self) -> Dict[str, Any]:
        return dict(self.fields)


class Conductivity(_JsonResult):
    """What :func:`sinterdem.conductivity` returns: the JSON object ``sinterdem conductivity``
    prints, every field kept (``fields``, also ``result[key]``), and

    - ``tensor``: κ_eff [W/(m K)] as a numpy (3, 3) array, the numbers the command prints bit for bit
      (with ``conductivity.quantity = "electrical"``: σ_eff [S/m]);
    - ``relative``: κ_eff/κ (or σ_eff/σ) [1], (3, 3);
    - ``quantity`` (``"thermal"`` or ``"electrical"``), ``kappa_material`` [W/(m K)] (thermal),
      ``sigma_material`` [S/m] (electrical), ``boundary``, ``warnings`` (list of str).
    """

    @property
    def quantity(self) -> str:
        return self.fields.get("quantity", "thermal")

    def _key(self, thermal: str, electrical: str) -> str:
        return electrical if self.quantity == "electrical" else thermal

    @property
    def tensor(self) -> "np.ndarray":
        import numpy as np

        return np.array(self.fields[self._key("kappa_eff_W_per_mK", "sigma_eff_S_per_m")], dtype=float)

    @property
    def relative(self) -> "np.ndarray":
        import numpy as np

        return np.array(self.fields[self._key("kappa_eff_over_kappa", "sigma_eff_over_sigma")], dtype=float)

    @property
    def kappa_material(self) -> Optional[float]:
        return self.fields.get("kappa_material_W_per_mK")

    @property
    def sigma_material(self) -> Optional[float]:
        return self.fields.get("sigma_material_S_per_m")

    @property
    def boundary(self) -> str:
        return self.fields["boundary"]

    @property
    def warnings(self) -> List[str]:
        return list(self.fields.get("warnings", []))

    def __repr__(self) -> str:
        d = self.relative.diagonal()
        extra = f", {len(self.warnings)} warning(s)" if self.warnings else ""
        if self.quantity == "electrical":
            head, bulk = "sigma_eff/sigma", f"sigma_material={self.sigma_material:.4g} S/m"
        else:
            head, bulk = "kappa_eff/kappa", f"kappa_material={self.kappa_material:.4g} W/(m K)"
        return (f"Conductivity(boundary={self.boundary!r}, {head} diagonal=[{d[0]:.4g}, {d[1]:.4g}, {d[2]:.4g}], "
                f"{bulk}, particles={self.fields.get('particles')}, contacts={self.fields.get('contacts')}{extra})")


class Neck(_JsonResult):
    """What :func:`sinterdem.neck` returns: the JSON object ``sinterdem neck`` prints
    (``a`` neck radius [m], ``a_coble`` [m], ``h_ci``, ``h_cj``, ``h_n`` [m], ``K_half_i``,
    ``K_half_j``, ``K_pair`` [W/K], ``newton_iterations``), as attributes and ``result[key]``."""

    def __getattr__(self, k: str) -> Any:
        try:
            return self.__dict__["fields"][k]
        except KeyError:
            raise AttributeError(k) from None

    def __repr__(self) -> str:
        f = self.fields
        return f"Neck(a={f['a']:.6g} m, a_coble={f['a_coble']:.6g} m, K_pair={f['K_pair']:.6g} W/K, conductance={f['conductance']!r})"


class CalibrationResult:
    """What :func:`sinterdem.calibrate` returns, read back from the files ``sinterdem calibrate`` writes.

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
        vals = ", ".join(f"{k}={v:.4g}" for k, v in self.parameters["value"].items()) if "value" in self.parameters else ""
        return f"CalibrationResult(chi2={self.chi2!r}, {vals}, out={str(self.out)!r})"
