"""Absolute deadlines of a realtime clock, its misses and its lateness (no ROS, no threads).

The plant's realtime clock steps at ``d_j = start + j T`` (``T`` the control
period, monotonic nanoseconds). Its state ``k`` goes out at tick ``k``
(``d_0 = start``: the first state goes out at the start); the command that
answers it is due at the next tick, ``d_{k+1}``. A tick whose command has not
arrived by its deadline is a deadline miss: the plant holds the last current,
as a drive holds its last set-point, and goes on. A tick that wakes more
than a period late is not skipped: the ticks that are due run at once
(their commands cannot be in, so each is a miss), so that simulated time
stays with wall time.

Lateness, as cyclictest reports it: a tick's is the time from its deadline
to when it stepped; a command's is the time from the tick of the state it
answers to its arrival, so that a command later than one period is exactly
a missed deadline (:func:`misses_of`).
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

#: Percentiles reported of each lateness (cyclictest's p50, p99 and the max).
PERCENTILES = (50.0, 99.0)

#: Relative width of a :class:`LatenessHistogram` bin.
LATENESS_RELATIVE_RESOLUTION = 0.01
#: Lower edge of its first log-spaced bin (ns): earlier is one bin.
LATENESS_FLOOR_NS = 100
#: Upper edge of its last log-spaced bin (ns): later is one bin.
LATENESS_CEILING_NS = 100_000_000_000
_LOG_STEP = math.log1p(LATENESS_RELATIVE_RESOLUTION)
_BINS = math.ceil(math.log(LATENESS_CEILING_NS / LATENESS_FLOOR_NS) / _LOG_STEP)


def deadline_ns(start_ns: int, period_ns: int, tick: int) -> int:
    """``d_tick = start + tick T``, ns."""
    return start_ns + tick * period_ns


def due_ticks(now_ns: int, start_ns: int, period_ns: int, next_tick: int) -> int:
    """How many ticks, from ``next_tick`` on, have their deadline at or before ``now_ns``.

    0 while the clock waits for ``next_tick``; more than 1 after a stall
    (a scheduler that woke the clock more than a period late).
    """
    passed = (now_ns - start_ns) // period_ns  # the last tick whose deadline has passed
    return max(0, passed - next_tick + 1)


def sleep_s(now_ns: int, deadline: int, spin_ns: int) -> float:
    """Seconds to sleep before spinning the last ``spin_ns`` to ``deadline`` (0: spin now)."""
    return max(0, deadline - now_ns - spin_ns) * 1e-9


def command_on_time(arrival_ns: int | None, tick_deadline_ns: int) -> bool:
    """A command counts for a tick if it arrived by the tick's deadline (not merely by
    the time the tick ran: a clock that woke late must not excuse a late command)."""
    return arrival_ns is not None and arrival_ns <= tick_deadline_ns


def misses_of(command_late_ns: ArrayLike, period_ns: int) -> int:
    """Deadline misses implied by the commands' lateness (NaN: never arrived).

    ``command_late_ns[k]`` is the arrival of command ``k`` after the tick of
    state ``k``; it was on time for tick ``k + 1`` iff it is <= one period.
    """
    late = np.asarray(command_late_ns, dtype=float)
    return int(np.count_nonzero(~(late <= period_ns)))  # NaN counts as a miss


class LatenessHistogram:
    """A streaming summary of a lateness series: fixed-size, whatever the run's length.

    Log-spaced bins of relative width :data:`LATENESS_RELATIVE_RESOLUTION`
    (1 %) from :data:`LATENESS_FLOOR_NS` (100 ns) to :data:`LATENESS_CEILING_NS`
    (100 s), a bin below (0 to 100 ns), one above, and one of negative
    values (an arrival before the deadline it is timed against: its
    percentiles are only known to lie between the min and 0); the count,
    sum, min and max exactly. A
    percentile is the middle of the bin its order statistic falls in, kept
    within the min and max, interpolated between the two order statistics as
    numpy's ``percentile`` does: within 1 % of the value numpy gives of the
    same samples, or 100 ns below 10 us (the reports round to 0.1 us); the
    min and max are exact. Adding a sample allocates
    nothing that stays (about 2,100 bins, 17 kB, from the start).

    Attributes
    ----------
    count : int
        Samples added.
    min_ns, max_ns : int or None
        The smallest and largest sample (ns); None before any.
    sum_ns : int
        The samples' sum (ns).
    """

    __slots__ = ("_bins", "count", "max_ns", "min_ns", "sum_ns")

    def __init__(self) -> None:
        # C int64 counts: an increment keeps no Python int alive.
        self._bins = array("q", bytes(8 * (_BINS + 3)))
        self.count = 0
        self.sum_ns = 0
        self.min_ns: int | None = None
        self.max_ns: int | None = None

    def add(self, late_ns: int) -> None:
        """Count one sample (ns)."""
        if late_ns < 0:
            index = 0
        elif late_ns < LATENESS_FLOOR_NS:
            index = 1
        elif late_ns >= LATENESS_CEILING_NS:
            index = _BINS + 2
        else:
            index = min(int(math.log(late_ns / LATENESS_FLOOR_NS) / _LOG_STEP), _BINS - 1) + 2
        self._bins[index] += 1
        self.count += 1
        self.sum_ns += late_ns
        if self.min_ns is None or late_ns < self.min_ns:
            self.min_ns = late_ns
        if self.max_ns is None or late_ns > self.max_ns:
            self.max_ns = late_ns

    @property
    def mean_ns(self) -> float:
        """The samples' mean (ns); NaN before any."""
        return self.sum_ns / self.count if self.count else math.nan

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile (0..100, ns) to the bins' resolution; NaN before any.

        As numpy's default (linear): between the order statistics at
        ``q / 100 (count - 1)``, each taken as the middle of its bin.
        """
        if not self.count:
            return math.nan
        position = q / 100.0 * (self.count - 1)
        below = math.floor(position)
        low = self._order_statistic(below)
        if position == below:
            return low
        return low + (position - below) * (self._order_statistic(below + 1) - low)

    def _order_statistic(self, rank: int) -> float:
        """The ``rank``-th smallest sample (0-based), as the middle of its bin."""
        assert self.min_ns is not None and self.max_ns is not None
        if rank <= 0:
            return float(self.min_ns)
        if rank >= self.count - 1:
            return float(self.max_ns)
        seen = 0
        index = 0
        for index, n in enumerate(self._bins):  # noqa: B007 (the bin is what is wanted)
            seen += n
            if seen > rank:
                break
        if index == 0:
            middle = self.min_ns / 2  # somewhere in [min, 0)
        elif index == 1:
            middle = LATENESS_FLOOR_NS / 2
        elif index == _BINS + 2:
            middle = float(self.max_ns)
        else:
            low = LATENESS_FLOOR_NS * math.exp((index - 2) * _LOG_STEP)
            middle = low * (1.0 + LATENESS_RELATIVE_RESOLUTION / 2)
        return float(min(max(middle, self.min_ns), self.max_ns))

    def stats(self) -> dict[str, float] | None:
        """What :func:`lateness_stats` gives of the same samples, to the bins' resolution."""
        if not self.count or self.max_ns is None:
            return None
        p50, p99 = (self.percentile(q) for q in PERCENTILES)
        return {
            "p50": round(p50 * 1e-3, 1),
            "p99": round(p99 * 1e-3, 1),
            "max": round(self.max_ns * 1e-3, 1),
        }


