#!/usr/bin/env bash
# Builds sinterdem (release) and runs one case:  bash scripts/run-case.sh CASE.toml [sinterdem run options]
# Results go to out/<case name>/ unless --out DIR is given.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
features=$(sinterdem_features)
# shellcheck disable=SC2086
cargo build --release --quiet $features
exec target/release/sinterdem run "$@"
