"""Feedforward generator node: reference + multirate PTC + friction table, ahead of time.

Topics (relative to the namespace):

* publishes ``reference`` (JointState, one message per control sample,
  published up to ``preview_steps`` samples ahead of the plant);
* subscribes ``plant/status`` (Float64MultiArray, every ``status_every_steps``
  of the plant) to know how far the plant is, without a callback per sample.

It publishes the first window as soon as ``wait_for_reference_subscribers``
subscribers have matched, then tops the window up whenever the plant has
used half of it. It never publishes past the end of the run, so that every
run records the same messages.

Run: ``python -m servo_axis.nodes.feedforward --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis import msgs
from servo_axis.core.errors import ParameterFileError, ServoAxisError, SignalError
from servo_axis.core.feedforward import FeedforwardGenerator
from servo_axis.core.friction_table import FrictionTable
from servo_axis.core.reference import make_reference
from servo_axis.nodes.common import STREAM_QOS, Throttle, run_main, steady_clock
from servo_axis.nodes.feedback import nominal, use_sim_time_by_default
from servo_axis.nodes.plant import STATUS_LABELS, run_steps
from servo_axis.params import build, read_parameters, section

SCHEMA: dict[str, object] = {
    "reference.kind": "sine",
    "reference.amplitude_m": 0.01,
    "reference.frequency_hz": 2.0,
    "reference.offset_m": 0.0,
    "reference.phase_rad": 0.0,
    "reference.distance_m": 0.01,
    "reference.move_time_s": 0.2,
    "reference.dwell_s": 0.1,
    "ptc.enabled": True,
    "friction_table.enabled": False,
    "friction_table.file": "",
    "preview_steps": 200,
    "wait_for_reference_subscribers": 0,
}

#: Which reference.* keys each kind takes.
REFERENCE_KEYS = {
    "sine": ("amplitude_m", "frequency_hz", "offset_m", "phase_rad"),
    "one_minus_cos": ("amplitude_m", "frequency_hz"),
    "point_to_point": ("distance_m", "move_time_s", "dwell_s"),
}


def build_generator(values: dict[str, Any]) -> FeedforwardGenerator:
    """The core feedforward generator from the node's parameter values."""
    ref_values = section(values, "reference")
    kind = ref_values.pop("kind")
    if kind not in REFERENCE_KEYS:
        raise ParameterFileError(
            f"parameter 'reference.kind': expected one of {sorted(REFERENCE_KEYS)}, got {kind!r}"
        )
    reference = build(
        "reference.", make_reference, kind=kind, **{k: ref_values[k] for k in REFERENCE_KEYS[kind]}
    )
    table = None
    if values["friction_table.enabled"]:
        path = values["friction_table.file"]
        if not path:
            raise ParameterFileError(
                "parameter 'friction_table.file': required when friction_table.enabled is true"
            )
        try:
            table = FrictionTable.load(path)
        except (OSError, ServoAxisError) as err:
            raise ParameterFileError(f"parameter 'friction_table.file': {err}") from err
    return build(
        "",
        FeedforwardGenerator,
        reference=reference,
        control_period_s=values["control_period_s"],
        lead_m_per_rad=values["lead_m_per_rad"],
        ptc_enabled=values["ptc.enabled"],
        friction_table=table,
        **nominal(values),
    )


class FeedforwardNode(Node):
    """Feedforward generator; see the module docstring for its protocol."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("feedforward", **kwargs)
        values = read_parameters(self, SCHEMA)
        use_sim_time_by_default(self)
        if values["preview_steps"] < 2:
            raise ParameterFileError(
                f"parameter 'preview_steps': expected >= 2, got {values['preview_steps']!r}"
            )
        self.generator = build_generator(values)
        self._v = values
        self._axis = values["axis"]
        self._period_ns = msgs.period_ns(values["control_period_s"])
        self._steps = run_steps(values)
        self._window = values["preview_steps"]

        self._msg = msgs.joint_state_template(
            msgs.motor_names(self._axis), ("position", "velocity", "effort")
        )
        self._pub = self.create_publisher(JointState, "reference", STREAM_QOS)
        self.create_subscription(Float64MultiArray, "plant/status", self._on_status, STREAM_QOS)
        self._start_timer = self.create_timer(0.01, self._try_start, clock=steady_clock())

        self.started = False
        self.published = 0  # samples 0 .. published-1 are out
        self._plant_step = -1
        self.rejected = 0
        self._complain = Throttle()

    def _try_start(self) -> None:
        if self._pub.get_subscription_count() < self._v["wait_for_reference_subscribers"]:
            return
        self._start_timer.cancel()
        self.started = True
        self._fill(self._window)

    def _on_status(self, msg: Float64MultiArray) -> None:
        try:
            step = int(msgs.labelled_array_values(msg, STATUS_LABELS)[0])
        except SignalError as err:
            self.rejected += 1
            if self._complain.ready():
                self.get_logger().warning(f"plant/status rejected: {err}")
            return
        self._plant_step = max(self._plant_step, step)
        if self.started and self.published - self._plant_step <= self._window // 2:
            self._fill(self._plant_step + self._window)

    def _fill(self, until: int) -> None:
        until = min(until, self._steps)
        if until <= self.published:
            return
        samples = self.generator.samples(self.published, until)
        for k, (pos, vel, cur) in enumerate(samples, start=self.published):
            self._pub.publish(
                msgs.reference_to_msg(
                    msgs.ReferenceSample(
                        step=k, position_rad=pos, velocity_rad_s=vel, current_A=cur
                    ),
                    axis=self._axis,
                    period_ns_=self._period_ns,
                )
            )
        self.published = until


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.feedforward``."""
    return run_main("feedforward", [FeedforwardNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
