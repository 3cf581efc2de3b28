"""Stepping a run (``Simulation``, docs/python.md "Stepping")."""

from __future__ import annotations

import math
import os
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Dict, Optional, Tuple

from . import _logs, _native
from ._case import CaseLike, as_case
from ._errors import ConfigError, Error
from ._progress import ProgressLine
from ._results import RunResult, particles_table
from ._tables import read_csv

if TYPE_CHECKING:
    import numpy as np


def _stops(answer: Any) -> bool:
    """Whether a callback's answer stops the run: any falsy value but ``None`` (``False``,
    ``np.False_``, ``0``); ``None`` (no ``return``) and truthy values go on."""
    return answer is not None and not bool(answer)


class Simulation:
    """A heat, compact or explicit_sinter run one step at a time (Yade's ``O.step()`` / ``PyRunner`` use).

    ``sim = Simulation(case, out=None)`` prepares the case and writes the outputs due at t = 0
    (``out=None``: a temporary directory that lives with ``sim`` and its result). Then:

    - ``sim.step()``: one accepted step (the outputs due in it are written); returns whether the
      run goes on; ``sim.advance(to=t)`` steps until the time reaches ``t`` [s] (steps are never
      shortened for it, so a stepped run is the uninterrupted run, bit for bit);
    - ``sim.run(callback=f, every=n)`` or ``sim.run(callback=f, every_s=t)``: steps to the end,
      calling ``f(sim)`` at the start and then every ``n`` steps or every ``t`` simulated
      seconds (at the first step that reaches each multiple of ``t``); ``f`` returning a false
      value (``False``, ``np.False_``, ``0``; not ``None``) stops the run there
      (``stop_reason = "stopped by the callback"``);
    - ``sim.time`` [s], ``sim.steps``, ``sim.end`` [s], ``sim.done``;
    - state in memory: ``sim.series`` (the rows of ``series.csv`` so far, a DataFrame),
      ``sim.relative_density`` [1] and ``sim.shrinkage`` (per axis, [1]) of a compact
      (explicit_sinter: the solid fraction of the sample being advanced), ``sim.stage``
      (explicit_sinter: ``(stage, pressure [Pa], t_sinter [s] or None)``);
    - explicit_sinter: one step is one explicit step of the sample the protocol is advancing (the
      trunk, or the branch that cools and is compressed); ``sim.time`` is that sample's time, so
      it goes back when a branch is finished and restarts at 0 for each pressure, and ``sim.end``
      is the end of the longest branch (docs/python.md);
    - ``sim.particles`` / ``sim.contacts``: dicts of numpy arrays of the state now (copies, SI
      units; docs/python.md gives their cost); ``sim.particles_frame()`` the particles as one
      table (``x_m, y_m, z_m, radius_m, temperature_K, ux_m, uy_m, uz_m``);
    - ``sim.set_furnace_temperature(T)`` [K]: the furnace held at T from now on (the same as
      the furnace profile written as a table with a jump now);
      ``sim.set_applied_stress(sigma)`` [Pa]: the same for a compact's ``[load]`` (an
      explicit_sinter run has neither: its temperature history is its protocol and its wall
      pressures are its list of experiments: :class:`ConfigError`);
    - ``sim.finish()``: writes ``summary.json`` and returns a :class:`RunResult` (a run not at
      its end time is marked ``completed = false``, ``stop_reason = "stopped by the caller"``).

    A model error raises from the ``step()``/``advance()``/``run()`` that met it, after the
    outputs are written (``summary.json`` with ``completed = false`` and the error; the
    exception's ``out`` is the directory). Steps run with the GIL released. Ctrl-C during a step
    stops the run after that step, writes the outputs (``completed = false``, ``stop_reason =
    "interrupted"``) and raises ``KeyboardInterrupt``. A ``Simulation`` is stepped from the
    thread that created it (another thread gets :class:`sinterdem.Error`). Also a context
    manager: ``with Simulation(case) as sim: …`` finishes on exit.
    """

    def __init__(self, case: CaseLike, out: Optional[os.PathLike] = None, progress: bool = False) -> None:
        c = as_case(case)
        self._thread = threading.get_ident()
        self._tmp = None
        if out is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="sinterdem-")
            self.out = Path(self._tmp.name)
        else:
            self.out = Path(out)
        self.case = c
        self._line = ProgressLine.make(progress)
        with _logs.captured():
            self._native = _native.SimulationCore(c._core, os.fspath(self.out), progress, self._line)
        self.kind: str = self._native.kind
        self.result: Optional[RunResult] = None
        self._error: Optional[Error] = None
        self._final: Optional[tuple] = None  # (time, steps, end, relative density, stage, shrinkage) once finished
        self._series_cache: Tuple[Any, Any] = (None, None)

    @property
    def _core(self):
        if threading.get_ident() != self._thread:
            raise Error(f"this Simulation was created in thread {self._thread} and is stepped from thread {threading.get_ident()}: "
                        "a Simulation is used by the thread that created it (create one per thread)")
        return self._native

    def _guard(self, f, *args):
        try:
            with _logs.captured(extra=2):
                return f(*args)
        except KeyboardInterrupt:
            self.finish()
            raise
        except Error as e:
            if self._native.finished:
                # the run ended on this error; its outputs are written, and the state it reached
                # stays readable (sim.time, sim.steps, …; None only after an internal error)
                n = self._native
                try:
                    last = (n.time, n.step_count, n.end, n.relative_density, n.stage, n.shrinkage)
                except RuntimeError:
                    last = (None, None, None, None, None, None)
                self._final = self._final or last
                self._error = e
                e.out = self.out
                e._tmp = self._tmp
            raise

    def step(self) -> bool:
        """One accepted step; returns ``True`` while the run goes on."""
        return self._guard(self._core.step)

    def advance(self, to: float) -> bool:
        """Steps until ``time >= to`` [s] or the end; returns ``True`` while the run goes on."""
        return self._guard(self._core.advance, float(to))

    def run(self, callback: Optional[Callable[["Simulation"], Any]] = None, every: Optional[int] = None,
            every_s: Optional[float] = None) -> "RunResult":
        """Steps to the end, calling ``callback(self)`` at the start and then every ``every`` steps
        (default 1) or every ``every_s`` simulated seconds; a callback returning a false value
        (``False``, ``np.False_``, ``0``; ``None`` goes on) stops the run there. Returns :meth:`finish`."""
        if every is not None and every_s is not None:
            raise ConfigError("run(every=…, every_s=…): give one of them", key="every_s", value=every_s, allowed="every or every_s", unit="s")
        if every_s is not None:
            if not (isinstance(every_s, (int, float)) and math.isfinite(every_s) and every_s > 0):
                raise ConfigError(f"every_s = {every_s!r}: expected a simulated time > 0 in s", key="every_s", value=every_s, allowed="(0, inf)", unit="s")
        n = 1 if every is None else every
        if every_s is None and (not isinstance(n, int) or isinstance(n, bool) or n < 1):
            raise ConfigError(f"every = {n!r}: expected a number of steps >= 1", key="every", value=n, allowed="[1, inf)", unit="steps")
        going = not self.done
        if callback is not None and going and _stops(callback(self)):
            return self._stop_by_callback()
        next_t = self.time + every_s if every_s is not None else None
        while going:
            if callback is None:
                going = self._guard(self._core.steps, 1 << 62)
            elif next_t is not None:
                going = self._guard(self._core.advance, next_t)
                t = self.time
                if t >= next_t:  # the next multiple after the time reached (a step may pass several)
                    next_t += every_s * (math.floor((t - next_t) / every_s) + 1)
            else:
                going = self._guard(self._core.steps, int(n))
            if callback is not None and _stops(callback(self)) and going:
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
        return self.result is not None or self._error is not None or self._core.done

    @property
    def relative_density(self) -> Optional[float]:
        """Relative density of the compact now [1] (``None`` for heat runs)."""
        return self._final[3] if self._final else self._core.relative_density

    @property
    def shrinkage(self) -> Optional["np.ndarray"]:
        """Shrinkage of the compact now per axis, 1 − L/L₀ (x, y, z) [1] (``None`` for heat and
        explicit_sinter runs): the ``shrinkage_x/y/z`` columns of ``series.csv``."""
        import numpy as np

        s = self._final[5] if self._final else self._core.shrinkage
        return None if s is None else np.array(s, dtype=float)

    @property
    def stage(self) -> Optional[Tuple[str, float, Optional[float]]]:
        """explicit_sinter: where the protocol is, ``(stage, pressure [Pa], t_sinter [s] or None)``,
        stage one of ``prepare``, ``heat``, ``sinter``, ``cool``, ``compress``, ``done``; ``None``
        for heat and compact runs."""
        return self._final[4] if self._final else self._core.stage

    @property
    def series(self):
        """The rows of ``series.csv`` so far (one per step or output time; written and flushed
        row by row) as a DataFrame (a dict of numpy arrays without pandas)."""
        path = self.out / "series.csv"
        try:
            st = path.stat()
        except FileNotFoundError:
            raise Error(f"{path}: no series yet (this {self.kind} run writes none)") from None
        key = (st.st_mtime_ns, st.st_size)
        if self._series_cache[0] != key:
            self._series_cache = (key, read_csv(path))
        return self._series_cache[1]

    def _state(self, what: str):
        if self.result is not None or self._error is not None:
            raise Error(f"sim.{what}: the simulation is finished; the last state is in its result: "
                        f"res = sim.finish(); res.{what}(-1) (the last snapshot, as a dict of numpy arrays)")
        return getattr(self._core, what)()

    @property
    def particles(self) -> Dict[str, "np.ndarray"]:
        """The particles now: ``ids`` (N,) int64, ``positions`` (N, 3) m, ``radii`` (N,) m,
        ``temperatures`` (N,) K, ``displacements`` (N, 3) m (a copy). For pandas:
        :meth:`particles_frame`."""
        return self._state("particles")

    def particles_frame(self):
        """The particles now as one table (a DataFrame; a dict without pandas): ``id``,
        ``x_m, y_m, z_m``, ``radius_m``, ``temperature_K``, ``ux_m, uy_m, uz_m``."""
        return particles_table(self.particles)

    @property
    def contacts(self) -> Dict[str, "np.ndarray"]:
        """The contacts now: ``pairs`` (M, 2) int64, ``neck_radii`` (M,) m, ``forces`` (M,) N (a copy)."""
        return self._state("contacts")

    def set_furnace_temperature(self, temperature: float) -> None:
        """Holds the furnace (gas and walls; isothermal runs: every particle) at ``temperature`` [K] from now on."""
        self._core.set_furnace_temperature(float(temperature))

    def set_applied_stress(self, stress: float) -> None:
        """Holds the applied stress of a compact's ``[load]`` at ``stress`` [Pa] (compressive positive) from now on."""
        self._core.set_applied_stress(float(stress))

    def finish(self) -> "RunResult":
        """Writes ``summary.json`` (and the plots) and returns the :class:`RunResult`; later calls
        return the same result (a run that ended on an error raises that error again)."""
        if self._error is not None:
            raise self._error
        if self.result is None:
            core = self._core
            self._final = (core.time, core.step_count, core.end, core.relative_density, core.stage, core.shrinkage)
            with _logs.captured():
                wall = core.finish()
            if self._line is not None:
                self._line.close()
            self.result = RunResult(self.out, self.kind, wall or 0.0, self._tmp)
        return self.result

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if self._error is None and (exc_type is None or self.result is None):
            try:
                self.finish()
            except Error:
                if exc_type is None:
                    raise

    def __repr__(self) -> str:
        if self.result is not None:
            state = "finished"
        elif self._error is not None:
            state = f"failed: {self._error}"
        else:
            state = f"t = {self.time:.6g} s of {self.end:.6g} s, {self.steps} steps"
            rho = self.relative_density
            if rho is not None:
                state += f", relative density {rho:.4g}"
        return f"Simulation(kind={self.kind!r}, {state}, out={str(self.out)!r})"
