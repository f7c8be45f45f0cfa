"""Feedforward generator node: reference + multirate PTC + feedforward terms, ahead of time.

Topics (relative to the namespace):

* publishes ``reference`` (JointState, one message per control sample,
  published up to ``preview_steps`` samples ahead of the plant; its
  ``effort`` is the feedforward torque ``K_T,n u_ff``, N m, of the
  generator's current ``u_ff`` with ``nominal.torque_constant_Nm_per_A``,
  :mod:`servo_axis.core.drive`);
* subscribes ``plant/status`` (Float64MultiArray, every ``status_every_steps``
  of the plant) to know how far the plant is, without a callback per sample;
* with learning (``learning.enabled``), its learning part
  (:mod:`servo_axis.nodes.feedforward_corrections`) subscribes the learning
  unit's corrections and applies each period's from the period it is
  stamped for;
* with ``adaptive.enabled`` (paper 003), its estimates part
  (:mod:`servo_axis.nodes.feedforward_estimates`) subscribes
  ``identifier/estimates`` and applies each estimate from its
  ``applies_from_step``.

It publishes the first window as soon as its ``reference`` publisher is
matched with its ``wait_for_reference_subscribers`` consumers (the feedback
and the recorder, counted by topic whatever their node names:
:meth:`~servo_axis.nodes.graph.GraphWatch.consumers_matched`),
then tops the window up whenever the plant has used half of it. It never
publishes past the end of the run, so that every run records the same
messages, nor past what its parts let go (the samples of a learning
boundary before the next period's correction is in; in lockstep the
samples an estimate not yet in applies to). A ``plant/status`` must carry a
whole step, not below the last one and not beyond the references published
(realtime: the run's end); others are rejected.

Run: ``python -m servo_axis.nodes.feedforward --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import time
from typing import Any, NamedTuple

from servo_axis.core.drive import torque_from_current
from servo_axis.core.errors import SignalError
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.feedforward_corrections import LearningCorrections
from servo_axis.nodes.feedforward_estimates import Estimates, estimates_part
from servo_axis.nodes.lockstep import stream_gate
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.factories import build_generator, run_steps
from servo_axis.params.values import FeedforwardValues
from servo_axis.wire import messages as msgs
from servo_axis.wire.streams import StampOrigin, StreamGate


class Step(NamedTuple):
    """A state's step, all the generator takes of it."""

    step: int


