"""Cases: a case file's content plus ``--set`` overrides (docs/python.md "Cases")."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Union

from . import _logs, _native
from ._errors import ConfigError

PathLike = Union[str, "os.PathLike[str]"]

# the names an error lists: "(allowed: "a", "b")", "(keys allowed in [pair]: a, b)", "expected a or b"
_ALLOWED = re.compile(r"\((?:keys )?allowed[^:()]*: ([^()]*)\)")
_EXPECTED = re.compile(r": expected (?:one of )?([^()]+?)(?:$|\n| \()")


def _fill(e: ConfigError, key: str, value: Any) -> ConfigError:
    """Fills the fields an error raised by ``case[key] = value`` leaves empty: ``key`` and
    ``value`` as assigned, ``allowed`` and ``unit`` from the key's range (``sinterdem keys``)
    or, for a name or choice, the names the message lists (unit ``""``: not a number)."""
    if e.key is None or (key.startswith(e.key + ".") and "unknown key" in e.message):
        e.key = key
    if e.value is None:
        e.value = value
    info = _native.key_range(e.key) or _native.key_range(key)
    if e.allowed is None:
        if info is not None:
            e.allowed = info[0]
        else:
            m = _ALLOWED.search(e.message) or _EXPECTED.search(e.message)
            e.allowed = m.group(1).strip().rstrip(".") if m else "see sinterdem keys and docs/case-file.md"
    if e.unit is None:
        e.unit = info[1] if info is not None else ""
    return e


class Case:
    """A case: a case file's content plus ``--set`` overrides, in order.

    Build one with :meth:`Case.load` (a file; relative paths in it start at its folder),
    :meth:`Case.from_dict` or :meth:`Case.from_toml`. ``case["time.end"] = 60`` is exactly
    ``--set time.end=60`` (array elements by index, ``case["materials.0.name"]``); a dict value
    replaces the whole table (``case["thermal.furnace.profile"] = {"constant": 1293.0}``).
    The assignment validates the case at once, as ``sinterdem check`` does: an unknown key, a
    value out of range or a bad choice raises :class:`ConfigError` there, with ``key``,
    ``value``, ``allowed`` and ``unit`` set, and the override is not kept. ``case[key]``
    reads a value of the case with its overrides.
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
        """A preset of the materials library (:func:`sinterdem.materials` lists them: copper,
        titanium, nickel, silver, iron, tungsten, 316l, alumina, …) as a dict to edit and put in a case's ``materials`` list."""
        return _native.CaseCore.preset_material(name)

    def __setitem__(self, key: str, value: Any) -> None:
        self.set(key, value)

    def __getitem__(self, key: str) -> Any:
        return self._core.get(key)

    def __contains__(self, key: str) -> bool:
        try:
            self._core.get(key)
        except KeyError:
            return False
        return True

    def set(self, key: str, value: Any) -> "Case":
        """``case[key] = value`` (validated at once), returning the case (for chaining)."""
        try:
            self._core.set(key, value)
        except ConfigError as e:
            raise _fill(e, key, value) from None
        return self

    def copy(self) -> "Case":
        """An independent copy (overrides included)."""
        return Case(self._core.copy())

    def check(self) -> str:
        """Validates the case as ``sinterdem check`` does (parse, ranges, scene) without running;
        returns its one-line description or raises :class:`ConfigError`; its warnings go
        through :mod:`warnings` (:class:`sinterdem.SinterdemWarning`)."""
        with _logs.captured():
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
    def base_dir(self) -> Path:
        """The folder relative paths of the case start from."""
        return Path(self._core.base_dir)

    @property
    def kind(self) -> str:
        """``kind`` of the case (default ``heat``)."""
        return self["kind"] if "kind" in self else "heat"

    def __repr__(self) -> str:
        src = f"{self.path}" if self.path else "<dict/text>"
        return f"Case({src}, kind={self.kind!r}, overrides={self.overrides!r})"


CaseLike = Union[Case, Mapping[str, Any], PathLike]


def as_case(case: CaseLike) -> Case:
    """A :class:`Case` from a case, a dict (paths from the working directory) or a file path."""
    if isinstance(case, Case):
        return case
    if isinstance(case, Mapping):
        return Case.from_dict(case)
    return Case.load(case)
