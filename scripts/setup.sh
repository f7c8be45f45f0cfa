#!/usr/bin/env bash
# Create .venv (Python 3.11) and install servo_axis with ROS 2 Jazzy from PyPI:
# the exact versions and hashes of requirements.lock (pyproject's dependencies and
# the test, dev, sweep and docs extras; refresh it with scripts/lock.sh), then the
# package itself without dependencies. Idempotent: a second call only re-checks.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
stamp=.venv/.servo_axis-installed
# The lock through uv (the version scripts/lock.sh resolves with), installed
# from PyPI into its own venv: 19 s against pip's 57-104 s on the 2-core host
# measured (1.3 GB of wheels; uv unpacks and compiles the bytecode on every
# core). Where uv cannot be had, pip does the same.
install() {
  local uv=.venv-lock/bin/uv  # the one scripts/lock.sh uses
  if [ -x "$uv" ] || { "$PY" -m venv .venv-lock && .venv-lock/bin/python -m pip install -q 'uv==0.13.9'; }; then
    export VIRTUAL_ENV=$PWD/.venv
    "$uv" pip install --compile-bytecode --upgrade pip &&
      "$uv" pip install --compile-bytecode --require-hashes -r requirements.lock &&
      "$uv" pip install --no-deps --no-build-isolation -e .
  else
    .venv/bin/python -m pip install --upgrade pip &&
      .venv/bin/python -m pip install --require-hashes -r requirements.lock &&
      .venv/bin/python -m pip install --no-deps --no-build-isolation -e .
  fi
}
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ requirements.lock -nt "$stamp" ]; then
  echo "Installing servo_axis and ROS 2 Jazzy from PyPI into .venv (log: .venv/install.log) ..."
  if ! install > .venv/install.log 2>&1; then
    tail -30 .venv/install.log
    echo "installation failed; the whole log is .venv/install.log" >&2
    exit 1
  fi
  touch "$stamp"
fi
# The package's bytecode, written now: an editable install has none, and
# with PYTHONDONTWRITEBYTECODE set (as in the shell of the host measured) every node process
# of every run compiled its ~90 modules again (~0.15 s of CPU each; a 2-core
# host runs five of them per run). Only what changed is compiled again.
.venv/bin/python -m compileall -q src/servo_axis >/dev/null