def lateness_stats(late_ns: ArrayLike) -> dict[str, float] | None:
    """``p50``, ``p99`` and ``max`` of a lateness series, us (NaNs left out; None if none)."""
    values = np.asarray(late_ns, dtype=float)
    values = values[~np.isnan(values)]
    if values.size == 0:
        return None
    p50, p99 = np.percentile(values, PERCENTILES)
    return {
        "p50": round(float(p50) * 1e-3, 1),
        "p99": round(float(p99) * 1e-3, 1),
        "max": round(float(values.max()) * 1e-3, 1),
    }


def timer_rate(ticks: int, period_ns: int, start_ns: int, last_tick_ns: int) -> float:
    """Ticks per period of wall time from the start to the last tick (1.0: on time)."""
    wall = last_tick_ns - start_ns
    return ticks * period_ns / wall if wall > 0 else math.nan


def answer_useful(
    now_ns: int, start_ns: int, period_ns: int, step: int, last_answered: int, max_gap: int
) -> bool:
    """Whether a realtime controller should still answer ``state[step]`` now.

    ``command[k]`` counts for tick ``k + 1`` if it is in by ``d_{k+1}``, and
    after that it is the newest current the plant holds, from tick ``k + 2``
    on, only if it is in before ``d_{k+2}``: by then ``state[k + 1]`` has gone
    out, so a controller that is behind (states queued after a stall)
    answers the newer state instead and catches up, rather than answering
    a backlog of states whose commands the plant can no longer use. It
    still answers at least every ``max_gap`` steps, so the command stream
    never skips more than ``max_gap - 1`` samples (readers of a realtime
    stream take jumps of a bounded size).

    Parameters
    ----------
    now_ns : int
        Monotonic time, ns.
    start_ns : int
        The clock's start ``d_0``, ns (the controller's estimate: when it
        answered ``state[0]``, which starts the plant's clock).
    period_ns : int
        The control period ``T``, ns, > 0.
    step : int
        The state's step ``k``, >= 0.
    last_answered : int
        The step of the last state answered (-1 before the first).
    max_gap : int
        Answer whenever ``step - last_answered >= max_gap``, >= 1.
    """
    if step - last_answered >= max_gap:
        return True
    return now_ns < deadline_ns(start_ns, period_ns, step + 2)


