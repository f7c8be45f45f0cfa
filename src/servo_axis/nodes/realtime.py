"""What a node does in realtime mode: its scheduling, the plant's clock, deadlines kept.

Nothing here imports rclpy (the numbers are :mod:`servo_axis.core.deadlines`'):

* :class:`RealtimeScheduling`: which threads of a node get a realtime
  priority, and when (:func:`realtime_priority`, :func:`fifo_this_thread`).
* :class:`ClockThread`: the thread that ticks at absolute deadlines
  ``d_j = start + j T_u`` of the monotonic clock (the plant's clock).
* :class:`ClockRecord`: a clock's ticks, its misses and the lateness of the
  ticks and of the arrivals they wait for (the plant's ``realtime`` report).
* :class:`HeldSetPoint`: the current a drive applies at a tick: the command
  of the step if it arrived by the deadline, else the newest one received.
* :class:`DriveSetPoint`: the same for a drive's set-point of no step
  (``command_source: drive_setpoint``): the newest one, whatever its stamp.
* :class:`CatchUp`: which states a node that fell behind still answers.
* :class:`LoopTimes`: the loop around an outside plant, as its feedback sees it.
"""

from __future__ import annotations

import gc
import os
import re
import sys
import threading
import time
from array import array
from collections.abc import Callable
from typing import Any

from servo_axis.core import deadlines
from servo_axis.core.errors import SignalError

#: The clock thread sleeps until this long before a deadline, then spins to
#: it, releasing the GIL (time.sleep wakes up to ~100 us late on a loaded
#: host, even with the thread's timer slack at 1 us).
SPIN_NS = 200_000
#: The same under SCHED_FIFO (``thread_priority``), where a sleep wakes within
#: tens of us: a shorter spin, because a realtime thread's busy time counts
#: against the kernel's realtime budget (95 % of each second; past it every
#: realtime thread is stopped for the remaining 50 ms).
SPIN_FIFO_NS = 50_000
#: The interpreter's switch interval while a clock runs, s: how long the
#: clock thread may wait for the GIL held by a callback (default 5 ms).
SWITCH_INTERVAL_S = 5e-5
#: A young-generation collection every this many ticks, when the next
#: deadline is at least half a period away.
GC_EVERY_TICKS = 256
#: States per window of :meth:`CatchUp.arrived`'s estimate of the clock's
#: start: the estimate follows a clock that slipped within two windows
#: (0.4-0.8 s at 0.4 ms), and is never made of a stall's backlog alone.
START_WINDOW = 1024
#: A clock that wakes later than this many periods after a deadline (and at
#: least :data:`SLIP_MIN_NS`) does not run the ticks it missed back to back
#: at its realtime priority: it slips, as ros2_control's controller manager
#: skips the periods it overran: the deadlines are re-based to the first
#: one after now, and the slip is counted (:attr:`ClockThread.slips`).
SLIP_PERIODS = 100
SLIP_MIN_NS = 50_000_000
#: ``command_source: drive_setpoint``: a tick misses its deadline when the
#: newest set-point is older than this many set-point periods then
#: (:class:`DriveSetPoint`).
SETPOINT_AGE_PERIODS = 1.5


# -- scheduling -------------------------------------------------------------------------
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


