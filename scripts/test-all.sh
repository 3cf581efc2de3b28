#!/usr/bin/env bash
# Runs every test: the Rust suite (unit, end-to-end, doc snippets) and the Python FE validation.
#   bash scripts/test-all.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
features=$(sinterdem_features)
start=$(date +%s)
echo "== cargo build --release $features"
# shellcheck disable=SC2086
cargo build --release --quiet $features
echo "== cargo test --release $features"
set +e
# shellcheck disable=SC2086
cargo test --release $features 2>&1 | tee /tmp/sinterdem-cargo-test.log
rust_status=${PIPESTATUS[0]}
set -e
python_status=0
echo "== Python FE validation (validation/)"
if [ -x validation/run_tests.sh ] || [ -f validation/run_tests.sh ]; then
    SINTERDEM_BIN="$PWD/target/release/sinterdem" bash validation/run_tests.sh || python_status=$?
else
    echo "validation/run_tests.sh missing"; python_status=1
fi
passed=$(grep -Eo "[0-9]+ passed" /tmp/sinterdem-cargo-test.log | awk '{s+=$1} END {print s+0}')
failed=$(grep -Eo "[0-9]+ failed" /tmp/sinterdem-cargo-test.log | awk '{s+=$1} END {print s+0}')
echo "== Rust: $passed passed, $failed failed; Python exit status $python_status; $(( $(date +%s) - start )) s"
if [ "$rust_status" != "0" ] || [ "$python_status" != "0" ]; then
    echo "SOME TESTS FAILED"
    exit 1
fi
echo "all tests passed"
