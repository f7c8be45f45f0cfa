"""Which threads of a node get a realtime priority, and when (no rclpy).

* :func:`realtime_priority`: the ``SCHED_FIFO`` priority a role asks for
  (``thread_priority`` less its ``realtime_below``);
* :func:`fifo_this_thread`: the calling thread only, with
  ``SCHED_RESET_ON_FORK``; :func:`favour_middleware_threads`: the middleware's
  receive threads just below, its other threads at a nice value;
* :class:`RealtimeScheduling`: asked for at start-up, applied once, in the
  executor's thread, on a role's first per-sample input;
* :func:`thread_policies`: who runs at which policy (a node's report, the tests).

The plant's clock thread applies its own (:class:`servo_axis.realtime.clock.ClockThread`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from typing import Any


def realtime_priority(*, mode: str, thread_priority: int, below: int | None) -> int | None:
    """The ``SCHED_FIFO`` priority a node asks for, or None for the default scheduler.

    Parameters
    ----------
    mode : str
        ``lockstep`` (nothing waits on the wall clock: None) or ``realtime``.
    thread_priority : int
        The pair's priority (the ``thread_priority`` parameter, 0-99; 0: None).
    below : int or None
        How far below the pair the node's work is (plant and feedback 0, the
        feedforward generator 1, the learning unit and the identifier 2; at
        least priority 1); None: a node that never asks (the recorder).
    """
    if below is None or mode == "lockstep" or thread_priority <= 0:
        return None
    return max(1, thread_priority - below)


def fifo_this_thread(priority: int) -> dict[str, object]:
    """Put the calling thread (only) under ``SCHED_FIFO`` at ``priority`` (1-99; 0: leave it).

    ``os.sched_setscheduler(0, ...)`` is per thread on Linux. The policy is
    set with ``SCHED_RESET_ON_FORK``, so that a thread this one creates later
    (the middleware makes some from the thread that creates an entity)
    starts at the default policy. The middleware's own threads (``dds.*``,
    made at start-up) are set by :func:`favour_middleware_threads`: only its
    receive threads get a realtime priority; a Fast DDS thread that spins at
    a realtime priority takes a core from everything below it (issue 30:
    ``dds.asyn.0.0`` at ``SCHED_FIFO`` 50 used 92 % of a core for minutes,
    the run never ended and SIGTERM did nothing). Where the system refuses
    (no ``CAP_SYS_NICE``, an ``RLIMIT_RTPRIO`` below ``priority``, not
    Linux), nothing changes and the reason is returned.

    Returns
    -------
    dict
        ``{"policy": "fifo", "priority": p}``, or ``{"policy": "other",
        "priority": 0}`` plus ``"refused": reason``.
    """
    if priority <= 0:
        return {"policy": "other", "priority": 0}
    try:
        policy = os.SCHED_FIFO | os.SCHED_RESET_ON_FORK
        os.sched_setscheduler(0, policy, os.sched_param(priority))
    except (OSError, AttributeError) as err:
        return {"policy": "other", "priority": 0, "refused": f"{type(err).__name__}: {err}"}
    return {"policy": "fifo", "priority": priority}


#: The nice value given to the middleware's threads (``dds.*``) of a node whose
#: executor thread runs under ``SCHED_FIFO``, but for its receive threads: they
#: stay ``SCHED_OTHER`` (a spinning one cannot take a core from everything
#: else), with more weight than the host's default jobs.
MIDDLEWARE_NICE = -10

#: Fast DDS's receive threads: one per shared-memory port (``dds.shm.<port>``)
#: and per UDP port (``dds.udp.<port>``) a participant listens on. Each sample
#: the executor takes was handed over by one of them: they are on the
#: per-sample path, as the executor thread is. They block in a receive call
#: while nothing comes. The port watchdog (``dds.shm.wdog``), the events thread
#: (``dds.ev.*``) and the asynchronous writer (``dds.asyn.*``, the thread that
#: spun in issue 30) are not receive threads.
RECEIVE_THREAD = re.compile(r"dds\.(shm|udp)\.\d+")


def favour_middleware_threads(nice: int = MIDDLEWARE_NICE, receive_priority: int = 0) -> int:
    """Put this process's middleware receive threads under ``SCHED_FIFO`` at
    ``receive_priority`` (``realtime.middleware_priority``; 0: leave them with
    the rest), and its other ``dds.*`` threads at the nice value ``nice`` (best effort).

    Why the receive threads get a realtime priority: at ``SCHED_OTHER`` a
    sample waits for one to be scheduled behind the host's default jobs before
    the ``SCHED_FIFO`` executor can take it. A 2 s realtime ``ptc_nominal``
    on a quiet 2-core host missed 461-914 of 2,000 deadlines with them at nice
    -10, 31-111 with them under ``SCHED_FIFO`` 49 (the bare pair of the
    floor, ``python -m servo_axis floor``, between the runs: 32-191;
    docs/explanation/realtime.md).

    Returns how many threads got their setting (0 where the system refuses or
    there is no ``/proc``).
    """
    done = 0
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return 0
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/comm") as f:
                name = f.read().strip()
            if not name.startswith("dds."):
                continue
            if receive_priority > 0 and RECEIVE_THREAD.fullmatch(name):
                policy = os.SCHED_FIFO | os.SCHED_RESET_ON_FORK
                os.sched_setscheduler(int(tid), policy, os.sched_param(receive_priority))
            else:
                os.setpriority(os.PRIO_PROCESS, int(tid), nice)
            done += 1
        except (OSError, AttributeError):
            continue
    return done


#: Scheduling policies by their number in ``/proc/<pid>/task/<tid>/stat``.
POLICY_NAMES = {0: "other", 1: "fifo", 2: "rr", 3: "batch", 5: "idle", 6: "deadline"}


def thread_policies(pid: int | str = "self") -> dict[str, list[str]]:
    """The threads of process ``pid`` by scheduling policy: ``{"fifo": [names], "other": [...]}``.

    Read from ``/proc/<pid>/task/*/stat`` (field 41, the policy) and
    ``comm`` (the thread's name); a thread that ended meanwhile is left out.
    Empty where there is no ``/proc``.
    """
    out: dict[str, list[str]] = {}
    base = f"/proc/{pid}/task"
    try:
        tids = os.listdir(base)
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"{base}/{tid}/stat") as f:
                stat = f.read()
            with open(f"{base}/{tid}/comm") as f:
                name = f.read().strip()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        policy = int(fields[41 - 3])  # fields 3.. follow "pid (comm) "
        out.setdefault(POLICY_NAMES.get(policy, str(policy)), []).append(name)
    return {k: sorted(v) for k, v in sorted(out.items())}


class RealtimeScheduling:
    """A node's realtime priority: asked for at start-up, applied once the run starts.

    Start-up (discovery, matching, loading the compiled kernels) runs at the
    default scheduler: realtime threads that saturate a small host while the
    others are still being set up can starve them (a run on 2 cores once
    never started). So the node calls :meth:`start` when its first
    per-sample input arrives, in the executor's thread: that thread (the
    per-sample callbacks) is the one put under ``SCHED_FIFO``, with
    ``SCHED_RESET_ON_FORK``, and the middleware's receive threads just below
    it; its other threads stay at the default policy
    (:func:`favour_middleware_threads`). The plant's clock thread, started
    from it, starts at the default policy and asks for its own
    (:meth:`ClockThread.start`).

    Parameters
    ----------
    priority : int or None
        From :func:`realtime_priority`; None: nothing to do.
    warn : callable
        Where a refusal is said (one line).
    apply : callable
        What applies a priority to the calling thread (:func:`fifo_this_thread`).
    favour : callable or None
        What sets the middleware's threads once ``apply`` got ``SCHED_FIFO``
        (None: :func:`favour_middleware_threads`).
    middleware_priority : int
        ``realtime.middleware_priority``: the ``SCHED_FIFO`` priority of the
        middleware's receive threads (:data:`RECEIVE_THREAD`); 0, they stay
        ``SCHED_OTHER`` as its other threads (nice :data:`MIDDLEWARE_NICE`).
    """

    def __init__(
        self,
        priority: int | None,
        *,
        warn: Callable[[str], Any],
        apply: Callable[[int], dict[str, object]] = fifo_this_thread,
        favour: Callable[[], int] | None = None,
        middleware_priority: int = 0,
    ) -> None:
        self._pending = priority
        #: The priority asked for (None: none).
        self.asked = priority
        self._warn = warn
        self._apply = apply
        # Below the executor's: a sample's first step must not preempt its last.
        self.middleware_priority = min(middleware_priority, max(0, (priority or 0) - 1))
        self._favour = favour or (
            lambda: favour_middleware_threads(receive_priority=self.middleware_priority)
        )
        #: What :meth:`start` got (``fifo_this_thread``'s answer); None before, or never asked.
        self.applied: dict[str, object] | None = None

    @property
    def fifo(self) -> bool:
        """Whether the node's executor thread runs under ``SCHED_FIFO``."""
        return self.applied is not None and self.applied["policy"] == "fifo"

    def start(self) -> None:
        """Apply the priority asked for (a warning if refused), once; later calls do nothing."""
        priority = self._pending
        if priority is None:
            return
        self._pending = None
        got = self._apply(priority)
        if got["policy"] == "fifo":
            middleware = {
                "middleware_priority": self.middleware_priority,
                "middleware_nice": MIDDLEWARE_NICE,
            }
            got = {**got, **middleware, "middleware_threads": self._favour()}
        self.applied = got
        if "refused" in got:
            self._warn(
                f"thread_priority {priority}: refused ({got['refused']}); the default scheduler"
            )
