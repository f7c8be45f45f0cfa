#!/usr/bin/env bash
# Set up (first time only) and run the whole test suite (unit, ROS, integration).
#
# With arguments: pytest with those arguments. Without: test/unit on every core
# (pytest-xdist; no test there starts ROS or measures time), then test/ros and
# test/integration one test at a time (their nodes' timing is the cores').
# Both parts always run; the exit code is the first failing part's.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
if [ $# -gt 0 ]; then
  exec .venv/bin/python -m pytest "$@"
fi
status=0
.venv/bin/python -m pytest -n auto test/unit || status=$?
.venv/bin/python -m pytest test/ros test/integration || { code=$?; [ "$status" -ne 0 ] || status=$code; }
exit "$status"
