#!/usr/bin/env bash
# Set up (first time only) and run the default scenario end to end:
# PTC + PID on the nominal ball-screw, recorded to runs/<name>-<time>/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
exec .venv/bin/python -m servo_axis "$@"