# -- the clock -------------------------------------------------------------------------
def _least_timer_slack(name: str) -> None:
    """Linux: the calling thread's sleeps end within 1 us of their time, not 50 us, and the
    thread's name is ``name`` in ``/proc`` (``ps``, :func:`thread_policies`) (best effort)."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(29, 1000, 0, 0, 0)  # PR_SET_TIMERSLACK, ns
        libc.prctl(15, ctypes.c_char_p(name.encode()[:15]), 0, 0, 0)  # PR_SET_NAME
    except (OSError, AttributeError):
        pass


class ClockThread:
    """A thread that calls ``tick(j, d_j)`` at ``d_j = start + j period`` (monotonic ns), j = 1, 2, ...

    It sleeps until shortly before each deadline, then spins to it (an rclpy
    timer slips), so the executor's callbacks never delay a tick by more
    than the interpreter's switch interval (:meth:`prepare`); the spin is
    bounded by the spin time per tick. A tick that wakes more than a period
    late runs at once with those that are due; one that wakes more than
    :data:`SLIP_PERIODS` periods late slips: the deadlines are re-based to
    the next one of the grid after now (counted in :attr:`slips`).
    The garbage collector is off while it runs (start-up objects are
    frozen, :func:`servo_axis.nodes.runtime.run_main`), with a
    young-generation collection every :data:`GC_EVERY_TICKS` ticks where
    the next deadline leaves room. It ends when ``tick`` returns True, on
    :meth:`stop`, or when ``tick`` raises (kept in :attr:`error`).

    Parameters
    ----------
    period_ns : int
        The period, ns, > 0.
    tick : callable
        ``tick(j, deadline_ns) -> bool``: True after the last one.
    name : str
        The thread's name.
    """

    def __init__(self, *, period_ns: int, tick: Callable[[int, int], bool], name: str) -> None:
        self.period_ns = period_ns
        self._tick = tick
        self._name = name
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.start_ns = 0
        #: What ``tick`` raised, if it did (the thread then ended).
        self.error: BaseException | None = None
        #: The clock thread's own scheduling (:func:`fifo_this_thread`'s answer).
        self.scheduling: dict[str, object] = {"policy": "other", "priority": 0}
        #: Times the clock slipped (:data:`SLIP_PERIODS`), and the periods it skipped.
        self.slips = 0
        self.slipped_periods = 0
        #: Monotonic ns of the last tick's start (0 before the first): a
        #: watchdog sees a clock that stalled.
        self.last_tick_ns = 0

    @staticmethod
    def prepare() -> None:
        """Before the run: the interpreter's switch interval short (:data:`SWITCH_INTERVAL_S`)."""
        sys.setswitchinterval(SWITCH_INTERVAL_S)

    @property
    def started(self) -> bool:
        return self._thread is not None

    def start(self, start_ns: int, *, priority: int = 0) -> None:
        """Start ticking from ``d_0 = start_ns`` (tick 1 at ``start_ns + period``).

        ``priority`` > 0: the clock thread puts itself (only) under
        ``SCHED_FIFO`` at it (:func:`fifo_this_thread`; :attr:`scheduling`
        says what it got), and spins less.
        """
        self.start_ns = start_ns
        self._thread = threading.Thread(
            target=self._run, args=(priority,), name=self._name, daemon=True
        )
        self._thread.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop after the tick under way (if running), waiting at most ``timeout_s``."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=timeout_s)

    def _run(self, priority: int) -> None:
        self.scheduling = fifo_this_thread(priority)
        spin_ns = SPIN_FIFO_NS if self.scheduling["policy"] == "fifo" else SPIN_NS
        period = self.period_ns
        slip_ns = max(SLIP_PERIODS * period, SLIP_MIN_NS)
        clock, sleep = time.monotonic_ns, time.sleep
        _least_timer_slack(self._name)
        gc.disable()
        try:
            tick = 1
            while not self._stop.is_set():
                deadline = self.start_ns + tick * period
                now = clock()
                if now - deadline > slip_ns:
                    # Far behind (the process was stopped, the host starved
                    # it): tick at the next deadline of the grid, not the
                    # missed ones at once.
                    skipped = (now - deadline) // period + 1
                    self.start_ns += skipped * period
                    self.slips += 1
                    self.slipped_periods += skipped
                    deadline += skipped * period
                if now < deadline:
                    pause = deadlines.sleep_s(now, deadline, spin_ns)
                    if pause > 0.0:
                        sleep(pause)
                    # The spin is bounded: at most spin_ns past the wake-up
                    # (a sleep that woke early spins no longer than that).
                    spin_end = clock() + spin_ns
                    while True:
                        t = clock()
                        if t >= deadline:
                            break
                        # Spin, but let the executor's thread have the GIL;
                        # past the spin's bound, sleep the rest.
                        sleep(0 if t < spin_end else (deadline - t) * 1e-9)
                self.last_tick_ns = clock()
                if self._tick(tick, deadline):
                    break
                tick += 1
                if tick % GC_EVERY_TICKS == 0 and deadline + period - clock() > period // 2:
                    gc.collect(0)
        except BaseException as err:  # the node reports it, in the executor's thread
            self.error = err
        finally:
            gc.enable()