def start_estimate_ns(
    estimate_ns: int | None, arrival_ns: int, step: int, period_ns: int
) -> int | None:
    """A controller's estimate of the plant clock's start ``d_0``, never before it.

    ``state[k]`` (``k >= 1``) goes out at tick ``k``, not before
    ``d_k = d_0 + k T``, so ``arrival_ns - k T >= d_0`` for each; the least
    of them is ``d_0`` plus the least latency seen so far. ``state[0]`` goes
    out before the clock starts (the plant starts it when ``command[0]`` is
    in) and tells nothing. Taking ``d_0`` as the time ``state[0]`` was
    answered put it early by the first command's transit (a few ms at
    start-up, 2-10 periods at 0.4 ms), so that every later state looked
    two periods late to :func:`answer_useful` and only every 5th was
    answered: 84 % misses in a realtime ``dlpid_tilt_pid``.

    Parameters
    ----------
    estimate_ns : int or None
        The estimate so far, ns (None before the first state after ``state[0]``).
    arrival_ns : int
        Monotonic time at which ``state[step]`` arrived, ns.
    step : int
        The state's step ``k``, >= 0.
    period_ns : int
        The control period ``T``, ns, > 0.

    Returns
    -------
    int or None
        The new estimate, ns: ``min(estimate_ns, arrival_ns - k T)`` for ``k >= 1``.
    """
    if step < 1:
        return estimate_ns
    offset = arrival_ns - step * period_ns
    return offset if estimate_ns is None else min(estimate_ns, offset)


def loop_from_times(
    *,
    period_ns: int,
    state_steps: Sequence[int],
    state_times_ns: Sequence[int],
    command_steps: Sequence[int],
    command_times_ns: Sequence[int],
) -> dict[str, Any] | None:
    """A loop's misses and lateness from when each state came and each command went.

    Where the plant is not the suite's (an outside plant reports no clock) the
    feedback measures the loop as the suite's plant does from its arrivals:
    tick ``k`` is when ``state[k]`` arrived; the command that answers it is
    late by the time from then until it was sent, and a miss if that is more
    than one period (:func:`misses_of`), or if it was never sent. The plant's
    transport, both ways, is not in these figures: what a drive sees is later
    by it.

    Parameters
    ----------
    period_ns : int
        The control period ``T``, ns, > 0.
    state_steps, state_times_ns : sequence of int
        The step of each state (increasing; a plant whose timer skipped
        leaves steps out) and when it arrived, ns (any monotonic clock).
    command_steps, command_times_ns : sequence of int
        The same of each command sent, on the same clock (the first per step counts).

    Returns
    -------
    dict or None
        ``ticks``, ``misses``, ``commands_missing``, ``commands_late``,
        ``timer_rate`` (periods per period of wall time between the first
        and the last state), ``tick_late_us`` (each state's arrival after
        the grid of the first one's) and ``command_late_us`` (:func:`lateness_stats`);
        None without states.

    Raises
    ------
    ValueError
        ``period_ns`` not positive, or times not one per step.
    """
    if period_ns <= 0:
        raise ValueError(f"period_ns: expected > 0, got {period_ns!r}")
    k = np.asarray(state_steps, dtype=np.int64)
    t = np.asarray(state_times_ns, dtype=np.int64)
    if k.shape != t.shape:
        raise ValueError(f"state_times_ns: expected one per state step ({k.size}), got {t.size}")
    if len(command_steps) != len(command_times_ns):
        raise ValueError(
            f"command_times_ns: expected one per command step ({len(command_steps)}), "
            f"got {len(command_times_ns)}"
        )
    if k.size == 0:
        return None
    sent: dict[int, int] = {}
    for step, when in zip(command_steps, command_times_ns, strict=True):
        sent.setdefault(int(step), int(when))
    late = np.array(
        [sent[s] - a if s in sent else np.nan for s, a in zip(k.tolist(), t.tolist(), strict=True)],
        dtype=float,
    )
    misses = misses_of(late, period_ns)
    missing = int(np.count_nonzero(np.isnan(late)))
    return {
        "period_ns": int(period_ns),
        "ticks": int(k.size),
        "misses": misses,
        "commands_missing": missing,
        "commands_late": misses - missing,
        "timer_rate": timer_rate(int(k[-1] - k[0]), period_ns, int(t[0]), int(t[-1])),
        "tick_late_us": lateness_stats(np.maximum(t - t[0] - (k - k[0]) * period_ns, 0)),
        "command_late_us": lateness_stats(late),
    }
