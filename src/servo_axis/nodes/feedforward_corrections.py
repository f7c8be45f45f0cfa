"""The feedforward generator's learning part: the learning unit's corrections in.

Composed by :class:`~servo_axis.nodes.feedforward.FeedforwardNode` only with
``learning.enabled``. It subscribes ``learning/correction`` (target-side
laws: position and velocity per reference instant) or
``learning/input_correction`` (input-side laws: a torque per control sample,
N m, turned back into a current with the nominal torque constant) and
applies each period's correction from the period it is stamped for, once
the period is whole.

A correction must be for a period still to come and not too far ahead
(lockstep: a cycle whose boundary the generator has not passed; realtime: a
cycle not yet published whole); others are rejected.

Fallback (``learning.timeout_s``): in lockstep a cycle waits for its
correction as long as the learning unit lives (liveliness of the
correction topic). It runs with the last correction (recorded as a
fallback) only once the unit has been gone for ``learning.timeout_s``, or
once it went away during the wait (a respawned unit did not see the cycle
end it owed a correction for) and the plant has then stood still for
``learning.timeout_s`` (:func:`~servo_axis.nodes.lockstep.waited_too_long`).

In realtime the references never wait for a correction: a learning unit
cannot have ``c_{j+1}`` in before the boundary it is learned at, and the
plant does not wait. The boundary goes by with the last correction
(``repeat_correction``, :meth:`LearningCorrections.go_on`) and ``c_{j+1}``
applies from the first sample not yet published once it is in
(``replace_correction``; counted as :attr:`LearningCorrections.late`), a few
preview windows into its period; the law's fixed point (``c_{j+1} = c_j``)
is the same.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, cast

import numpy as np

from servo_axis.core.drive import current_from_torque
from servo_axis.core.errors import SignalError
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import PeerWatch, waited_too_long
from servo_axis.nodes.runtime import steady_clock
from servo_axis.params.factories import grid, learning_period_steps, run_steps
from servo_axis.params.values import FeedforwardValues
from servo_axis.wire import messages as msgs


class LearningCorrections:
    """The learning unit's corrections into the generator (see the module docstring).

    Parameters
    ----------
    node : ServoNode
        The feedforward node: its values, inputs, report and timers.
    generator : FeedforwardGenerator
        Where the corrections go.
    published : callable
        How many samples are out (samples ``0 .. published() - 1``).
    refill : callable
        Publish on, once a correction (or its fallback) let the window move.
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
        self._lockstep = values.mode == "lockstep"
        self._steps = run_steps(values)
        self._cycle_steps = learning_period_steps(values) or 0
        self._ratio = grid(values).ratio
        self._kt = values.nominal.torque_constant_Nm_per_A
        self._timeout_s = values.learning.timeout_s
        self._parts: dict[int, dict[int, tuple[float, ...]]] = {}
        self._waiting_since: float | None = None
        self._learner = PeerWatch()
        #: Lockstep: boundaries passed with the last correction (a fallback each).
        self.missed = 0
        #: Realtime: corrections applied from a sample into their period.
        self.late = 0
        axis, period_ns = values.axis, msgs.period_ns(values.control_period_s)
        target = generator.learning_side == "target"
        # Target side: (position, velocity) per reference instant; input side:
        # (current,) per control sample.
        self.topic = "learning/correction" if target else "learning/input_correction"
        self._stride = self._ratio if target else 1
        from_msg = msgs.correction_from_msg if target else msgs.input_correction_from_msg

        def decode(m: Any) -> tuple[int, int, tuple[float, ...]]:
            return self._gate(from_msg(m, axis=axis, period_ns_=period_ns))

        node.inputs.subscribe(self.topic, decode, self._take)
        node.create_timer(self._timeout_s / 5.0, self._watchdog, clock=steady_clock())

    def plant_moved(self) -> None:
        """The plant stepped on (``plant/status``): a wait at a boundary is not a stall yet."""
        if self._waiting_since is not None:
            self._waiting_since = time.monotonic()

    def go_on(self, ready: int | None, until: int) -> int | None:
        """Realtime: the boundaries before ``until`` go by with the last correction.

        Returns the generator's ``ready_until`` then (lockstep: ``ready``, unchanged).
        """
        if self._lockstep:
            return ready
        generator = self._generator
        lead = generator.boundary_lead()
        while ready is not None and ready < until and ready + lead < self._steps:
            generator.repeat_correction((ready + lead) // self._cycle_steps)
            ready = generator.ready_until()
        return ready

    def _gate(
        self, c: msgs.CorrectionSample | msgs.InputCorrectionSample
    ) -> tuple[int, int, tuple[float, ...]]:
        """``(period, index, values)`` of a correction for a period still to come."""
        if c.step % self._stride:
            raise SignalError(f"step {c.step} is not a reference instant")
        nd = self._cycle_steps // self._stride
        cycle, idx = divmod(c.step // self._stride, nd)
        ready = self._generator.ready_until()
        lead = self._generator.boundary_lead()
        if cycle < 1:
            raise SignalError(f"cycle {cycle + 1} is already under way")
        if self._lockstep and ready is not None and cycle * self._cycle_steps - lead < ready:
            raise SignalError(f"cycle {cycle + 1} is already under way")
        if not self._lockstep and (cycle + 1) * self._cycle_steps - lead <= self._published():
            raise SignalError(f"cycle {cycle + 1} is over")
        under_way = 0 if ready is None else ready // self._cycle_steps
        if cycle * self._cycle_steps >= self._steps or cycle > under_way + 2:
            raise SignalError(f"cycle {cycle + 1} is too far in the future")
        if isinstance(c, msgs.CorrectionSample):
            return cycle, idx, (c.position_rad, c.velocity_rad_s)
        return cycle, idx, (current_from_torque(c.torque_Nm, torque_constant_Nm_per_A=self._kt),)

    def _take(self, item: tuple[int, int, tuple[float, ...]]) -> None:
        cycle, idx, values_at = item
        nd = self._cycle_steps // self._stride
        part = self._parts.setdefault(cycle, {})
        part[idx] = values_at
        if len(part) < nd:
            return
        del self._parts[cycle]
        values = np.array([part[i] for i in range(nd)])
        columns = [values[:, c] for c in range(values.shape[1])]
        generator = self._generator
        if not self._lockstep and cycle * self._cycle_steps - generator.boundary_lead() < (
            self._published()
        ):
            # Realtime: the boundary went by with the last correction.
            generator.replace_correction(cycle, *columns)
            self.late += 1
        else:
            generator.set_correction(cycle, *columns)
        self._waiting_since = None
        self._learner.forget()
        self._refill()

    def _watchdog(self) -> None:
        # A dead learning unit must not stop the axis; a live one is waited
        # for (see the module docstring). The plant stands still at the
        # boundary when no plant/status has come since _waiting_since.
        now = time.monotonic()
        self._learner.look(self._node.inputs.peer_alive(self.topic), now)
        generator = self._generator
        ready = generator.ready_until()
        if (
            ready is None
            or self._published() < ready
            or ready >= self._steps
            or (self._lockstep and ready == generator.next_estimate_step)  # the identifier
        ):
            self._waiting_since = None
            return
        if self._waiting_since is None:
            self._waiting_since = now
            return
        why = waited_too_long(
            self._learner,
            waiting_since=self._waiting_since,
            timeout_s=self._timeout_s,
            now=now,
            name="learning unit",
            lockstep=self._lockstep,
        )
        if why is None:
            return  # it lives, or not for long enough: wait
        cycle = (ready + self._ratio) // self._cycle_steps
        generator.repeat_correction(cycle)
        self._parts.pop(cycle, None)
        self.missed += 1
        self._node.report.fallback(
            "learning_timeout",
            ready,
            f"no learning correction for cycle {cycle + 1} within {self._timeout_s} s ({why}): "
            f"keeping the last one ({self.missed} missed)",
        )
        # lost_at stays until a correction comes: a restarted unit that has
        # not delivered one yet may owe the next boundary too.
        self._waiting_since = None
        self._refill()