#: Ticks a :class:`ClockRecord` keeps the deadline of: a command that answers
#: an older state (seconds late at 1 kHz) is timed against the grid instead.
DEADLINE_RING = 4096


class ClockRecord:
    """A realtime clock's ticks and the arrivals it waits for, against its deadlines.

    Tick ``j`` is due at ``d_j = start + j T``; the input that answers state
    ``k`` (the plant's command ``k``) is late by its arrival minus ``d_k``,
    so that later than one period is a missed deadline
    (:mod:`servo_axis.core.deadlines`). The first arrival of a step counts.

    What it keeps is the same size for a run of any length: the lateness
    of ticks and of arrivals as :class:`~servo_axis.core.deadlines.LatenessHistogram`
    (percentiles to 1 % or 0.1 us), the counts, and the deadlines and arrivals
    of the last :data:`DEADLINE_RING` ticks.

    Parameters
    ----------
    steps : int
        Steps of the run (ticks 1 .. steps, arrivals 0 .. steps - 1).
    period_ns : int
        The control period ``T``, ns.
    """

    def __init__(self, *, steps: int, period_ns: int) -> None:
        self.steps = steps
        self.period_ns = period_ns
        self.start_ns = 0
        self.misses = 0
        self.last_tick_ns = 0
        self.tick_late = deadlines.LatenessHistogram()
        self.arrival_late = deadlines.LatenessHistogram()
        #: Arrivals later than one period (deadline misses of their commands).
        self.arrivals_late = 0
        # Tick j's deadline, as the clock had it (a slip re-bases the grid), and
        # the step whose arrival was counted, for the last DEADLINE_RING ticks.
        # C int64 rings: a write keeps no Python int alive.
        self._deadline_ns = array("q", [0]) * DEADLINE_RING
        self._deadline_tick = array("q", [-1]) * DEADLINE_RING
        self._arrived_step = array("q", [-1]) * DEADLINE_RING

    def arrived(self, step: int, now_ns: int) -> None:
        """The input of ``step`` arrived at ``now_ns`` (a step outside the run, or a
        second arrival of a step, is not counted)."""
        if not 0 <= step < self.steps:
            return
        slot = step % DEADLINE_RING
        if self._arrived_step[slot] >= step:
            return
        self._arrived_step[slot] = step
        if step > 0 and self._deadline_tick[slot] == step:
            due = self._deadline_ns[slot]
        else:
            due = self.start_ns + step * self.period_ns
        late = now_ns - due
        self.arrival_late.add(late)
        if late > self.period_ns:
            self.arrivals_late += 1

    def ticked(self, tick: int, deadline_ns: int, now_ns: int) -> None:
        """Tick ``tick``, due at ``deadline_ns``, ran at ``now_ns``."""
        self.tick_late.add(now_ns - deadline_ns)
        slot = tick % DEADLINE_RING
        self._deadline_ns[slot] = deadline_ns
        self._deadline_tick[slot] = tick
        self.last_tick_ns = now_ns

    def report(
        self,
        ticks: int,
        scheduling: dict[str, object] | None,
        *,
        slips: int = 0,
        slipped_periods: int = 0,
    ) -> dict[str, Any]:
        """The figures of the run's ``ticks`` ticks (the plant's ``health.realtime``).

        ``slips``, ``slipped_periods``: the clock's (:class:`ClockThread`).
        Arrivals are those of steps 0 .. ``ticks`` - 1 (the plant reports at
        its last step: every step of the run).
        """
        return {
            "clock_slips": int(slips),
            "slipped_periods": int(slipped_periods),
            "period_ns": self.period_ns,
            "ticks": int(ticks),
            "misses": int(self.misses),
            "commands_missing": max(0, int(ticks) - self.arrival_late.count),
            "commands_late": self.arrivals_late,
            "timer_rate": deadlines.timer_rate(
                ticks, self.period_ns, self.start_ns, self.last_tick_ns
            ),
            "tick_late_us": self.tick_late.stats(),
            "command_late_us": self.arrival_late.stats(),
            "scheduling": scheduling,
        }


