"""Shared helpers of the Python package tests (run by scripts/test-all.sh, see docs/python.md)."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
CASES = REPO / "cases"

# Fields of summary.json that measure the machine, not the simulation.
TIMING = {"wall_seconds", "timing_seconds", "threads"}


def strip_timing(d, parent=""):
    """summary.json without its wall-time and thread-count fields (recursively; ``seconds_*``
    and, in a ``*_profile`` table, ``*_s`` fields are wall times too)."""
    if isinstance(d, dict):
        return {k: strip_timing(v, k) for k, v in d.items()
                if k not in TIMING and not k.startswith("seconds_") and not (parent.endswith("profile") and k.endswith("_s"))}
    if isinstance(d, list):
        return [strip_timing(v) for v in d]
    return d


def read_summary(out):
    with open(Path(out) / "summary.json", encoding="utf-8") as f:
        return json.load(f)


def cli_commands():
    """The command lines to compare against: the wheel's console entry point (always) and the
    Rust binary of the repository when SINTERDEM_BIN names it."""
    cmds = []
    console = Path(sys.executable).parent / "sinterdem"
    if console.exists():
        cmds.append(("console", [str(console)]))
    b = os.environ.get("SINTERDEM_BIN")
    if b:
        cmds.append(("binary", [b]))
    return cmds


def run_cli(cmd, *args, check=True):
    p = subprocess.run([*cmd, *args], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError(f"{cmd + list(args)} exited {p.returncode}: {p.stderr}")
    return p


@pytest.fixture
def repo():
    return REPO
