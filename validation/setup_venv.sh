#!/usr/bin/env bash
# Idempotent: create validation/.venv and install validation/requirements.txt
# into it. Reinstalls only when the venv is missing or requirements.txt has
# changed (its sha256 is kept in validation/.venv/.requirements.sha256).
# Prints the venv's python path on the last line of stdout.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="$here/.venv"
req="$here/requirements.txt"
stamp="$venv/.requirements.sha256"
py="${PYTHON:-python3}"

want="$(sha256sum "$req" | cut -d' ' -f1)"
have=""
[[ -f "$stamp" ]] && have="$(cat "$stamp")"

if [[ ! -x "$venv/bin/python" ]]; then
    echo "setup_venv: creating $venv" >&2
    "$py" -m venv "$venv"
    have=""
fi
if [[ "$want" != "$have" ]]; then
    echo "setup_venv: installing $(basename "$req")" >&2
    "$venv/bin/python" -m pip install --disable-pip-version-check -q -r "$req" >&2
    echo "$want" > "$stamp"
else
    echo "setup_venv: $venv up to date" >&2
fi
echo "$venv/bin/python"
