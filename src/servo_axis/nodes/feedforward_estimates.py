"""The feedforward generator's adaptive part: the identifier's estimates in (paper 003).

Composed by :class:`~servo_axis.nodes.feedforward.FeedforwardNode` only with
``adaptive.enabled``, one class per mode (:func:`estimates_part`). Both
subscribe ``identifier/estimates`` and apply each estimate from its
``applies_from_step``: the PTC's model is rebuilt from ``J``, ``D`` (eq.
(11)) and the MNC gets ``U``, ``C``. Estimates must come in order, each the
next one expected (its step and application step on the schedule of
``adaptive.rls_period_s`` and ``adaptive.latency_s``); an exact repeat of
the last one (a restarted identifier sends its last estimate again) is
taken silently; anything else (NaN, out of order, another schedule) is
rejected and counted, and the model in force stays.

:class:`LockstepEstimates`: no sample from an estimate's step on is
published before the estimate is in. Identifier fallback
(``adaptive.timeout_s``): the rule of the learning unit's
(:func:`~servo_axis.nodes.lockstep.waited_too_long`) with the identifier as
the peer (liveliness of ``identifier/estimates``); on it the generator keeps
the estimates in force for the rest of the run and takes no later one
(:meth:`~servo_axis.core.feedforward.generator.FeedforwardGenerator.stop_estimates`).

:class:`RealtimeEstimates`: an estimate is waited for only until its sample
is due: the plant's clock does not wait for the identifier, and a reference
held back past its sample's deadline makes the feedback hold the last one
while the axis moves on (measured: ``dlpid_tilt_lpf2``, 4 s at 0.4 ms, the
identifier some 4 ms late at step ~8,650: 0.43 rad of tracking error, 165
times lockstep's RMS). So when the plant's clock (estimated from
``plant/status``, :func:`~servo_axis.realtime.deadlines.start_estimate_ns`) is
:data:`ESTIMATE_LEAD_S` before the next estimate's ``applies_from_step`` and
the estimate is not in, the references of one more estimate period go out
with the model in force, and the estimate applies from the first reference
instant not yet published once it is in (counted as ``late``;
:meth:`~servo_axis.core.feedforward.generator.FeedforwardGenerator.stop_waiting_for_estimates`).
An estimate in time applies from its own step, as in lockstep. Nothing
stalls, so there is no identifier fallback; a restarted identifier's
estimates are applied as they come.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, cast

from servo_axis.core.errors import ServoAxisError, SignalError
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import PeerWatch, waited_too_long
from servo_axis.nodes.runtime import steady_clock
from servo_axis.params.factories import estimate_steps, run_steps
from servo_axis.params.values import FeedforwardValues
from servo_axis.realtime.deadlines import start_estimate_ns
from servo_axis.wire import messages as msgs

#: Realtime: how long before the next estimate's first sample is due the
#: references go on without it (publishing, the timer's lateness and the
#: transport to the feedback: 0.2-0.5 ms each on a loaded 2-core host).
ESTIMATE_LEAD_S = 1.2e-3


class Estimates:
    """What both modes share: the estimates taken in order and applied (see the module docstring).

    Parameters
    ----------
    node : ServoNode
        The feedforward node: its values, inputs, report and timers.
    generator : FeedforwardGenerator
        Where the estimates go.
    published : callable
        How many samples are out (samples ``0 .. published() - 1``).
    refill : callable
        Publish on, once an estimate (or its fallback) let the window move.
    """

    def __init__(
        self,
        node: ServoNode,
        generator: FeedforwardGenerator,
        *,
        published: Callable[[], int],
        refill: Callable[[], None],
    ) -> None:
        values = cast(FeedforwardValues, node.values)  # the feedforward node's
        self._node = node
        self._generator = generator
        self._published = published
        self._refill = refill
        self._steps = run_steps(values)
        # Estimate period and latency (control samples); an estimate applies
        # ``latency + 1`` samples after the last one it is computed from.
        period, latency = estimate_steps(values)
        assert period is not None  # a part of a feedforward that takes estimates
        self._estimate_period = period
        self._lag = latency + 1
        #: The last estimate taken.
        self.last: msgs.EstimateData | None = None
        self.taken = 0
        #: Realtime: estimates applied from after their step.
        self.late = 0
        node.inputs.subscribe("identifier/estimates", self._gate, self._take)

    def plant_moved(self, step: int) -> None:
        """The plant is at ``step`` (``plant/status``)."""

    def limit(self, until: int) -> int:
        """How far the references may go out now, up to ``until``."""
        return until

    def _gate(self, msg: Any) -> msgs.EstimateData | None:
        """The next estimate expected; None for an exact repeat of the last one (or once stopped)."""
        e = msgs.estimate_from_msg(msg)
        if e == self.last:
            return None  # a restarted identifier sends its last estimate again
        expected = self._generator.next_estimate_step
        if expected is None:
            return None  # estimates stopped (fallback): the model in force stays
        if e.applies_from_step != expected:
            raise SignalError(
                f"applies_from_step {e.applies_from_step}: expected the next estimate's {expected}"
            )
        if e.applies_from_step - e.step != self._lag:
            raise SignalError(
                f"step {e.step}: expected {expected - self._lag} for an estimate "
                f"applying from {expected} (latency {self._lag - 1} steps)"
            )
        return e

    def _take(self, e: msgs.EstimateData | None) -> None:
        if e is None:
            return
        try:
            first = self._generator.set_estimate(
                e.applies_from_step,
                inertia_kgm2=e.inertia_kgm2,
                damping_Nms_per_rad=e.damping_Nms_per_rad,
                unbalance_Nm=e.unbalance_Nm,
                coulomb_Nm=e.coulomb_Nm,
            )
        except ServoAxisError as err:
            # A value the model refuses (the PTC's discretisation, say): the
            # model in force stays and the estimate is counted as rejected.
            self._node.report.reject(
                "identifier/estimates", f"identifier/estimates rejected: {err}"
            )
            return
        self.last = e
        self.taken += 1
        self.late += first != e.applies_from_step
        self._taken_one()
        self._refill()

    def _taken_one(self) -> None:
        """An estimate was taken (a wait for it is over)."""


class LockstepEstimates(Estimates):
    """Lockstep: no sample an estimate applies to goes out before it; a gone identifier falls back."""

    def __init__(
        self,
        node: ServoNode,
        generator: FeedforwardGenerator,
        *,
        published: Callable[[], int],
        refill: Callable[[], None],
    ) -> None:
        super().__init__(node, generator, published=published, refill=refill)
        self._timeout_s = cast(FeedforwardValues, node.values).adaptive.timeout_s
        self._identifier = PeerWatch()
        self._wait_since: float | None = None
        node.create_timer(self._timeout_s / 5.0, self._watchdog, clock=steady_clock())

    def plant_moved(self, step: int) -> None:
        if self._wait_since is not None:
            self._wait_since = time.monotonic()  # the plant still moves: not stalled yet

    def _taken_one(self) -> None:
        self._wait_since = None
        self._identifier.forget()

    def _watchdog(self) -> None:
        now = time.monotonic()
        self._identifier.look(self._node.inputs.peer_alive("identifier/estimates"), now)
        generator = self._generator
        expected = generator.next_estimate_step
        if expected is None or self._published() < expected or expected >= self._steps:
            self._wait_since = None
            return
        if self._wait_since is None:
            self._wait_since = now
            return
        why = waited_too_long(
            self._identifier,
            waiting_since=self._wait_since,
            timeout_s=self._timeout_s,
            now=now,
            name="identifier",
            lockstep=True,
        )
        if why is None:
            return
        generator.stop_estimates()
        self._node.report.fallback(
            "identifier_timeout",
            expected,
            f"no estimate applying from step {expected} within {self._timeout_s} s ({why}): "
            f"keeping the estimates in force for the rest of the run ({self.taken} taken)",
        )
        self._wait_since = None
        self._refill()


class RealtimeEstimates(Estimates):
    """Realtime: an estimate is waited for only until its sample is due (see the module docstring)."""

    def __init__(
        self,
        node: ServoNode,
        generator: FeedforwardGenerator,
        *,
        published: Callable[[], int],
        refill: Callable[[], None],
    ) -> None:
        super().__init__(node, generator, published=published, refill=refill)
        generator.stop_waiting_for_estimates()
        self._period_ns = msgs.period_ns(node.values.control_period_s)
        self._lead_steps = -(-round(ESTIMATE_LEAD_S * 1e9) // self._period_ns)
        self._without_until = 0  # published without their estimate up to here
        self._plant_start_ns: int | None = None  # the plant clock's d_0
        self._start_provisional = False  # from status 0, sent before d_0
        self._due_for: int | None = None  # the estimate step the timer is set for
        self._due_timer = node.create_timer(1.0, self._due, clock=steady_clock())
        self._due_timer.cancel()

    def plant_moved(self, step: int) -> None:
        now_ns = time.monotonic_ns()
        if step == 0 and self._plant_start_ns is None:
            # Before its clock starts: early, so an estimate is let go
            # early at worst (the first ones are the initial model).
            self._plant_start_ns = now_ns
            self._start_provisional = True
        elif step > 0:
            self._plant_start_ns = start_estimate_ns(
                None if self._start_provisional else self._plant_start_ns,
                now_ns,
                step,
                self._period_ns,
            )
            self._start_provisional = False

    def limit(self, until: int) -> int:
        """``until``, but not past the next estimate's step before it is due."""
        nxt = self._generator.next_estimate_step
        if nxt is None:
            return until
        # Past an estimate that was let go, the next wait is a period on.
        wait_at = max(nxt, self._without_until)
        if until <= wait_at or wait_at >= self._steps:
            return until
        if self._due_for != wait_at and self._plant_start_ns is not None:
            # Not before the plant has said where it is (plant/status).
            self._due_for = wait_at
            due_ns = self._plant_start_ns + (wait_at - self._lead_steps) * self._period_ns
            self._due_timer.timer_period_ns = max(1, due_ns - time.monotonic_ns())
            self._due_timer.reset()
        return wait_at

    def _due(self) -> None:
        """The samples from ``_due_for`` are due; go on if their estimate is not in.

        An estimate that came in time moved the next wait on, and
        :meth:`limit` set the timer for that one.
        """
        self._due_timer.cancel()
        wait_at, self._due_for = self._due_for, None
        nxt = self._generator.next_estimate_step
        if wait_at is None or nxt is None or nxt > wait_at:
            return
        self._without_until = wait_at + self._estimate_period
        self._refill()


def estimates_part(
    node: ServoNode,
    generator: FeedforwardGenerator,
    *,
    published: Callable[[], int],
    refill: Callable[[], None],
) -> Estimates:
    """The estimates part of the node's mode (``mode``: lockstep or realtime)."""
    cls = LockstepEstimates if node.values.mode == "lockstep" else RealtimeEstimates
    return cls(node, generator, published=published, refill=refill)
