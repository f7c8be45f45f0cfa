"""Feedback loop node: PID + DOB, sums feedforward and feedback, trips on faults.

Topics (relative to the namespace):

* subscribes ``state`` (JointState, every sample) and ``reference``
  (JointState, published ahead by the feedforward generator);
* publishes ``command`` (JointState, every sample) and ``fault``
  (Float64MultiArray ``[step, code, value]``, latched, once on a trip).

For ``state[k]`` the node answers ``command[k]`` as soon as
``reference[k]`` is here. If it does not come within ``input_timeout_s`` of
wall time, the loop trips: zero current from then on, fault published.

Run: ``python -m servo_axis.nodes.feedback --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis import msgs
from servo_axis.core.controllers import (
    DiscretePid,
    DisturbanceObserver,
    design_pid_pole_placement,
)
from servo_axis.core.errors import ParameterFileError, SignalError
from servo_axis.core.servo import Fault, FeedbackLoop, LoopOutput, SafetyLimits
from servo_axis.nodes.common import LATCHED_QOS, STREAM_QOS, Throttle, run_main, steady_clock
from servo_axis.params import build, read_parameters

SCHEMA: dict[str, object] = {
    "bandwidth_hz": 40.0,
    "dob.enabled": False,
    "dob.cutoff_hz": 80.0,
    "use_feedforward": True,
    "sensor": "encoder",
    "limits.following_error_m": 2e-3,
    "limits.travel_m": 0.2,
    "limits.current_A": 50.0,
    "input_timeout_s": 0.5,
    "max_preview_steps": 20000,
}

FAULT_LABELS = (
    "step",
    "code(1=following_error;2=travel;3=current;4=input_timeout)",
    "value(m_or_A_or_s)",
)
SENSORS = ("encoder", "scale")


def nominal(values: dict[str, Any]) -> dict[str, float]:
    """Nominal model keyword arguments shared by PID, DOB and PTC design."""
    return {
        "inertia_kgm2": values["nominal.inertia_kgm2"],
        "damping_Nms_per_rad": values["nominal.damping_Nms_per_rad"],
        "torque_constant_Nm_per_A": values["nominal.torque_constant_Nm_per_A"],
    }


def use_sim_time_by_default(node: Node) -> None:
    """Every node but the plant runs on the plant's clock unless told otherwise."""
    if "use_sim_time" not in node._parameter_overrides:
        node.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])


def build_loop(values: dict[str, Any]) -> FeedbackLoop:
    """The core feedback loop from the node's parameter values."""
    period = values["control_period_s"]
    gains = build(
        "", design_pid_pole_placement, bandwidth_hz=values["bandwidth_hz"], **nominal(values)
    )
    pid = build("", DiscretePid, gains=gains, period_s=period)
    dob = (
        build(
            "dob.",
            DisturbanceObserver,
            cutoff_hz=values["dob.cutoff_hz"],
            period_s=period,
            **nominal(values),
        )
        if values["dob.enabled"]
        else None
    )
    limits = build(
        "limits.",
        SafetyLimits,
        following_error_m=values["limits.following_error_m"],
        travel_m=values["limits.travel_m"],
        current_A=values["limits.current_A"],
    )
    return FeedbackLoop(
        pid=pid,
        dob=dob,
        lead_m_per_rad=values["lead_m_per_rad"],
        limits=limits,
        use_feedforward=values["use_feedforward"],
    )


class FeedbackNode(Node):
    """Feedback loop; see the module docstring for its protocol."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("feedback", **kwargs)
        values = read_parameters(self, SCHEMA)
        use_sim_time_by_default(self)
        if values["sensor"] not in SENSORS:
            raise ParameterFileError(
                f"parameter 'sensor': expected one of {SENSORS}, got {values['sensor']!r}"
            )
        if values["input_timeout_s"] <= 0.0:
            raise ParameterFileError(
                f"parameter 'input_timeout_s': expected > 0, got {values['input_timeout_s']!r}"
            )
        self.loop = build_loop(values)
        self._v = values
        self._axis = values["axis"]
        self._lead = values["lead_m_per_rad"]
        self._period_ns = msgs.period_ns(values["control_period_s"])
        self._lockstep = values["mode"] == "lockstep"

        self._command_msg = msgs.joint_state_template(msgs.motor_names(self._axis), ("effort",))
        self._command_pub = self.create_publisher(JointState, "command", STREAM_QOS)
        self._fault_pub = self.create_publisher(Float64MultiArray, "fault", LATCHED_QOS)
        self.create_subscription(JointState, "state", self._on_state, STREAM_QOS)
        self.create_subscription(JointState, "reference", self._on_reference, STREAM_QOS)
        self.create_timer(values["input_timeout_s"] / 10.0, self._watchdog, clock=steady_clock())

        self._references: dict[int, msgs.ReferenceSample] = {}
        self._last_reference_step = -1
        self._last_state_step = -1
        self._held: msgs.ReferenceSample | None = None
        self._pending: msgs.StateSample | None = None
        self._pending_since = 0.0
        self.rejected = 0
        self.missed_references = 0
        self._complain = Throttle()

    def _on_state(self, msg: JointState) -> None:
        try:
            state = msgs.state_from_msg(msg, axis=self._axis, period_ns_=self._period_ns)
        except SignalError as err:
            self._reject(f"state rejected: {err}")
            return
        if state.step <= self._last_state_step:
            self._reject(
                f"state rejected: stale stamp (step {state.step} after {self._last_state_step})"
            )
            return
        self._last_state_step = state.step
        self._pending = state
        self._pending_since = time.monotonic()
        self._try_answer()

    def _on_reference(self, msg: JointState) -> None:
        try:
            ref = msgs.reference_from_msg(msg, axis=self._axis, period_ns_=self._period_ns)
        except SignalError as err:
            self._reject(f"reference rejected: {err}")
            return
        if ref.step <= self._last_reference_step:
            self._reject(
                f"reference rejected: stale stamp (step {ref.step} after {self._last_reference_step})"
            )
            return
        if ref.step > max(self._last_state_step, 0) + self._v["max_preview_steps"]:
            self._reject(f"reference rejected: step {ref.step} is too far in the future")
            return
        self._last_reference_step = ref.step
        self._references[ref.step] = ref
        self._try_answer()

    def _try_answer(self) -> None:
        state = self._pending
        if state is None:
            return
        ref = self._references.pop(state.step, None)
        if ref is None:
            if self._lockstep and not self.loop.tripped:
                return  # the reference is guaranteed to come, or the watchdog trips
            self.missed_references += 0 if self.loop.tripped else 1
            ref = self._held
        else:
            self._held = ref
        self._pending = None
        if state.step % 1000 == 0:  # drop references of samples that never came
            for old in [s for s in self._references if s < state.step]:
                del self._references[old]
        angle = state.encoder_rad if self._v["sensor"] == "encoder" else state.scale_m / self._lead
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
        self._fault_pub.publish(msgs.labelled_array(FAULT_LABELS, [step, int(fault), value]))

    def _reject(self, text: str) -> None:
        self.rejected += 1
        if self._complain.ready():
            self.get_logger().warning(f"{text} ({self.rejected} rejected so far)")


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.feedback``."""
    return run_main("feedback", [FeedbackNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
