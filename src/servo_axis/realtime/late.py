"""What a realtime node does with what is late (no rclpy).

* :class:`HeldSetPoint`: the current a drive applies at a tick: the command
  of the step if it arrived by the deadline, else the newest one received.
* :class:`DriveSetPoint`: the same for a drive's set-point of no step
  (``command_source: drive_setpoint``): the newest one, whatever its stamp.
* :class:`CatchUp`: which states a node that fell behind still answers.

The deadlines themselves are :mod:`servo_axis.realtime.deadlines`'.
"""

from __future__ import annotations

from typing import Any

from servo_axis.core.errors import SignalError
from servo_axis.realtime import deadlines

#: States per window of :meth:`CatchUp.arrived`'s estimate of the clock's
#: start: the estimate follows a clock that slipped within two windows
#: (0.4-0.8 s at 0.4 ms), and is never made of a stall's backlog alone.
START_WINDOW = 1024
#: ``command_source: drive_setpoint``: a tick misses its deadline when the
#: newest set-point is older than this many set-point periods then
#: (:class:`DriveSetPoint`).
SETPOINT_AGE_PERIODS = 1.5


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
    (:func:`~servo_axis.realtime.deadlines.answer_useful`: after a stall, while
    newer states wait in the queue) is not answered, so that the node
    catches up with the clock instead of answering a backlog; it still
    answers at least every ``gap`` steps, and always ``last_step``. The
    deadlines are those of the plant's clock as the states' arrivals show
    it (:func:`~servo_axis.realtime.deadlines.start_estimate_ns`: never before
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
