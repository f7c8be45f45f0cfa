"""Feedforward generator node: reference + multirate PTC + feedforward terms, ahead of time.

Topics (relative to the namespace):

* publishes ``reference`` (JointState, one message per control sample,
  published up to ``preview_steps`` samples ahead of the plant; its
  ``effort`` is the feedforward torque ``K_T,n u_ff``, N m, of the
  generator's current ``u_ff`` with ``nominal.torque_constant_Nm_per_A``,
  :mod:`servo_axis.core.drive`);
* subscribes ``plant/status`` (Float64MultiArray, every ``status_every_steps``
  of the plant) to know how far the plant is, without a callback per sample;
* with learning, subscribes ``learning/correction`` (target-side laws) or
  ``learning/input_correction`` (input-side laws: a torque, N m, turned
  back into a current with the nominal torque constant) and applies each
  period's correction from the period it is stamped for;
* with ``adaptive.enabled`` (paper 003), subscribes ``identifier/estimates``
  and applies each estimate from its ``applies_from_step``: the PTC's model
  is rebuilt from ``J``, ``D`` (eq. (11)) and the MNC gets ``U``, ``C``; in
  lockstep no sample from there on is published before the estimate is in
  (realtime: below). Estimates
  must come in order, each the next one expected (its step and application
  step on the schedule of ``adaptive.rls_period_s`` and
  ``adaptive.latency_s``); an exact repeat of the last one (a restarted
  identifier sends its last estimate again) is taken silently; anything else
  (NaN, out of order, another schedule) is rejected and counted, and the
  model in force stays.

It publishes the first window as soon as its ``reference`` publisher is
matched with its ``wait_for_reference_subscribers`` consumers (the feedback
and the recorder, counted by topic whatever their node names:
:meth:`~servo_axis.nodes.base.ServoNode.consumers_matched`),
then tops the window up whenever the plant has used half of it. It never
publishes past the end of the run, so that every run records the same
messages. A ``plant/status`` must carry a whole step, not below the last
one and not beyond the references published (realtime: the run's end);
others are rejected.

Fallback (``learning.timeout_s``): in lockstep a cycle waits for its
correction as long as the learning unit lives (liveliness of
``learning/correction``). It runs with the last correction (recorded as a
fallback) only once the unit has been gone for ``learning.timeout_s``, or
once it went away during the wait (a respawned unit did not see the cycle
end it owed a correction for) and the plant has then stood still for
``learning.timeout_s``.

In realtime the references never wait for a correction: a learning unit
cannot have ``c_{j+1}`` in before the boundary it is learned at, and the
plant does not wait. The boundary goes by with the last correction
(``repeat_correction``) and ``c_{j+1}`` applies from the first sample not
yet published once it is in (``replace_correction``; counted as
``late_corrections`` on ``/diagnostics``), a few preview windows into its
period; the law's fixed point (``c_{j+1} = c_j``) is the same.

Identifier fallback (``adaptive.timeout_s``, lockstep): the same rule with
the identifier as the peer (liveliness of ``identifier/estimates``); on it
the generator keeps the estimates in force for the rest of the run and takes
no later one (:meth:`~servo_axis.core.feedforward.generator.FeedforwardGenerator.stop_estimates`).

In realtime an estimate is waited for only until its sample is due: the
plant's clock does not wait for the identifier, and a reference held back
past its sample's deadline makes the feedback hold the last one while the
axis moves on (measured: ``dlpid_tilt_lpf2``, 4 s at 0.4 ms, the identifier
some 4 ms late at step ~8,650: 0.43 rad of tracking error, 165 times
lockstep's RMS). So when the plant's clock (estimated from ``plant/status``,
:func:`~servo_axis.core.deadlines.start_estimate_ns`) is
:data:`ESTIMATE_LEAD_S` before the next estimate's ``applies_from_step``
and the estimate is not in, the references of one more estimate period go
out with the model in force, and the estimate applies from the first
reference instant not yet published once it is in (counted as
``late_estimates``;
:meth:`~servo_axis.core.feedforward.generator.FeedforwardGenerator.stop_waiting_for_estimates`).
An estimate in time applies from its own step, as in lockstep. Nothing
stalls, so there is no identifier fallback; a restarted identifier's
estimates are applied as they come.

Run: ``python -m servo_axis.nodes.feedforward --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from servo_axis.core.deadlines import start_estimate_ns
from servo_axis.core.drive import current_from_torque, torque_from_current
from servo_axis.core.errors import ServoAxisError, SignalError
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import PeerWatch
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.factories import (
    build_generator,
    estimate_schedule,
    grid,
    learning_period_steps,
    run_steps,
)
from servo_axis.wire import messages as msgs

#: Realtime: how long before the next estimate's first sample is due the
#: references go on without it (publishing, the timer's lateness and the
#: transport to the feedback: 0.2-0.5 ms each on a loaded 2-core host).
ESTIMATE_LEAD_S = 1.2e-3


class FeedforwardNode(ServoNode):
    """Feedforward generator; see the module docstring for its protocol."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("feedforward", **kwargs)
        values = self.values
        self.generator = build_generator(values)
        self._v = values
        self._axis = values["axis"]
        self._grid = grid(values)
        self._period_ns = msgs.period_ns(values["control_period_s"])
        self._steps = run_steps(values)
        self._window = values["preview_steps"]
        self._kt = values["nominal.torque_constant_Nm_per_A"]
        # Estimate period and latency (control samples); an estimate applies
        # ``latency + 1`` samples after the last one it is computed from.
        self._estimate_period, latency = (
            estimate_schedule(values, "adaptive.rls_period_s", "adaptive.latency_s")
            if values["adaptive.enabled"]
            else (0, -1)
        )
        self._estimate_lag = latency + 1

        self._pub = self.publisher("reference")
        # Sent as CDR bytes, as the plant's and the feedback's per-sample streams.
        self._reference_codec = msgs.joint_codec(
            "reference", axis=self._axis, period_ns_=self._period_ns
        )
        self._learning = values["learning.enabled"]
        self._lockstep = values["mode"] == "lockstep"
        # Realtime: the references must be out before the feedback needs
        # them, so the generator preempts other work too, below the pair.
        self.realtime_scheduling(below=1)
        self._corrections: dict[int, dict[int, tuple[float, ...]]] = {}
        self.missed_corrections = 0
        self.late_corrections = 0  # realtime: applied from a sample into their period
        self._waiting_since: float | None = None
        self._learner = PeerWatch()
        self.started = False
        self.published = 0  # samples 0 .. published-1 are out
        self._plant_step = -1
        period_ns, axis = self._period_ns, self._axis
        if self._learning:
            self._cycle_steps = learning_period_steps(values) or 0
            if self.generator.learning_side == "target":
                # (position, velocity) per reference instant
                self._correction_topic = "learning/correction"
                self._stride = self._grid.ratio
                self.subscribe(
                    self._correction_topic,
                    lambda m: self._correction_gate(
                        msgs.correction_from_msg(m, axis=axis, period_ns_=period_ns)
                    ),
                    self._on_correction,
                )
            else:
                # (current,) per control sample
                self._correction_topic = "learning/input_correction"
                self._stride = 1
                self.subscribe(
                    self._correction_topic,
                    lambda m: self._correction_gate(
                        msgs.input_correction_from_msg(m, axis=axis, period_ns_=period_ns)
                    ),
                    self._on_correction,
                )
            self.create_timer(
                values["learning.timeout_s"] / 5.0, self._learning_watchdog, clock=steady_clock()
            )
        self._adaptive = values["adaptive.enabled"]
        self._identifier = PeerWatch()
        self.last_estimate: msgs.EstimateData | None = None
        self.estimates_taken = 0
        self.late_estimates = 0  # realtime: applied from after their step
        self._estimate_wait_since: float | None = None
        if self._adaptive:
            self.subscribe("identifier/estimates", self._estimate_gate, self._on_estimate)
            if self._lockstep:
                self.create_timer(
                    values["adaptive.timeout_s"] / 5.0,
                    self._identifier_watchdog,
                    clock=steady_clock(),
                )
            else:
                self.generator.stop_waiting_for_estimates()
                self._lead_steps = -(-round(ESTIMATE_LEAD_S * 1e9) // self._period_ns)
                self._without_until = 0  # published without their estimate up to here
                self._plant_start_ns: int | None = None  # the plant clock's d_0
                self._start_provisional = False  # from status 0, sent before d_0
                self._due_for: int | None = None  # the estimate step the timer is set for
                self._due_timer = self.create_timer(1.0, self._estimate_due, clock=steady_clock())
                self._due_timer.cancel()
        self.subscribe(
            "plant/status",
            lambda m: self._plausible_status(msgs.labelled_array_values(m, msgs.STATUS_LABELS)[0]),
            self._on_status,
        )
        self._start_timer = self.create_timer(0.01, self._try_start, clock=steady_clock())

    def diagnostic_values(self) -> list[tuple[str, Any]]:
        return [
            ("started", self.started),
            ("published_up_to_step", self.published),
            ("plant_step", self._plant_step),
            ("missed_corrections", self.missed_corrections),
            ("late_corrections", self.late_corrections),
            ("estimates_taken", self.estimates_taken),
            ("late_estimates", self.late_estimates),
        ]

    def realtime_counts(self) -> dict[str, int]:
        return {"late_corrections": self.late_corrections, "late_estimates": self.late_estimates}

    def _try_start(self) -> None:
        if not self.consumers_matched(
            self._pub, "reference", self._v["wait_for_reference_subscribers"]
        ):
            return
        self._start_timer.cancel()
        self.started = True
        self._fill(self._window)

    def _plausible_status(self, value: float) -> int:
        """The plant's step: whole, not below the last one, not beyond what the
        plant can have reached (lockstep: the references published)."""
        if value != int(value):
            raise SignalError(f"step: expected a whole number, got {value!r}")
        step = int(value)
        if step < self._plant_step:
            raise SignalError(f"step {step} below the last one {self._plant_step}")
        bound = self.published if self._lockstep else self._steps
        if step > bound:
            raise SignalError(f"step {step} beyond what the plant can have reached ({bound})")
        return step

    def _on_status(self, step: int) -> None:
        self.start_realtime()
        self._plant_step = step
        if self._adaptive and not self._lockstep:
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
        if self._waiting_since is not None:
            self._waiting_since = time.monotonic()  # the plant still moves: not stalled yet
        if self._estimate_wait_since is not None:
            self._estimate_wait_since = time.monotonic()
        if self.started and self.published - self._plant_step <= self._window // 2:
            self._fill(self._plant_step + self._window)

    def _correction_gate(
        self, c: msgs.CorrectionSample | msgs.InputCorrectionSample
    ) -> tuple[int, int, tuple[float, ...]]:
        """``(period, index, values)`` of a correction for a period still to come."""
        if c.step % self._stride:
            raise SignalError(f"step {c.step} is not a reference instant")
        nd = self._cycle_steps // self._stride
        cycle, idx = divmod(c.step // self._stride, nd)
        ready = self.generator.ready_until()
        lead = self.generator.boundary_lead()
        if cycle < 1:
            raise SignalError(f"cycle {cycle + 1} is already under way")
        if self._lockstep and ready is not None and cycle * self._cycle_steps - lead < ready:
            raise SignalError(f"cycle {cycle + 1} is already under way")
        if not self._lockstep and (cycle + 1) * self._cycle_steps - lead <= self.published:
            raise SignalError(f"cycle {cycle + 1} is over")
        under_way = 0 if ready is None else ready // self._cycle_steps
        if cycle * self._cycle_steps >= self._steps or cycle > under_way + 2:
            raise SignalError(f"cycle {cycle + 1} is too far in the future")
        if isinstance(c, msgs.CorrectionSample):
            return cycle, idx, (c.position_rad, c.velocity_rad_s)
        return cycle, idx, (current_from_torque(c.torque_Nm, torque_constant_Nm_per_A=self._kt),)

    def _on_correction(self, item: tuple[int, int, tuple[float, ...]]) -> None:
        cycle, idx, values_at = item
        nd = self._cycle_steps // self._stride
        part = self._corrections.setdefault(cycle, {})
        part[idx] = values_at
        if len(part) == nd:
            del self._corrections[cycle]
            values = np.array([part[i] for i in range(nd)])
            columns = [values[:, c] for c in range(values.shape[1])]
            if not self._lockstep and cycle * self._cycle_steps - self.generator.boundary_lead() < (
                self.published
            ):
                # Realtime: the boundary went by with the last correction.
                self.generator.replace_correction(cycle, *columns)
                self.late_corrections += 1
            else:
                self.generator.set_correction(cycle, *columns)
            self._waiting_since = None
            self._learner.forget()
            self._fill(self._plant_step + self._window)

    def _estimate_gate(self, msg: Any) -> msgs.EstimateData | None:
        """The next estimate expected; None for an exact repeat of the last one (or once stopped)."""
        e = msgs.estimate_from_msg(msg)
        if e == self.last_estimate:
            return None  # a restarted identifier sends its last estimate again
        expected = self.generator.next_estimate_step
        if expected is None:
            return None  # estimates stopped (fallback): the model in force stays
        if e.applies_from_step != expected:
            raise SignalError(
                f"applies_from_step {e.applies_from_step}: expected the next estimate's {expected}"
            )
        if e.applies_from_step - e.step != self._estimate_lag:
            raise SignalError(
                f"step {e.step}: expected {expected - self._estimate_lag} for an estimate "
                f"applying from {expected} (latency {self._estimate_lag - 1} steps)"
            )
        return e

    def _on_estimate(self, e: msgs.EstimateData | None) -> None:
        if e is None:
            return
        try:
            first = self.generator.set_estimate(
                e.applies_from_step,
                inertia_kgm2=e.inertia_kgm2,
                damping_Nms_per_rad=e.damping_Nms_per_rad,
                unbalance_Nm=e.unbalance_Nm,
                coulomb_Nm=e.coulomb_Nm,
            )
        except ServoAxisError as err:
            # A value the model refuses (the PTC's discretisation, say): the
            # model in force stays and the estimate is counted as rejected.
            self.reject("identifier/estimates", f"identifier/estimates rejected: {err}")
            return
        self.last_estimate = e
        self.estimates_taken += 1
        self.late_estimates += first != e.applies_from_step
        self._estimate_wait_since = None
        self._identifier.forget()
        if self.started:
            self._fill(self._plant_step + self._window)

    def _identifier_watchdog(self) -> None:
        now = time.monotonic()
        self._identifier.look(self.peer_alive("identifier/estimates"), now)
        expected = self.generator.next_estimate_step
        if expected is None or self.published < expected or expected >= self._steps:
            self._estimate_wait_since = None
            return
        if self._estimate_wait_since is None:
            self._estimate_wait_since = now
            return
        timeout = self._v["adaptive.timeout_s"]
        why = self._too_late(
            self._identifier, self._estimate_wait_since, timeout, now, "identifier"
        )
        if why is None:
            return
        self.generator.stop_estimates()
        self.fallback(
            "identifier_timeout",
            expected,
            f"no estimate applying from step {expected} within {timeout} s ({why}): keeping "
            f"the estimates in force for the rest of the run ({self.estimates_taken} taken)",
        )
        self._estimate_wait_since = None
        self._fill(self._plant_step + self._window)

    def _too_late(
        self, peer: PeerWatch, waiting_since: float, timeout: float, now: float, name: str
    ) -> str | None:
        """Why a wait for ``peer`` has lasted too long, or None to go on waiting.

        Realtime: the plant stood still for ``timeout``. Lockstep: the peer has
        been gone for ``timeout``, or it went away during the wait (a
        respawned peer may not deliver what the dead one owed) and the plant
        has then stood still for ``timeout``; while it lives, never.
        """
        if not self._lockstep:
            still = now - waiting_since
            return f"the plant stood still for {still:.3g} s" if still > timeout else None
        if peer.gone_for(now) > timeout:
            return f"the {name} has been gone for {peer.gone_for(now):.3g} s"
        if peer.lost_at is not None:
            still = now - max(waiting_since, peer.lost_at)
            if still > timeout:
                return (
                    f"the {name} went away during the wait and the plant stood still "
                    f"for {still:.3g} s"
                )
        return None

    def _learning_watchdog(self) -> None:
        # A dead learning unit must not stop the axis; a live one is waited
        # for (see the module docstring). The plant stands still at the
        # boundary when no plant/status has come since _waiting_since.
        now = time.monotonic()
        self._learner.look(self.peer_alive(self._correction_topic), now)
        ready = self.generator.ready_until()
        if (
            ready is None
            or self.published < ready
            or ready >= self._steps
            or (self._lockstep and ready == self.generator.next_estimate_step)  # the identifier
        ):
            self._waiting_since = None
            return
        if self._waiting_since is None:
            self._waiting_since = now
            return
        timeout = self._v["learning.timeout_s"]
        why = self._too_late(self._learner, self._waiting_since, timeout, now, "learning unit")
        if why is None:
            return  # it lives, or not for long enough: wait
        cycle = (ready + self._grid.ratio) // self._cycle_steps
        self.generator.repeat_correction(cycle)
        self._corrections.pop(cycle, None)
        self.missed_corrections += 1
        self.fallback(
            "learning_timeout",
            ready,
            f"no learning correction for cycle {cycle + 1} within {timeout} s ({why}): "
            f"keeping the last one ({self.missed_corrections} missed)",
        )
        # lost_at stays until a correction comes: a restarted unit that has
        # not delivered one yet may owe the next boundary too.
        self._waiting_since = None
        self._fill(self._plant_step + self._window)

    def _fill(self, until: int) -> None:
        until = min(until, self._steps)
        self.generator.repeat_past_run(self._steps)
        ready = self.generator.ready_until()
        if not self._lockstep and self._learning:
            # Realtime: the references never wait for a correction (it cannot
            # be in before the boundary it is learned at); the last one goes
            # on, and the new one applies once it is in (_on_correction).
            lead = self.generator.boundary_lead()
            while ready is not None and ready < until and ready + lead < self._steps:
                self.generator.repeat_correction((ready + lead) // self._cycle_steps)
                ready = self.generator.ready_until()
        if ready is not None:
            until = min(until, ready)
        if self._adaptive and not self._lockstep:
            until = self._within_estimates(until)
        if until <= self.published:
            return
        samples = self.generator.samples(self.published, until)
        kt = self._kt
        for k, (pos, vel, cur) in enumerate(samples, start=self.published):
            self._pub.publish(
                self._reference_codec.encode(
                    msgs.ReferenceSample(
                        step=k,
                        position_rad=pos,
                        velocity_rad_s=vel,
                        torque_Nm=torque_from_current(cur, torque_constant_Nm_per_A=kt),
                    )
                )
            )
        self.published = until

    def _within_estimates(self, until: int) -> int:
        """Realtime: ``until``, but not past the next estimate's step before it is due."""
        nxt = self.generator.next_estimate_step
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

    def _estimate_due(self) -> None:
        """Realtime: the samples from ``_due_for`` are due; go on if their estimate is not in.

        An estimate that came in time moved the next wait on, and
        :meth:`_within_estimates` set the timer for that one.
        """
        self._due_timer.cancel()
        wait_at, self._due_for = self._due_for, None
        nxt = self.generator.next_estimate_step
        if wait_at is None or nxt is None or nxt > wait_at:
            return
        self._without_until = wait_at + self._estimate_period
        self._fill(self._plant_step + self._window)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.feedforward``."""
    return run_main("feedforward", [FeedforwardNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
