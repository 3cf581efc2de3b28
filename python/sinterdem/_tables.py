"""Tables sinterdem writes (CSV) as pandas DataFrames, or dicts of numpy arrays without pandas."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Union

from . import _native

PathLike = Union[str, "os.PathLike[str]"]


def pandas_or_none():
    """pandas if importable."""
    try:
        import pandas
    except ImportError:
        return None
    return pandas


def to_frame(data: Dict[str, Any], columns: List[str], want: Optional[bool] = None):
    """``data`` as a DataFrame (pandas importable, or ``want=True``), else the dict itself."""
    pd = pandas_or_none() if want is not False else None
    if want and pd is None:
        raise ImportError("pandas is not installed: pip install pandas")
    return pd.DataFrame(data, columns=columns) if pd is not None else data


def read_csv(path: PathLike, frame: Optional[bool] = None):
    """Reads a CSV that sinterdem wrote (``series.csv``, ``study.csv``, …).

    Numbers are parsed exactly as Rust wrote them: float64, and int64 for columns of integers
    (counts). Returns a pandas DataFrame when pandas is importable (or ``frame=True``), else a
    dict of column name → numpy array (text columns: lists of str).
    """
    names, cols = _native.read_csv(os.fspath(path))
    return to_frame(dict(zip(names, cols)), names, frame)