#: ``Realtime.measured_from`` of a loop a feedback measured (:class:`LoopTimes`).
MEASURED_AT_FEEDBACK = "the feedback's arrival and send times (an outside plant)"


class LoopTimes:
    """When each state came and each command went, at a feedback whose plant is outside.

    Such a plant (a drive, a user's node) reports no clock, so the feedback
    measures the loop (:func:`~servo_axis.core.deadlines.loop_from_times`):
    misses, lateness, states never answered; the summary's ``realtime``
    block is made of it. What it keeps is the same size for a run of any
    length (streaming lateness, the last :data:`DEADLINE_RING` arrivals).

    Parameters
    ----------
    steps : int
        Steps of the run, >= 1 (later ones are not kept).
    period_ns : int
        The control period ``T``, ns, > 0.
    """

    def __init__(self, *, steps: int, period_ns: int) -> None:
        self.period_ns = period_ns
        self.steps = steps
        self.tick_late = deadlines.LatenessHistogram()
        self.command_late = deadlines.LatenessHistogram()
        self.commands_late = 0
        self._first: tuple[int, int] | None = None  # (step, arrival) of the first state
        self._last: tuple[int, int] | None = None  # of the newest step
        # The last DEADLINE_RING states' arrivals, and which of them were answered.
        self._arrival_ns = array("q", [0]) * DEADLINE_RING
        self._arrival_step = array("q", [-1]) * DEADLINE_RING
        self._answered_step = array("q", [-1]) * DEADLINE_RING

    def arrived(self, step: int, now_ns: int) -> None:
        """``state[step]`` arrived at ``now_ns`` (monotonic; the first arrival counts)."""
        if not 0 <= step < self.steps:
            return
        slot = step % DEADLINE_RING
        if self._arrival_step[slot] >= step:
            return
        self._arrival_step[slot] = step
        self._arrival_ns[slot] = now_ns
        if self._first is None:
            self._first = (step, now_ns)
        first_step, first_ns = self._first
        # Its tick: the grid of the first state's arrival.
        self.tick_late.add(max(now_ns - first_ns - (step - first_step) * self.period_ns, 0))
        if self._last is None or step > self._last[0]:
            self._last = (step, now_ns)

    def sent(self, step: int, now_ns: int) -> None:
        """``command[step]`` went out at ``now_ns`` (monotonic; the first per step counts;
        one for a state that did not arrive, or arrived more than the ring ago, is not)."""
        if not 0 <= step < self.steps:
            return
        slot = step % DEADLINE_RING
        if self._arrival_step[slot] != step or self._answered_step[slot] >= step:
            return
        self._answered_step[slot] = step
        late = now_ns - self._arrival_ns[slot]
        self.command_late.add(late)
        if late > self.period_ns:
            self.commands_late += 1

    def report(self) -> dict[str, Any] | None:
        """The fields of the summary's ``realtime`` block; None before any state.

        Those of :func:`~servo_axis.core.deadlines.loop_from_times` of the same
        times, the lateness to the resolution of its histograms.
        """
        if self._first is None or self._last is None:
            return None
        ticks = self.tick_late.count
        missing = ticks - self.command_late.count
        return {
            "period_ns": int(self.period_ns),
            "ticks": ticks,
            "misses": missing + self.commands_late,
            "commands_missing": missing,
            "commands_late": self.commands_late,
            "timer_rate": deadlines.timer_rate(
                self._last[0] - self._first[0], self.period_ns, self._first[1], self._last[1]
            ),
            "tick_late_us": self.tick_late.stats(),
            "command_late_us": self.command_late.stats(),
            "measured_from": MEASURED_AT_FEEDBACK,
        }


