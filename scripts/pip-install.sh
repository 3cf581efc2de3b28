#!/usr/bin/env bash
# Installs the Python package (and its `sinterdem` command) into the current Python on the build of
# the README's first command:  bash scripts/pip-install.sh [pip options]
# `pip install ./python` builds the binding crate, a member of the root workspace, into the
# repository's target/ with the HDF5 choice of scripts/setup.sh (MATURIN_PEP517_ARGS="--features h5"
# when libhdf5 is there), so the sinterdem library compiled by `cargo build --release --features h5`
# is reused and only the binding (pyo3, numpy, sinterdem-python) compiles (docs/python.md
# "Install"). PYTHON names the interpreter (default: python3).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck source=scripts/setup.sh
source "$root/scripts/setup.sh"
features=$(sinterdem_features)
export MATURIN_PEP517_ARGS="${MATURIN_PEP517_ARGS:-$features}"
echo "pip-install: pip install ./python ${MATURIN_PEP517_ARGS:+(maturin $MATURIN_PEP517_ARGS) }into $(command -v "${PYTHON:-python3}")" >&2
exec "${PYTHON:-python3}" -m pip install "$@" "$root/python"
