"""Realtime scheduling of the per-sample pair (``nodes.realtime.fifo_every_thread``)."""

from __future__ import annotations

import json
import subprocess
import sys

# Run in a child: the test process itself must not end up under SCHED_FIFO.
PROBE = """
import json, os, sys, threading
from servo_axis.nodes.realtime import fifo_every_thread
before = threading.Thread(target=threading.Event().wait, args=(5,), daemon=True)
before.start()
got = fifo_every_thread(int(sys.argv[1]))
after = threading.Thread(target=threading.Event().wait, args=(5,), daemon=True)
after.start()
policies = {int(t): os.sched_getscheduler(int(t)) for t in os.listdir("/proc/self/task")}
print(json.dumps({"got": got, "policies": sorted(set(policies.values())),
                  "priorities": sorted({os.sched_getparam(t).sched_priority for t in policies})}))
"""

PERMITTED = """
import os
os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(7))
"""


def probe(priority: int) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", PROBE, str(priority)], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout)


def fifo_permitted() -> bool:
    return subprocess.run([sys.executable, "-c", PERMITTED], capture_output=True).returncode == 0


def test_every_thread_made_before_and_after_gets_the_priority_or_none_does() -> None:
    import os

    got = probe(7)
    if fifo_permitted():
        assert got["got"]["policy"] == "fifo" and got["got"]["priority"] == 7
        assert got["got"]["threads"] >= 2  # the main thread and the one made before
        assert got["policies"] == [os.SCHED_FIFO] and got["priorities"] == [7]
    else:
        assert got["got"]["policy"] == "other" and "refused" in got["got"]
        assert got["policies"] == [os.SCHED_OTHER] and got["priorities"] == [0]


def test_priority_zero_leaves_the_default_scheduler() -> None:
    import os

    got = probe(0)
    assert got["got"] == {"policy": "other", "priority": 0}
    assert got["policies"] == [os.SCHED_OTHER]