class HeldSetPoint:
    """The current a drive applies at each tick, as a drive holds its last set-point.

    A command that has arrived by its tick's deadline is applied at that
    tick; otherwise the tick is a deadline miss and the newest current
    received is held. A command that arrives after its tick ran is not
    applied for its own step but replaces the held value if it is newer than
    what is held.
    """

    def __init__(self) -> None:
        self.pending: float | None = None  # the command of the step the next tick applies
        self.arrival_ns = 0
        self.held = 0.0
        self.held_step = -1  # step of the command whose current is held

    def check(self, step: int, expected: int) -> None:
        """Raise :class:`SignalError` unless a command of ``step`` may be taken now.

        ``expected``: the step the next tick applies (the plant's step); a
        command not newer than the held one, ahead of ``expected``, or a
        second one for ``expected`` is refused.
        """
        if not self.held_step < step <= expected:
            when = "stale" if step <= self.held_step else "future"
            raise SignalError(f"{when} stamp (step {step}, expected {expected})")
        if step == expected and self.pending is not None:
            raise SignalError(f"a second command for step {step}")

    def arrived(self, step: int, current_A: float, now_ns: int, expected: int) -> None:
        """A checked command of ``step`` (``current_A``) arrived at ``now_ns``."""
        if step < expected:
            # Late (its tick has run), but newer than the held current: it replaces it.
            if step > self.held_step:
                self.held, self.held_step = current_A, step
            return
        self.pending = current_A
        self.arrival_ns = now_ns

    def take(self, deadline_ns: int, step: int) -> tuple[float, bool]:
        """The current for the tick of ``step`` due at ``deadline_ns``, and whether it was on time."""
        command, self.pending = self.pending, None
        on_time = command is not None and deadlines.command_on_time(self.arrival_ns, deadline_ns)
        current = command if on_time and command is not None else self.held
        if command is not None:
            # On time, or after the deadline yet before the tick ran: the
            # newest current, held from now on.
            self.held_step = step
            self.held = command
        return current, on_time


class DriveSetPoint:
    """``command_source: drive_setpoint``: the newest set-point, whatever its stamp, held.

    A drive commanded over a fieldbus, or the hardware behind ros2_control's
    topic-based interface, applies at each tick the newest set-point
    received, held until the next one. Its commander runs on a clock of its
    own at the set-point period ``P`` (ros2_control: the controller
    manager's ``update_rate``), so a set-point belongs to no step. How a
    tick without a fresh one is judged depends on the commander:

    * it publishes every cycle (``threshold_Nm`` < 0: the plugin's
      ``trigger_joint_command_threshold: -1``): a tick misses its deadline
      when the newest set-point is older than :data:`SETPOINT_AGE_PERIODS`
      ``P`` then (any phase between the two clocks, jitter up to ``P / 2``);
    * it publishes only when its command moves away from the effort it read
      by more than ``threshold_Nm`` (the plugin's default, 1e-5): silence
      means "no change", which a drive cannot tell from a lost set-point. A
      tick without a fresh set-point is then held and counted
      (:attr:`quiet_ticks`), never judged a miss.

    NaN (the plugin's command before a controller is active) is no
    set-point: the node counts it (:attr:`unset`) and never applies it.

    Parameters
    ----------
    period_ns : int
        The set-point period ``P``, ns, > 0.
    threshold_Nm : float
        The commander's ``trigger_joint_command_threshold``, N m; negative:
        it publishes every cycle.
    """

    def __init__(self, *, period_ns: int, threshold_Nm: float) -> None:
        if period_ns <= 0:
            raise ValueError(f"period_ns: expected > 0, got {period_ns!r}")
        self.period_ns = period_ns
        self.threshold_Nm = threshold_Nm
        self.max_age_ns = int(SETPOINT_AGE_PERIODS * period_ns)
        self.held_A = 0.0  # zero current until the first set-point
        self.arrival_ns: int | None = None
        #: Set-points taken (finite), and NaN ones (no command yet) counted, not applied.
        self.received = 0
        self.unset = 0
        #: Ticks without a fresh set-point that were no miss (a commander that is
        #: silent while its command does not change).
        self.quiet_ticks = 0

    @property
    def silent_when_unchanged(self) -> bool:
        """Whether the commander publishes only on a change (``threshold_Nm`` >= 0)."""
        return self.threshold_Nm >= 0.0

    def arrived(self, current_A: float, now_ns: int) -> None:
        """A set-point (finite, as a current) arrived at ``now_ns``: held from now on."""
        self.held_A, self.arrival_ns = current_A, now_ns
        self.received += 1

    def take(self, deadline_ns: int) -> tuple[float, bool]:
        """The current for the tick due at ``deadline_ns``, and whether it kept its deadline."""
        fresh = self.arrival_ns is not None and (
            deadline_ns - self.max_age_ns < self.arrival_ns <= deadline_ns
        )
        if not fresh and self.silent_when_unchanged and self.arrival_ns is not None:
            self.quiet_ticks += 1
            return self.held_A, True
        return self.held_A, fresh

    def report(self) -> dict[str, Any]:
        """The set-point figures of the plant's ``realtime`` report (``setpoints``)."""
        return {
            "period_ns": self.period_ns,
            "received": self.received,
            "unset": self.unset,
            "quiet_ticks": self.quiet_ticks,
        }


