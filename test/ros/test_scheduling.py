"""Realtime scheduling of a node's threads (``realtime.scheduling.fifo_this_thread``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

# Run in a child: the test process itself must not end up under SCHED_FIFO.
PROBE = """
import json, os, sys, threading
from servo_axis.realtime.scheduling import fifo_this_thread, thread_policies
before = threading.Thread(target=threading.Event().wait, args=(5,), name="before", daemon=True)
before.start()
got = fifo_this_thread(int(sys.argv[1]))
after = threading.Thread(target=threading.Event().wait, args=(5,), name="after", daemon=True)
after.start()
policies = {int(t): os.sched_getscheduler(int(t)) for t in os.listdir("/proc/self/task")}
me = threading.get_native_id()
print(json.dumps({"got": got, "mine": policies.pop(me), "others": sorted(set(policies.values())),
                  "threads": thread_policies()}))
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


def test_only_the_calling_thread_gets_the_priority_threads_made_later_do_not() -> None:
    got = probe(7)
    if fifo_permitted():
        assert got["got"] == {"policy": "fifo", "priority": 7}
        # SCHED_RESET_ON_FORK is or-ed into the policy the kernel reports.
        assert got["mine"] & ~os.SCHED_RESET_ON_FORK == os.SCHED_FIFO
        assert got["others"] == [os.SCHED_OTHER]  # "before" and "after"
        assert len(got["threads"]["fifo"]) == 1
        assert len(got["threads"]["other"]) >= 2  # "before" and "after" (named "python")
    else:
        assert got["got"]["policy"] == "other" and "refused" in got["got"]
        assert got["mine"] == os.SCHED_OTHER and got["others"] == [os.SCHED_OTHER]
        assert "fifo" not in got["threads"]


def test_priority_zero_leaves_the_default_scheduler() -> None:
    got = probe(0)
    assert got["got"] == {"policy": "other", "priority": 0}
    assert got["mine"] == os.SCHED_OTHER and got["others"] == [os.SCHED_OTHER]
    assert list(got["threads"]) == ["other"]
