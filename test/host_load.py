"""How long a busy or slow host kept processes from running: what a wall-clock bound allows for.

A product's wall-clock promise (the feedback trips within the lease +
``input_timeout_s`` + a watchdog period) holds on a host that runs the
threads on the way when they are ready. A loaded host makes them wait for a
CPU, and Linux counts that wait for each thread: the second field of
``/proc/<pid>/task/<tid>/schedstat`` is the time (ns) the thread was
runnable but not running. Whatever the host withheld from a chain of events
through those threads is at most the sum of their waits over the window
(each instant the chain was held up, the thread holding it was waiting on a
run queue). A test adds that sum to its bound: on a quiet host the bound is
what it was; on a busy one it grows by exactly what was measured, never by a
guess.

Counted: the threads of the given processes that exist when
:meth:`RunQueueWait.seconds` is read (a thread made in the window counts
from its start). A thread that exited in the window is not counted (its
record is gone); so a process on the path must still be alive at the end.
Without schedstat (a kernel without ``CONFIG_SCHED_INFO``) the wait reads 0:
the bound is then the fixed one, and :data:`AVAILABLE` says so.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

#: Whether this kernel reports per-thread run-queue waits.
AVAILABLE = Path("/proc/self/schedstat").is_file()


def thread_waits_ns(pids: Iterable[int]) -> dict[tuple[int, int], int]:
    """Run-queue wait so far (ns) of each live thread ``(pid, tid)`` of ``pids``."""
    out = {}
    for pid in pids:
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            try:
                fields = Path(f"/proc/{pid}/task/{tid}/schedstat").read_text().split()
                out[(pid, int(tid))] = int(fields[1])
            except (OSError, IndexError, ValueError):
                continue  # exited meanwhile
    return out


def process_waits_ns(pid: int) -> int:
    """The run-queue wait so far (ns) of the live threads of ``pid``, together."""
    return sum(thread_waits_ns([pid]).values())


class RunQueueWait:
    """Seconds the threads of ``pids`` (default: this process) waited for a CPU since made.

    Parameters
    ----------
    *pids : int
        The processes on the measured path (their threads are read at
        :meth:`seconds`; add one started later with :meth:`add`).
    """

    def __init__(self, *pids: int) -> None:
        self.pids = list(pids) or [os.getpid()]
        self._start = thread_waits_ns(self.pids)

    def add(self, pid: int) -> None:
        """Count ``pid`` too, from now."""
        self.pids.append(pid)
        self._start.update(thread_waits_ns([pid]))

    def seconds(self) -> float:
        """The wait of every live thread of :attr:`pids` since it was first seen, s."""
        now = thread_waits_ns(self.pids)
        return sum(ns - self._start.get(key, 0) for key, ns in now.items()) * 1e-9


def said(elapsed_s: float, bound_s: float, wait_s: float) -> str:
    """The line an assertion on ``elapsed_s < bound_s + wait_s`` fails with."""
    how = "" if AVAILABLE else " (this kernel reports no run-queue waits)"
    return (
        f"{elapsed_s:.3f} s against a bound of {bound_s:.3f} s + {wait_s:.3f} s that the "
        f"host kept the threads on the way waiting for a CPU{how}"
    )
