"""Parameter identifier node: online identification of J, D, U, C (paper 003, Figs. 3-4).

Topics (relative to the namespace):

* subscribes ``state`` (JointState, every sample: the measured angle
  ``y_m[k]`` is the encoder reading) and ``command`` (JointState, every
  sample: the motor torque reference ``T_m[k] = K_T i[k]`` (N m) the
  feedback answered ``state[k]`` with, its current reference times the
  nominal ``K_T``; the torque of the regression);
* publishes ``identifier/estimates`` (Float64MultiArray,
  :data:`~servo_axis.wire.cdr.ESTIMATE_LABELS`) once per RLS period.

Convention (one for the whole suite): the estimate computed from the
samples up to step ``k`` (``k = (n + 1) R - 1`` for the ``n``-th, ``R =
rls_period_s / T_u``) is stamped ``step = k`` and ``applies_from_step = k +
1 + latency_s / T_u``; the feedforward generator uses it for every sample
from there on, and publishes no sample from there on before it has it. An
estimate that would apply only after the run's last step is not published
(nothing would use it, and a message sent as the run stops may or may not be
recorded).

Both streams are taken exactly in order (:class:`~servo_axis.wire.streams.StreamGate`),
each sample validated whole; step ``k`` is identified once both ``state[k]``
and ``command[k]`` are in.

Memory: after every estimate the identifier's whole state (filters, RLS,
covariance, PE window, ``C``) and the estimate are written atomically to
``memory.file`` before the estimate is published. A restarted identifier
(``late_join``) loads it, publishes the last estimate again (the feedforward
takes an identical repeat silently) and takes the streams from the sample
after the last one it had, out of their history (transient-local, 2000
samples deep: the plant cannot be further ahead while the feedforward waits
for the next estimate), so that it resumes bit-identically. Samples of that
history up to the memory's last step are skipped, not counted as rejected.

Run: ``python -m servo_axis.nodes.identifier --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from servo_axis.core.errors import ParameterFileError, ServoAxisError
from servo_axis.core.identification.online.dlpid import Estimate
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import stream_gate
from servo_axis.nodes.runtime import run_main
from servo_axis.params.factories import build_identifier, identifier_schedule, run_steps
from servo_axis.params.values import IdentifierValues
from servo_axis.storage import load_identifier_memory, save_identifier_memory
from servo_axis.wire import messages as msgs


class IdentifierNode(ServoNode):
    """Online identifier; see the module docstring for its protocol."""

    # Realtime: the default scheduler. Only the per-sample pair's executor
    # threads and the plant's clock run under SCHED_FIFO: a node of the
    # reference path at FIFO (as before, one or two below the pair) starved
    # the pair's middleware threads, which stay SCHED_OTHER (issue 30).
    realtime_below = None

    values: IdentifierValues

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("identifier", **kwargs)
        values = self.values
        self.identifier = build_identifier(values)
        _, self._latency = identifier_schedule(values)
        self._axis = values.axis
        self._period_ns = msgs.period_ns(values.control_period_s)
        self._steps = run_steps(values)
        self._scenario = values.scenario.name or "unnamed"
        self._memory = Path(values.memory.file) if values.memory.file else None
        self.last_estimate: msgs.EstimateData | None = None
        self.published = 0
        self._resume_memory()

        self._pub = self.publisher("identifier/estimates")
        # A restarted identifier continues after its memory's last step;
        # one without memory joins at the first step it gets.
        resumed = self.identifier.last_step
        first: int | None = 0
        if values.late_join:
            first = None if resumed is None else resumed + 1
        self._skip_through = -1 if resumed is None else resumed
        self._lockstep = values.mode == "lockstep"
        gate = {"first": first, "limit": self._steps, "period_ns": self._period_ns}
        self._state_gate = stream_gate(self._lockstep, **gate)
        self._command_gate = stream_gate(self._lockstep, **gate)
        self._angles: dict[int, float] = {}
        self._torques: dict[int, float] = {}
        self._last_torque = 0.0
        self.held_torques = 0  # realtime: steps whose command never came
        self.held_angles = 0  # realtime: steps whose state never came
        self._last_angle = 0.0
        self.inputs_subscribed = False
        self.graph.after_consumers_matched(
            [(self._pub, "identifier/estimates", values.wait_for_estimate_subscribers)],
            self._subscribe_inputs,
        )

    def _resume_memory(self) -> None:
        if self._memory is None or not self.values.memory.resume or not self._memory.exists():
            return
        if not self.values.late_join:
            # A state is the middle of a run: a fresh start (step 0) cannot
            # continue it, and overwrites it at its first estimate.
            self.get_logger().info(f"fresh start: {self._memory} not resumed (not late_join)")
            return
        try:
            state, last = load_identifier_memory(
                self._memory, method=self.values.method, scenario=self._scenario
            )
            self.identifier.load_state(state)
            self.last_estimate = None if last is None else msgs.check_estimate_values(last)
        except (OSError, ServoAxisError) as err:
            raise ParameterFileError(f"parameter 'memory.file': {err}") from err
        self.get_logger().info(
            f"resumed after step {self.identifier.last_step} from {self._memory}"
        )

    def _subscribe_inputs(self) -> None:
        state = msgs.joint_codec("state", axis=self._axis, period_ns_=self._period_ns)
        command = msgs.joint_codec("command", axis=self._axis, period_ns_=self._period_ns)
        if self.last_estimate is not None:
            # The dead identifier may have saved it without publishing it.
            self._pub.publish(msgs.estimate_to_msg(self.last_estimate))
        self.inputs.subscribe(
            "state",
            lambda data: self._fresh(state.decode(data)),
            lambda s: self._take(s.step, angle=s.encoder_rad) if s is not None else None,
            raw=True,
            gate=self._state_gate,
        )
        self.inputs.subscribe(
            "command",
            lambda data: self._fresh(command.decode(data)),
            lambda c: self._take(c.step, torque=c.torque_Nm) if c is not None else None,
            raw=True,
            gate=self._command_gate,
        )
        self.inputs_subscribed = True

    def _fresh(self, sample: Any) -> Any:
        """The sample, or None for history a resumed identifier already had."""
        return None if sample.step <= self._skip_through else sample

    def _take(self, step: int, *, angle: float | None = None, torque: float | None = None) -> None:
        self.realtime.start()
        if angle is not None:
            self._angles[step] = angle
        if torque is not None:
            self._torques[step] = torque
        while True:
            last = self.identifier.last_step
            if last is not None:
                nxt = last + 1
            elif self._angles and self._torques:
                # A late joiner without memory starts where both streams are
                # in; what one stream has before that is never used.
                nxt = max(min(self._angles), min(self._torques))
                for buffer in (self._angles, self._torques):
                    for old in [k for k in buffer if k < nxt]:
                        del buffer[old]
            else:
                return
            if nxt in self._angles:
                y = self._angles[nxt]
            elif not self._lockstep and any(k > nxt for k in self._angles):
                # Realtime: state[nxt] will not come (the identifier fell
                # behind and its stream jumped, StreamGate): the last angle
                # is held, as for a command that never came, and it goes on.
                y = self._last_angle
                self.held_angles += 1
            else:
                return
            if nxt in self._torques:
                torque = self._torques.pop(nxt)
            elif not self._lockstep and any(k > nxt for k in self._torques):
                # Realtime: command[nxt] will not come (the feedback skipped
                # it or it was lost); the plant held the last current, as a
                # drive does, and so does the identifier.
                torque = self._last_torque
                self.held_torques += 1
            else:
                return
            self._last_torque = torque
            self._angles.pop(nxt, None)
            self._last_angle = y
            estimate = self.identifier.update(nxt, y, torque)
            if estimate is not None:
                self._publish(estimate)

    def realtime_counts(self) -> dict[str, int]:
        return {"identifier_samples_held": self.held_angles + self.held_torques}

    def diagnostic_values(self) -> list[tuple[str, Any]]:
        return [
            ("estimates", self.published),
            ("states_skipped", self._state_gate.skipped),
            ("samples_held", self.held_angles + self.held_torques),
        ]

    def diagnostic_stamp_ns(self) -> int:
        """The simulation time of the last sample identified (it does not run on ``/clock``)."""
        return max(self.identifier.last_step or 0, 0) * self._period_ns

    def _publish(self, e: Estimate) -> None:
        applies = e.step + 1 + self._latency
        if applies >= self._steps:
            return  # nothing would use it
        values = (e.J, e.D, e.U, e.C, e.kappa)
        if not all(math.isfinite(v) for v in values):
            # Cannot happen inside the projection's bounds; never put NaN on the wire.
            self.get_logger().error(f"estimate at step {e.step} not finite {values}: not published")
            return
        data = msgs.EstimateData(
            step=e.step,
            applies_from_step=applies,
            inertia_kgm2=e.J,
            damping_Nms_per_rad=e.D,
            unbalance_Nm=e.U,
            coulomb_Nm=e.C,
            kappa=e.kappa,
            updated=e.updated,
        )
        # Persist before publishing: whatever the feedforward has used is on
        # disk if the identifier dies now.
        if self._memory is not None:
            save_identifier_memory(
                self._memory,
                self.identifier.state(),
                data.values(),
                method=self.values.method,
                scenario=self._scenario,
            )
        self.last_estimate = data
        self._pub.publish(msgs.estimate_to_msg(data))
        self.published += 1


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.identifier``."""
    return run_main("identifier", [IdentifierNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
