#!/usr/bin/env bash
# Set up (first time only) and run the whole test suite (unit, ROS, integration).
#
# With arguments: pytest with those arguments. Without, three parts:
# 1. test/unit (no test there starts ROS or touches /dev/shm; the few that
#    time a stop of child processes allow 0.4 s or more of slack), beside
#    the `shm` tests (a SIGKILLed participant, /dev/shm checks: another
#    run's segments would count), one at a time: those mostly wait (a
#    participant's lease, a timeout) and leave a core to the unit tests.
# 2. test/ros and test/integration but the `realtime` and `shm` tests, two at
#    a time (-n 2): lockstep runs are deterministic whatever the load, and
#    each worker takes its own half of the ROS domains (test/conftest.py). A
#    module stays on one worker (--dist loadfile: its module-scoped runs are
#    made once), the longest modules first (--no-loadscope-reorder keeps the
#    order test/conftest.py gives). (Not --dist loadgroup: with pytest 9.2 it
#    ignores xdist_group, pytest-xdist issue 1386.)
# 3. The `realtime` tests (wall-clock time, mode realtime, deadline misses)
#    one at a time, alone.
# All parts always run; the exit code is the first failing part's.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
if [ $# -gt 0 ]; then
  exec .venv/bin/python -m pytest "$@"
fi
status=0
part() {
  local started=$SECONDS
  "$@" || { code=$?; [ "$status" -ne 0 ] || status=$code; }
  echo "scripts/test.sh: $((SECONDS - started)) s: $*"
}
beside() {
  # The unit tests in the background, their output in a file shown after.
  local log
  log=$(mktemp)
  .venv/bin/python -m pytest -p no:cacheprovider -n 2 test/unit >"$log" 2>&1 &
  local unit=$!
  local code=0
  "$@" || code=$?
  wait "$unit" || { [ "$code" -ne 0 ] || code=$?; }
  cat "$log"
  rm -f "$log"
  return "$code"
}
part beside .venv/bin/python -m pytest -m "shm and not realtime" test/ros test/integration
part .venv/bin/python -m pytest -n 2 --dist loadfile --no-loadscope-reorder \
  -m "not realtime and not shm" test/ros test/integration
part .venv/bin/python -m pytest -m realtime test/ros test/integration
exit "$status"