class CatchUp:
    """Realtime: which states a node answers once it has fallen behind its plant's clock.

    Every state goes through the loop, in order, but a state whose answer
    could no longer reach the plant in time to be used
    (:func:`~servo_axis.core.deadlines.answer_useful`: after a stall, while
    newer states wait in the queue) is not answered, so that the node
    catches up with the clock instead of answering a backlog; it still
    answers at least every ``gap`` steps, and always ``last_step``. The
    deadlines are those of the plant's clock as the states' arrivals show
    it (:func:`~servo_axis.core.deadlines.start_estimate_ns`: never before
    its start, so a useful answer is never skipped).

    Parameters
    ----------
    period_ns : int
        The control period, ns.
    last_step : int
        The run's last step (always answered: the recorder counts to it).
    gap : int
        The most steps between two answered states, >= 1.
    """

    def __init__(self, *, period_ns: int, last_step: int, gap: int) -> None:
        self.period_ns = period_ns
        self.last_step = last_step
        self.gap = gap
        self.start_ns: int | None = None  # the plant clock's d_0 as the states show it
        self._window_ns: int | None = None  # the estimate of this window of states
        self._previous_ns: int | None = None  # that of the window before
        self._seen = 0
        self.answered = -1
        #: States not answered.
        self.skipped = 0

    def arrived(self, step: int, now_ns: int) -> None:
        """State ``step`` arrived at ``now_ns``: the estimate of the clock's start follows it.

        The least of the last one or two windows of :data:`START_WINDOW`
        states: a clock that slipped (re-based its deadlines later,
        :class:`ClockThread`) is followed within two windows, rather than
        every later state looking late for ever (and only every ``gap``-th
        answered).
        """
        cur = deadlines.start_estimate_ns(self._window_ns, now_ns, step, self.period_ns)
        self._window_ns = cur
        prev = self._previous_ns
        self.start_ns = cur if prev is None or cur is None else min(prev, cur)
        self._seen += 1
        if self._seen >= START_WINDOW:
            self._previous_ns, self._window_ns, self._seen = cur, None, 0

    def answer(self, step: int, now_ns: int) -> bool:
        """Whether state ``step`` is answered now (else counted in :attr:`skipped`)."""
        if (
            self.start_ns is not None
            and step < self.last_step
            and not deadlines.answer_useful(
                now_ns, self.start_ns, self.period_ns, step, self.answered, self.gap
            )
        ):
            self.skipped += 1
            return False
        self.answered = step
        return True
