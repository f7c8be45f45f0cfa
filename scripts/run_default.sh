#!/usr/bin/env bash
# Set up (first time only) and run the default scenario end to end:
# rptc_friction_table: detailed ball screw (3 modes, 70 us dead time, rolling
# friction), friction table from cycle 1, RPTC with Q~5 from cycle 2; recorded
# to runs/<name>-<time>/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
exec .venv/bin/python -m servo_axis "$@"
