#!/usr/bin/env bash
# Regenerates the key table of docs/case-file.md from the code's range tables (`sinterdem keys`).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin="${CARGO_TARGET_DIR:-target}/release/sinterdem"
SINTERDEM_KEYS_BIN="$bin" python3 - <<'PY'
import re, subprocess
doc = open("docs/case-file.md").read()
table = subprocess.run([__import__("os").environ.get("SINTERDEM_KEYS_BIN", "target/release/sinterdem"), "keys"], capture_output=True, text=True, check=True).stdout
begin = doc.index("<!-- keys:begin")
body = doc.index("\n", begin) + 1
end = doc.index("<!-- keys:end -->")
open("docs/case-file.md", "w").write(doc[:body] + table + doc[end:])
PY
