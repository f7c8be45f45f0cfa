"""Feedback loop node: PID + DOB, sums feedforward and feedback, trips on faults.

Topics (relative to the namespace):

* subscribes ``state`` (JointState, every sample) and ``reference``
  (JointState, published ahead by the feedforward generator);
* publishes ``command`` (JointState, every sample) and ``fault``
  (Float64MultiArray ``[step, code, value]``, latched, once on a trip).

For ``state[k]`` the node answers ``command[k]`` as soon as
``reference[k]`` is here. If it does not come within ``input_timeout_s`` of
wall time, the loop trips: zero current from then on, fault published. The
controlled output is :func:`servo_axis.core.feedback.output.controlled_output`
of the ``sensor`` parameter.

Run: ``python -m servo_axis.nodes.feedback --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import time
from typing import Any

from servo_axis.core.errors import SignalError
from servo_axis.core.feedback.loop import Fault, LoopOutput
from servo_axis.core.feedback.output import controlled_output
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import SampleBuffer, StampGate
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.factories import build_loop
from servo_axis.wire import messages as msgs


class FeedbackNode(ServoNode):
    """Feedback loop; see the module docstring for its protocol."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("feedback", **kwargs)
        values = self.values
        self.loop = build_loop(values)
        self._v = values
        self._axis = values["axis"]
        self._lead = values["lead_m_per_rad"]
        self._period_ns = msgs.period_ns(values["control_period_s"])
        self._lockstep = values["mode"] == "lockstep"

        self._command_msg = msgs.joint_state_template(msgs.motor_names(self._axis), ("effort",))
        self._command_pub = self.publisher("command")
        self._fault_pub = self.publisher("fault")
        period_ns, axis = self._period_ns, self._axis
        self.subscribe(
            "state",
            lambda m: self._state_gate(msgs.state_from_msg(m, axis=axis, period_ns_=period_ns)),
            self._on_state,
        )
        self.subscribe(
            "reference",
            lambda m: self._reference_gate(
                msgs.reference_from_msg(m, axis=axis, period_ns_=period_ns)
            ),
            self._on_reference,
        )
        self.create_timer(values["input_timeout_s"] / 10.0, self._watchdog, clock=steady_clock())

        self._references: SampleBuffer[msgs.ReferenceSample] = SampleBuffer()
        self._states = StampGate()
        self._refs = StampGate()
        self._held: msgs.ReferenceSample | None = None
        self._pending: msgs.StateSample | None = None
        self._pending_since = 0.0
        self.missed_references = 0

    def _state_gate(self, state: msgs.StateSample) -> msgs.StateSample:
        self._states.accept(state.step)
        return state

    def _reference_gate(self, ref: msgs.ReferenceSample) -> msgs.ReferenceSample:
        self._refs.check(ref.step)
        if ref.step > max(self._states.last, 0) + self._v["max_preview_steps"]:
            raise SignalError(f"step {ref.step} is too far in the future")
        self._refs.accept(ref.step)
        return ref

    def _on_state(self, state: msgs.StateSample) -> None:
        self._pending = state
        self._pending_since = time.monotonic()
        self._try_answer()

    def _on_reference(self, ref: msgs.ReferenceSample) -> None:
        self._references.put(ref.step, ref)
        self._try_answer()

    def _try_answer(self) -> None:
        state = self._pending
        if state is None:
            return
        ref = self._references.take(state.step)
        if ref is None:
            if self._lockstep and not self.loop.tripped:
                return  # the reference is guaranteed to come, or the watchdog trips
            self.missed_references += 0 if self.loop.tripped else 1
            ref = self._held
        else:
            self._held = ref
        self._pending = None
        if state.step % 1000 == 0:  # drop references of samples that never came
            self._references.drop_before(state.step)
        angle = controlled_output(
            self._v["sensor"],
            encoder_rad=state.encoder_rad,
            scale_m=state.scale_m,
            lead_m_per_rad=self._lead,
        )
        if ref is None:
            out = LoopOutput(0.0, 0.0, 0.0, 0.0)
        else:
            out = self.loop.update(
                angle_rad=angle, reference_rad=ref.position_rad, feedforward_A=ref.current_A
            )
        if out.fault is not None:
            self._publish_fault(state.step, out.fault, out.fault_value)
        self._command_pub.publish(
            msgs.write_command(
                self._command_msg,
                msgs.CommandSample(step=state.step, current_A=out.current_A),
                period_ns_=self._period_ns,
            )
        )

    def _watchdog(self) -> None:
        if self._pending is None or self.loop.tripped:
            return
        waited = time.monotonic() - self._pending_since
        if waited > self._v["input_timeout_s"]:
            self.loop.trip(Fault.INPUT_TIMEOUT)
            self._publish_fault(self._pending.step, Fault.INPUT_TIMEOUT, waited)
            self._try_answer()

    def _publish_fault(self, step: int, fault: Fault, value: float) -> None:
        self.get_logger().error(
            f"TRIP at step {step}: {fault.name.lower()} ({value:.6g}); current set to zero"
        )
        self._fault_pub.publish(msgs.labelled_array(msgs.FAULT_LABELS, [step, int(fault), value]))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.feedback``."""
    return run_main("feedback", [FeedbackNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