class FeedforwardNode(ServoNode):
    """Feedforward generator; see the module docstring for its protocol."""

    # Realtime: SCHED_FIFO two below the pair (48 under the default 50), so
    # its executor thread and its receive threads (47) stay below the pair's
    # receive threads (49), which it never delays. At the default scheduler
    # the reference each state needs waited behind the host's other jobs: a
    # 2 s realtime ptc_friction missed a median of 73 of 2000 deadlines, 17
    # with this (scripts/rt_ab.py, alternated run by run; the bare pair 10).
    # At 49 (one below) it competed with the pair's receive threads: worse.
    realtime_below = 2

    values: FeedforwardValues

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("feedforward", **kwargs)
        values = self.values
        self.generator = build_generator(values)
        self._lockstep = values.mode == "lockstep"
        self._steps = run_steps(values)
        self._window = values.preview_steps
        self._kt = values.nominal.torque_constant_Nm_per_A
        self._pub = self.publisher("reference")
        # Sent as CDR bytes, as the plant's and the feedback's per-sample streams.
        self._reference_codec = msgs.joint_codec(
            "reference", axis=values.axis, period_ns_=msgs.period_ns(values.control_period_s)
        )
        self.started = False
        self.published = 0  # samples 0 .. published-1 are out
        self._plant_step = -1
        parts = {"published": lambda: self.published, "refill": self.refill}
        self.corrections = (
            LearningCorrections(self, self.generator, **parts) if values.learning.enabled else None
        )
        self.estimates: Estimates | None = (
            estimates_part(self, self.generator, **parts) if values.adaptive.enabled else None
        )
        if values.progress_from_state:
            # An outside plant need publish `state` only: each state's stamp is its step.
            period = msgs.period_ns(values.control_period_s)
            if values.state_stamps == "plant_clock" and not self._lockstep:
                # A plant that owns its clock: steps from its stamps (StampOrigin).
                origin, by_ns = (
                    StampOrigin(period),
                    msgs.joint_codec("state", axis=values.axis, period_ns_=1),
                )

                def decode(data: Any) -> Any:
                    sample = by_ns.decode(data)
                    return Step(origin.state_step(sample.step, time.monotonic_ns()))

                # Such a plant goes on after the run's last step (a driver).
                gate = StreamGate(window=self._steps, first=0)
            else:
                codec = msgs.joint_codec("state", axis=values.axis, period_ns_=period)
                decode = codec.decode
                gate = stream_gate(self._lockstep, first=0, limit=self._steps)
            self.inputs.subscribe(
                "state",
                decode,
                lambda sample: self._on_status(min(sample.step, self._steps)),
                raw=True,
                gate=gate,
            )
        else:
            self.inputs.subscribe(
                "plant/status",
                lambda m: self._plausible_status(
                    msgs.labelled_array_values(m, msgs.STATUS_LABELS)[0]
                ),
                self._on_status,
            )
        self._start_timer = self.create_timer(0.01, self._try_start, clock=steady_clock())

    def diagnostic_values(self) -> list[tuple[str, Any]]:
        corrections, estimates = self.corrections, self.estimates
        return [
            ("started", self.started),
            ("published_up_to_step", self.published),
            ("plant_step", self._plant_step),
            ("missed_corrections", 0 if corrections is None else corrections.missed),
            ("late_corrections", 0 if corrections is None else corrections.late),
            ("estimates_taken", 0 if estimates is None else estimates.taken),
            ("late_estimates", 0 if estimates is None else estimates.late),
        ]

    def realtime_counts(self) -> dict[str, int]:
        return {
            "late_corrections": 0 if self.corrections is None else self.corrections.late,
            "late_estimates": 0 if self.estimates is None else self.estimates.late,
        }

    def _try_start(self) -> None:
        extra = self._outside_feedback_reads()
        if extra is None or not self.graph.consumers_matched(
            self._pub, "reference", self.values.wait_for_reference_subscribers + extra
        ):
            return
        self._start_timer.cancel()
        self.started = True
        self._fill(self._window)

    def _outside_feedback_reads(self) -> int | None:
        """Readers of ``reference`` an outside feedback adds: 1 if it subscribes, None while unknown.

        Nobody waits for an outside node on an input its role need not take:
        a regulator with its own set-point reads ``state`` only. Once
        ``command`` has had a publisher for
        :data:`~servo_axis.nodes.graph.MATCH_SETTLE_S` (its node's
        subscriptions are in the graph by then), the node that publishes it
        either subscribes to ``reference`` (then the first window waits for it:
        a volatile reader gets nothing sent before it matched) or does not.
        """
        if not self.graph.is_outside("feedback"):
            return 0
        if not self.graph.readers_settled("command", 0):
            return None
        return 1 if self.graph.answerer_listens("command", "reference") else 0

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
        self.realtime.start()
        self._plant_step = step
        if self.estimates is not None:
            self.estimates.plant_moved(step)
        if self.corrections is not None:
            self.corrections.plant_moved()
        if self.started and self.published - self._plant_step <= self._window // 2:
            self._fill(self._plant_step + self._window)

    def refill(self) -> None:
        """Publish up to a window ahead of the plant (once started): a part let the window on."""
        if self.started:
            self._fill(self._plant_step + self._window)

    def _fill(self, until: int) -> None:
        until = min(until, self._steps)
        self.generator.repeat_past_run(self._steps)
        ready = self.generator.ready_until()
        if self.corrections is not None:
            ready = self.corrections.go_on(ready, until)
        if ready is not None:
            until = min(until, ready)
        if self.estimates is not None:
            until = self.estimates.limit(until)
        if until <= self.published:
            return
        samples = self.generator.samples(self.published, until)
        kt, codec = self._kt, self._reference_codec
        for k, (pos, vel, cur) in enumerate(samples, start=self.published):
            self._pub.publish(
                codec.encode(
                    msgs.ReferenceSample(
                        step=k,
                        position_rad=pos,
                        velocity_rad_s=vel,
                        torque_Nm=torque_from_current(cur, torque_constant_Nm_per_A=kt),
                    )
                )
            )
        self.published = until


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.feedforward``."""
    return run_main("feedforward", [FeedforwardNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
