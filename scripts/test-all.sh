#!/usr/bin/env bash
# Runs every test: the Rust suite (unit, end-to-end, doc snippets), the Python FE validation and the
# Python package (python/run_tests.sh: pip install ./python, the wheel without cargo, pytest).
#   bash scripts/test-all.sh
set -uo pipefail
set -e
cd "$(dirname "$0")/.."
source scripts/setup.sh
features=$(sinterdem_features)
start=$(date +%s)
# The tests write nothing into the tree (docs/decisions.md "Tests leave the tree as they found
# it"): the tree's state (status, tracked changes, untracked files) before and after must agree.
tree_state() {
    git status --porcelain=v1 --untracked-files=all 2>/dev/null
    git diff --binary HEAD 2>/dev/null | sha256sum
    git ls-files --others --exclude-standard -z 2>/dev/null | xargs -0 -r sha256sum 2>/dev/null
}
tree_check=1
if ! git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
    echo "tree check SKIPPED: $(pwd) is not a git work tree (the check compares git status before and after)"
    tree_check=0
fi
[ "$tree_check" = "1" ] && tree_before=$(tree_state)
echo "== cargo build --release $features"
# shellcheck disable=SC2086
cargo build --release --quiet $features
echo "== cargo fmt --check and cargo clippy --all-targets -D warnings (allow-list in Cargo.toml [lints.clippy])"
gate_status=0
if ! cargo fmt --check >/tmp/sinterdem-fmt.log 2>&1; then
    echo "cargo fmt --check: the tree is not formatted (run cargo fmt):"; head -n 40 /tmp/sinterdem-fmt.log
    gate_status=1
fi
# shellcheck disable=SC2086
if ! cargo clippy --release --quiet --all-targets $features -- -D warnings >/tmp/sinterdem-clippy.log 2>&1; then
    echo "cargo clippy: warnings or errors:"; head -n 60 /tmp/sinterdem-clippy.log
    gate_status=1
fi
[ "$gate_status" = "0" ] && echo "fmt and clippy: clean"
echo "== SLURM: a single-node cluster on localhost for the SLURM engine tests (scripts/slurm-local.sh)"
slurm_dir=$(mktemp -d /tmp/sinterdem-slurm-XXXXXX)
set +e
bash scripts/slurm-local.sh start "$slurm_dir" 2>&1 | tail -n 5 | tee /tmp/sinterdem-slurm-start.log
slurm_status=${PIPESTATUS[0]}
set -e
if [ "$slurm_status" = "0" ]; then
    export SINTERDEM_SLURM_DIR="$slurm_dir"
    trap 'bash scripts/slurm-local.sh stop "$slurm_dir" >/dev/null 2>&1 || true' EXIT
elif [ "$slurm_status" = "77" ]; then
    reason=$(grep -o "SKIP: .*" /tmp/sinterdem-slurm-start.log | head -n 1)
    export SINTERDEM_SLURM_SKIP="${reason#SKIP: }"
    echo "SLURM engine tests SKIPPED: $SINTERDEM_SLURM_SKIP"
else
    # root with apt-get but the cluster did not come up: the SLURM test tries again and fails loudly
    echo "SLURM: scripts/slurm-local.sh start failed (exit $slurm_status); the SLURM engine test will report it"
fi
echo "== cargo test --release $features"
set +e
# shellcheck disable=SC2086
cargo test --release --no-fail-fast $features 2>&1 | tee /tmp/sinterdem-cargo-test.log
rust_status=${PIPESTATUS[0]}
set -e
# hypre's BoomerAMG solver (`mechanics.solver = "hypre"`, the `hypre` feature): its tests only,
# one more build of the crate with the feature (docs/coupled.md "hypre's BoomerAMG against our AMG")
hypre_features="--features hypre"
[ -n "$features" ] && hypre_features="${features},hypre"
echo "== hypre solver tests (cargo test --release $hypre_features --test hypre)"
if sinterdem_hypre; then
    set +e
    # shellcheck disable=SC2086
    cargo test --release --no-fail-fast $hypre_features --test hypre 2>&1 | tee /tmp/sinterdem-hypre-test.log | tee -a /tmp/sinterdem-cargo-test.log
    hypre_status=${PIPESTATUS[0]}
    set -e
    [ "$hypre_status" = "0" ] || rust_status=$hypre_status
