"""What a node does in realtime mode: the plant's clock, deadlines kept.

Nothing here imports rclpy (the numbers are :mod:`servo_axis.realtime.deadlines`',
which threads get a realtime priority :mod:`servo_axis.realtime.scheduling`'):

* :class:`ClockThread`: the thread that ticks at absolute deadlines
  ``d_j = start + j T_u`` of the monotonic clock (the plant's clock).
* :class:`ClockRecord`: a clock's ticks, its misses and the lateness of the
  ticks and of the arrivals they wait for (the plant's ``realtime`` report).
* :class:`LoopTimes`: the loop around an outside plant, as its feedback sees it.

What a node does with what is late is :mod:`servo_axis.realtime.late`.
"""

from __future__ import annotations

import gc
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from servo_axis.realtime import deadlines
from servo_axis.realtime.scheduling import fifo_this_thread

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
#: A clock that wakes later than this many periods after a deadline (and at
#: least :data:`SLIP_MIN_NS`) does not run the ticks it missed back to back
#: at its realtime priority: it slips, as ros2_control's controller manager
#: skips the periods it overran: the deadlines are re-based to the first
#: one after now, and the slip is counted (:attr:`ClockThread.slips`).
SLIP_PERIODS = 100
SLIP_MIN_NS = 50_000_000


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


class ClockRecord:
    """A realtime clock's ticks and the arrivals it waits for, against its deadlines.

    Tick ``j`` is due at ``d_j = start + j T``; the input that answers state
    ``k`` (the plant's command ``k``) is late by its arrival minus ``d_k``,
    so that later than one period is a missed deadline
    (:mod:`servo_axis.realtime.deadlines`).

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
        self._tick_late_ns = np.full(steps + 1, np.nan)  # by tick j (1 .. steps)
        self._arrival_late_ns = np.full(steps, np.nan)  # by step k (0 .. steps - 1)
        # Tick j's deadline, as the clock had it (a slip re-bases the grid).
        self._deadline_ns = np.zeros(steps + 1, dtype=np.int64)

    def arrived(self, step: int, now_ns: int) -> None:
        """The input of ``step`` arrived at ``now_ns`` (a step outside the run is not kept)."""
        if 0 <= step < self.steps:
            due = int(self._deadline_ns[step]) if step > 0 else 0
            if due == 0:
                due = self.start_ns + step * self.period_ns
            self._arrival_late_ns[step] = now_ns - due

    def ticked(self, tick: int, deadline_ns: int, now_ns: int) -> None:
        """Tick ``tick``, due at ``deadline_ns``, ran at ``now_ns``."""
        self._tick_late_ns[tick] = now_ns - deadline_ns
        self._deadline_ns[tick] = deadline_ns
        self.last_tick_ns = now_ns

    def report(
        self,
        ticks: int,
        scheduling: dict[str, object] | None,
        *,
        slips: int = 0,
        slipped_periods: int = 0,
    ) -> dict[str, Any]:
        """The figures of the first ``ticks`` ticks (the plant's ``health.realtime``).

        ``slips``, ``slipped_periods``: the clock's (:class:`ClockThread`).
        """
        late = self._arrival_late_ns[:ticks]
        return {
            "clock_slips": int(slips),
            "slipped_periods": int(slipped_periods),
            "period_ns": self.period_ns,
            "ticks": int(ticks),
            "misses": int(self.misses),
            "commands_missing": int(np.count_nonzero(np.isnan(late))),
            "commands_late": int(np.count_nonzero(late > self.period_ns)),
            "timer_rate": deadlines.timer_rate(
                ticks, self.period_ns, self.start_ns, self.last_tick_ns
            ),
            "tick_late_us": deadlines.lateness_stats(self._tick_late_ns[1 : ticks + 1]),
            "command_late_us": deadlines.lateness_stats(late),
            "scheduling": scheduling,
        }


#: ``Realtime.measured_from`` of a loop a feedback measured (:class:`LoopTimes`).
MEASURED_AT_FEEDBACK = "the feedback's arrival and send times (an outside plant)"


class LoopTimes:
    """When each state came and each command went, at a feedback whose plant is outside.

    Such a plant (a drive, a user's node) reports no clock, so the feedback
    measures the loop (:func:`~servo_axis.realtime.deadlines.loop_from_times`):
    misses, lateness, states never answered; the summary's ``realtime``
    block is made of it.

    Parameters
    ----------
    steps : int
        Steps of the run, >= 1 (later ones are not kept).
    period_ns : int
        The control period ``T``, ns, > 0.
    """

    def __init__(self, *, steps: int, period_ns: int) -> None:
        self.period_ns = period_ns
        self._arrived = np.zeros(steps, dtype=np.int64)
        self._sent = np.zeros(steps, dtype=np.int64)

    def arrived(self, step: int, now_ns: int) -> None:
        """``state[step]`` arrived at ``now_ns`` (monotonic; the first arrival counts)."""
        if 0 <= step < self._arrived.size and self._arrived[step] == 0:
            self._arrived[step] = now_ns

    def sent(self, step: int, now_ns: int) -> None:
        """``command[step]`` went out at ``now_ns`` (monotonic)."""
        if 0 <= step < self._sent.size and self._sent[step] == 0:
            self._sent[step] = now_ns

    def report(self) -> dict[str, Any] | None:
        """The fields of the summary's ``realtime`` block; None before any state."""
        states = np.flatnonzero(self._arrived)
        commands = np.flatnonzero(self._sent)
        figures = deadlines.loop_from_times(
            period_ns=self.period_ns,
            state_steps=states.tolist(),
            state_times_ns=self._arrived[states].tolist(),
            command_steps=commands.tolist(),
            command_times_ns=self._sent[commands].tolist(),
        )
        return None if figures is None else {**figures, "measured_from": MEASURED_AT_FEEDBACK}
