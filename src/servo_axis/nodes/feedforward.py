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

import time
from typing import Any

import numpy as np
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
    "reference.ramp_s": 0.0,
    "reference.distance_m": 0.01,
    "reference.move_time_s": 0.2,
    "reference.dwell_s": 0.1,
    "ptc.enabled": True,
    "friction_table.enabled": False,
    "friction_table.file": "",
    "preview_steps": 200,
    "wait_for_reference_subscribers": 0,
    "learning.enabled": False,
    "learning.cycle_s": 0.5,
    "learning.timeout_s": 0.5,
}

#: Which reference.* keys each kind takes.
REFERENCE_KEYS = {
    "sine": ("amplitude_m", "frequency_hz", "offset_m", "phase_rad", "ramp_s"),
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
    cycle_steps = None
    if values["learning.enabled"]:
        cycle_steps = round(values["learning.cycle_s"] / values["control_period_s"])
        if abs(cycle_steps * values["control_period_s"] - values["learning.cycle_s"]) > 1e-9:
            raise ParameterFileError(
                f"parameter 'learning.cycle_s': expected a whole number of control periods, "
                f"got {values['learning.cycle_s']!r}"
            )
    return build(
        "",
        FeedforwardGenerator,
        learning_cycle_steps=cycle_steps,
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
        self._learning = values["learning.enabled"]
        self._corrections: dict[int, dict[int, tuple[float, float]]] = {}
        self.missed_corrections = 0
        self._waiting_since: float | None = None
        if self._learning:
            self._cycle_steps = round(values["learning.cycle_s"] / values["control_period_s"])
            self.create_subscription(
                JointState, "learning/correction", self._on_correction, STREAM_QOS
            )
            self.create_timer(
                values["learning.timeout_s"] / 5.0, self._learning_watchdog, clock=steady_clock()
            )
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
        if self._waiting_since is not None:
            self._waiting_since = time.monotonic()  # the plant still moves: not stalled yet
        if self.started and self.published - self._plant_step <= self._window // 2:
            self._fill(self._plant_step + self._window)

    def _on_correction(self, msg: JointState) -> None:
        try:
            c = msgs.correction_from_msg(msg, axis=self._axis, period_ns_=self._period_ns)
        except SignalError as err:
            self._reject(f"learning/correction rejected: {err}")
            return
        nd = self._cycle_steps // 2
        if c.step % 2:
            self._reject(f"learning/correction rejected: step {c.step} is not a reference instant")
            return
        cycle, idx = divmod(c.step // 2, nd)
        ready = self.generator.ready_until()
        if cycle < 1 or (ready is not None and cycle * self._cycle_steps - 2 < ready):
            self._reject(f"learning/correction rejected: cycle {cycle + 1} is already under way")
            return
        under_way = 0 if ready is None else ready // self._cycle_steps
        if cycle * self._cycle_steps >= self._steps or cycle > under_way + 2:
            self._reject(
                f"learning/correction rejected: cycle {cycle + 1} is too far in the future"
            )
            return
        part = self._corrections.setdefault(cycle, {})
        part[idx] = (c.position_rad, c.velocity_rad_s)
        if len(part) == nd:
            del self._corrections[cycle]
            values = np.array([part[i] for i in range(nd)])
            self.generator.set_correction(cycle, values[:, 0], values[:, 1])
            self._waiting_since = None
            self._fill(self._plant_step + self._window)

    def _learning_watchdog(self) -> None:
        # A dead learning unit must not stop the axis: once the preview is used
        # up to the cycle boundary and no plant/status has come for
        # learning.timeout_s (the plant is stalled at the boundary), go on with
        # the last correction (no learning for that cycle). Keep it below the
        # feedback's input_timeout_s.
        ready = self.generator.ready_until()
        if ready is None or self.published < ready or ready >= self._steps:
            self._waiting_since = None
            return
        if self._waiting_since is None:
            self._waiting_since = time.monotonic()
        elif time.monotonic() - self._waiting_since > self._v["learning.timeout_s"]:
            cycle = (ready + 2) // self._cycle_steps
            self.generator.repeat_correction(cycle)
            self.missed_corrections += 1
            self.get_logger().warning(
                f"no learning correction for cycle {cycle + 1} within {self._v['learning.timeout_s']} s: "
                f"keeping the last one ({self.missed_corrections} missed)"
            )
            self._waiting_since = None
            self._fill(self._plant_step + self._window)

    def _reject(self, text: str) -> None:
        self.rejected += 1
        if self._complain.ready():
            self.get_logger().warning(f"{text} ({self.rejected} rejected so far)")

    def _fill(self, until: int) -> None:
        until = min(until, self._steps)
        ready = self.generator.ready_until()
        if ready is not None and ready < self._steps <= ready + 2:
            # The run's last two samples look one instant into the cycle after
            # it, whose correction the learning unit never publishes: repeat
            # the last one at once (what the timeout would do, without the wait).
            self.generator.repeat_correction((ready + 2) // self._cycle_steps)
            ready = self.generator.ready_until()
        if ready is not None:
            until = min(until, ready)
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
