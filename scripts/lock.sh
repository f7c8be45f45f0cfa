#!/usr/bin/env bash
# Refresh requirements.lock: the exact versions, with their SHA-256 hashes, that
# scripts/setup.sh installs (pyproject's dependencies + the test, dev and sweep
# extras, for Python 3.11 on Linux x86_64), resolved with uv 0.13.
#
#   scripts/lock.sh             # re-resolve, keeping the locked versions that still fit
#   scripts/lock.sh --upgrade   # move every package to its newest fitting version
#
# Then: scripts/setup.sh (reinstalls .venv from the new lock) and
#   .venv/bin/python scripts/scenario_hashes.py > test/data/scenario_hashes.txt
# since other numpy/scipy/numba versions may change the recorded bytes.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
tools=.venv-lock
[ -x "$tools/bin/uv" ] || { "$PY" -m venv "$tools" && "$tools/bin/python" -m pip install -q 'uv==0.13.9'; }
"$tools/bin/uv" pip compile pyproject.toml \
  --extra test --extra dev --extra sweep \
  --python-version 3.11 --python-platform x86_64-unknown-linux-gnu \
  --generate-hashes --index-url https://pypi.org/simple \
  --custom-compile-command 'scripts/lock.sh' \
  -o requirements.lock "$@"
echo "requirements.lock written; now run scripts/setup.sh, then" \
  ".venv/bin/python scripts/scenario_hashes.py > test/data/scenario_hashes.txt" \
  "(and commit both if the hashes changed)"
