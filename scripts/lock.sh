#!/usr/bin/env bash
# Refresh requirements.lock and, with it, the scenario hashes: one command.
#
# The lock holds the exact versions, with their SHA-256 hashes, that
# scripts/setup.sh installs (pyproject's dependencies + the test, dev, sweep and
# docs extras, for Python 3.11 on Linux x86_64), resolved with uv 0.13 against the
# package index pip is configured with. Other numpy/scipy/numba versions may
# change the recorded bytes, so the command then reinstalls .venv from the new
# lock and rewrites test/data/scenario_hashes.txt from every shipped scenario
# (about 10 minutes); commit both.
#
#   scripts/lock.sh                      # re-resolve, keeping the locked versions that still fit
#   scripts/lock.sh --upgrade            # move every package to its newest fitting version
#   SKIP_HASHES=1 scripts/lock.sh ...    # the lock only (the hashes by hand later)
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
tools=.venv-lock
[ -x "$tools/bin/uv" ] || { "$PY" -m venv "$tools" && "$tools/bin/python" -m pip install -q 'uv==0.13.9'; }
"$tools/bin/uv" pip compile pyproject.toml \
  --extra test --extra dev --extra sweep --extra docs \
  --python-version 3.11 --python-platform x86_64-unknown-linux-gnu \
  --generate-hashes \
  --custom-compile-command 'scripts/lock.sh' \
  -o requirements.lock "$@"
echo "requirements.lock written"
[ "${SKIP_HASHES:-0}" = 1 ] && exit 0
scripts/setup.sh
hashes=test/data/scenario_hashes.txt
versions=$(.venv/bin/python -c 'import numpy, scipy, numba; print(f"numpy {numpy.__version__}, scipy {scipy.__version__}, numba {numba.__version__}")')
{
  grep '^#' "$hashes"
  echo "# refreshed by scripts/lock.sh on $(date -u +%F) with $versions"
  .venv/bin/python scripts/scenario_hashes.py
} > "$hashes.new"
mv "$hashes.new" "$hashes"
echo "$hashes rewritten; git diff shows what the new versions changed"
