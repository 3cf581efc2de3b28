#!/usr/bin/env bash
# Run the Python FE validation of the conductance model (pytest, < 3 min).
# Sets up validation/.venv first (validation/setup_venv.sh, idempotent).
# The CLI comparison tests use the sinterdem binary at
# target/release/sinterdem (override with SINTERDEM_BIN); they are skipped
# only if that file does not exist. Extra arguments go to pytest.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
py="$(bash "$here/setup_venv.sh" | tail -n 1)"
export SINTERDEM_BIN="${SINTERDEM_BIN:-$root/target/release/sinterdem}"
cd "$root"
exec "$py" -m pytest validation -q -p no:cacheprovider "$@"
