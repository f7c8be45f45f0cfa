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
from array import array
from collections.abc import Callable
from typing import Any

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


#: Ticks a :class:`ClockRecord` keeps the deadline of: a command that answers
#: an older state (seconds late at 1 kHz) is timed against the grid instead.
DEADLINE_RING = 4096


class ClockRecord:
    """A realtime clock's ticks and the arrivals it waits for, against its deadlines.

    Tick ``j`` is due at ``d_j = start + j T``; the input that answers state
    ``k`` (the plant's command ``k``) is late by its arrival minus ``d_k``,
    so that later than one period is a missed deadline
    (:mod:`servo_axis.realtime.deadlines`). The first arrival of a step counts.

    What it keeps is the same size for a run of any length: the lateness
    of ticks and of arrivals as :class:`~servo_axis.realtime.deadlines.LatenessHistogram`
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
    measures the loop (:func:`~servo_axis.realtime.deadlines.loop_from_times`):
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

        Those of :func:`~servo_axis.realtime.deadlines.loop_from_times` of the same
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