else
    echo "hypre solver tests SKIPPED: $SINTERDEM_HYPRE_SKIP"
fi
python_status=0
echo "== Python FE validation (validation/)"
if [ -x validation/run_tests.sh ] || [ -f validation/run_tests.sh ]; then
    set +e
    SINTERDEM_BIN="$PWD/target/release/sinterdem" bash validation/run_tests.sh 2>&1 | tee /tmp/sinterdem-pytest.log
    python_status=${PIPESTATUS[0]}
    set -e
else
    echo "validation/run_tests.sh missing"; python_status=1
fi
echo "== Python package (python/: pip install ./python, maturin wheel, pytest python/tests)"
package_status=0
set +e
SINTERDEM_BIN="$PWD/target/release/sinterdem" bash python/run_tests.sh 2>&1 | tee /tmp/sinterdem-package.log
package_status=${PIPESTATUS[0]}
set -e
if [ "$package_status" = "77" ]; then
    package_status=0   # skipped: run_tests.sh printed "Python package tests SKIPPED: <why>"
fi
tree_status=0
if [ "$tree_check" = "1" ]; then
    echo "== the tree after the tests (git status --porcelain outside ignored paths, as before the run)"
    tree_after=$(tree_state)
    if [ "$tree_before" != "$tree_after" ]; then
        echo "THE TESTS CHANGED THE TREE (a test wrote into the repository; tests must write to temporary folders):"
        diff <(echo "$tree_before") <(echo "$tree_after") | head -n 40
        tree_status=1
    else
        echo "tree unchanged"
    fi
fi
set +e
passed=$(grep -Eo "[0-9]+ passed" /tmp/sinterdem-cargo-test.log | awk '{s+=$1} END {print s+0}')
failed=$(grep -Eo "[0-9]+ failed" /tmp/sinterdem-cargo-test.log | awk '{s+=$1} END {print s+0}')
py_passed=$(grep -Eo "[0-9]+ passed" /tmp/sinterdem-pytest.log 2>/dev/null | tail -n 1 | awk '{print $1+0}')
py_failed=$(grep -Eo "[0-9]+ failed" /tmp/sinterdem-pytest.log 2>/dev/null | tail -n 1 | awk '{print $1+0}')
pkg_passed=$(grep -Eo "[0-9]+ passed" /tmp/sinterdem-package.log 2>/dev/null | tail -n 1 | awk '{print $1+0}')
pkg_failed=$(grep -Eo "[0-9]+ failed" /tmp/sinterdem-package.log 2>/dev/null | tail -n 1 | awk '{print $1+0}')
pkg_note=""
grep -q "Python package tests SKIPPED" /tmp/sinterdem-package.log 2>/dev/null && pkg_note=" (SKIPPED)"
set -e
echo "== Rust: $passed passed, $failed failed; Python: ${py_passed:-0} passed, ${py_failed:-0} failed (exit $python_status); Python package: ${pkg_passed:-0} passed, ${pkg_failed:-0} failed (exit $package_status)$pkg_note; $(( $(date +%s) - start )) s"
if [ "$rust_status" != "0" ] || [ "$python_status" != "0" ] || [ "$package_status" != "0" ] || [ "$gate_status" != "0" ] || [ "$tree_status" != "0" ]; then
    echo "SOME TESTS FAILED"
    echo "$(( passed + ${py_passed:-0} + ${pkg_passed:-0} )) passed, $(( failed + ${py_failed:-0} + ${pkg_failed:-0} + (rust_status != 0 && failed == 0) + (python_status != 0 && ${py_failed:-0} == 0) + (package_status != 0 && ${pkg_failed:-0} == 0) + gate_status + tree_status )) failed"
    exit 1
fi
echo "$(( passed + ${py_passed:-0} + ${pkg_passed:-0} )) passed, 0 failed"
