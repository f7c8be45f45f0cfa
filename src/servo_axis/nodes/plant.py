"""Plant simulator node: the physical axis and, in lockstep, the simulation clock.

Topics (relative to the node's namespace):

* publishes ``state`` (JointState, every sample), ``/clock`` (every
  ``clock_every_steps`` samples: nodes use the clock for logs and timers,
  never for per-sample logic, so 100 Hz suffices and saves every node a
  callback per sample), ``plant/status`` (Float64MultiArray ``[step,
  deadline_misses, rejected_commands, command_timeouts]``, every
  ``status_every_steps``: the feedforward generator's progress signal);
* subscribes ``command`` (JointState) and ``recorder/progress``
  (Float64MultiArray, for flow control).

Lockstep: the plant publishes ``state[k]`` and waits for ``command[k]``,
then integrates one control period. Before publishing ``state[k]`` it waits
until the recorder has acknowledged step ``k - max_recorder_lag_steps``;
after the last step it waits until the recorder has everything, then stops.
Realtime: a wall-clock timer steps at the control period; a command that has
not arrived is a deadline miss and the newest current received is held, as a
drive holds its last set-point: a command that arrives after its tick is not
applied for its own step but replaces the held value (it is newer than what
is held), and the miss was counted at the tick.

Run: ``python -m servo_axis.nodes.plant --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis import msgs
from servo_axis.core.errors import ParameterFileError, SignalError
from servo_axis.core.friction import FrictionParams
from servo_axis.core.plant import (
    BallScrewParams,
    BallScrewPlant,
    DisturbanceParams,
    PlantOutput,
)
from servo_axis.core.sensors import SensorParams
from servo_axis.nodes.common import (
    LATCHED_QOS,
    STREAM_QOS,
    Throttle,
    run_main,
    steady_clock,
)
from servo_axis.params import build, read_parameters, section

SCHEMA: dict[str, object] = {
    "torque_constant_Nm_per_A": 0.715,
    "inertia_kgm2": 0.01,
    "damping_Nms_per_rad": 0.1,
    "modes.frequency_hz": [0.0],
    "modes.zeta": [0.0],
    "modes.a": [0.0],
    "dead_time_s": 0.0,
    "sim_step_s": 50e-6,
    "current_limit_A": 30.0,
    "initial_angle_rad": 0.0,
    "initial_velocity_rad_s": 0.0,
    "friction.rolling_coulomb_Nm": 0.0,
    "friction.presliding_width_m": 10e-6,
    "friction.elements": 8,
    "friction.coulomb_Nm": 0.0,
    "friction.coulomb_smoothing_rad_s": 1e-3,
    "friction.viscous_Nms_per_rad": 0.0,
    "disturbance.amplitude_Nm": 0.0,
    "disturbance.frequency_hz": 4.0,
    "disturbance.phase_rad": 0.0,
    "encoder.resolution": 2.0 * np.pi / 2**20,
    "encoder.noise_std": 0.0,
    "scale.resolution": 100e-9,
    "scale.noise_std": 0.0,
    "noise_seed": 0,
    "publish_clock": True,
    "clock_every_steps": 10,
    "wait_for_state_subscribers": 0,
    "wait_for_clock_subscribers": 0,
    "wait_for_status_subscribers": 0,
    "flow_control": False,
    "max_recorder_lag_steps": 200,
    "command_timeout_s": 2.0,
    "status_every_steps": 50,
}

# The modes lists default to [0.0] only so that their type is known; an
# all-zero frequency list means "no modes".
_NO_MODES = [0.0]

#: Wall time the plant waits at the end for the recorder to acknowledge everything.
FINISH_TIMEOUT_S = 10.0

STATUS_LABELS = ("step", "deadline_misses", "rejected_commands", "command_timeouts")
PROGRESS_LABELS = ("steps_recorded",)


def plant_params(values: dict[str, Any]) -> BallScrewParams:
    """Build :class:`BallScrewParams` from the node's parameter values."""
    freqs, zetas, gains = (values[f"modes.{k}"] for k in ("frequency_hz", "zeta", "a"))
    if freqs == _NO_MODES and zetas == _NO_MODES and gains == _NO_MODES:
        freqs, zetas, gains = [], [], []
    if not len(freqs) == len(zetas) == len(gains):
        raise ParameterFileError(
            "parameter 'modes': modes.frequency_hz, modes.zeta and modes.a must have the "
            f"same length, got {len(freqs)}, {len(zetas)}, {len(gains)}"
        )
    return build(
        "",
        BallScrewParams,
        torque_constant_Nm_per_A=values["torque_constant_Nm_per_A"],
        inertia_kgm2=values["inertia_kgm2"],
        damping_Nms_per_rad=values["damping_Nms_per_rad"],
        lead_m_per_rad=values["lead_m_per_rad"],
        modes=tuple(zip(freqs, zetas, gains, strict=True)),
        dead_time_s=values["dead_time_s"],
        control_period_s=values["control_period_s"],
        sim_step_s=values["sim_step_s"],
        current_limit_A=values["current_limit_A"],
        initial_angle_rad=values["initial_angle_rad"],
        initial_velocity_rad_s=values["initial_velocity_rad_s"],
        friction=build("friction.", FrictionParams, **section(values, "friction")),
        disturbance=build("disturbance.", DisturbanceParams, **section(values, "disturbance")),
        encoder=build("encoder.", SensorParams, **section(values, "encoder")),
        scale=build("scale.", SensorParams, **section(values, "scale")),
    )


def run_steps(values: dict[str, Any]) -> int:
    """Number of control samples of the run (``duration_s / control_period_s``)."""
    steps = round(values["duration_s"] / values["control_period_s"])
    if steps < 1:
        raise ParameterFileError(
            f"parameter 'duration_s': expected at least one control period, got {values['duration_s']!r}"
        )
    return int(steps)


def state_sample(out: PlantOutput, lead_m_per_rad: float) -> msgs.StateSample:
    """The wire sample of a plant output."""
    return msgs.StateSample(
        step=out.step,
        encoder_rad=out.encoder_rad,
        scale_m=out.scale_m,
        velocity_rad_s=out.velocity_rad_s,
        velocity_m_s=out.velocity_m_s,
        motor_torque_Nm=out.motor_torque_Nm,
        friction_force_N=out.friction_torque_Nm / lead_m_per_rad,
    )


class PlantNode(Node):
    """Plant simulator; see the module docstring for its protocol."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("plant", **kwargs)
        values = read_parameters(self, SCHEMA)
        if self.get_parameter("use_sim_time").value:
            raise ParameterFileError(
                "parameter 'use_sim_time': the plant owns the clock; set it false"
            )
        self._params = plant_params(values)
        self._axis = values["axis"]
        self._period_ns = msgs.period_ns(values["control_period_s"])
        self._steps = run_steps(values)
        self._lockstep = values["mode"] == "lockstep"
        for key in ("clock_every_steps", "status_every_steps", "max_recorder_lag_steps"):
            if values[key] < 1:
                raise ParameterFileError(f"parameter '{key}': expected >= 1, got {values[key]!r}")
        self._v = values
        self.plant = BallScrewPlant(self._params, rng=np.random.default_rng(values["noise_seed"]))

        # One message per publisher, refilled each sample: publish() serialises
        # at once, and building a fresh JointState costs more than the physics.
        self._state_msg = msgs.joint_state_template(
            msgs.state_names(self._axis), ("position", "velocity", "effort")
        )
        self._state_pub = self.create_publisher(JointState, "state", STREAM_QOS)
        self._clock_pub = (
            self.create_publisher(Clock, "/clock", STREAM_QOS) if values["publish_clock"] else None
        )
        self._status_pub = self.create_publisher(Float64MultiArray, "plant/status", STREAM_QOS)
        self.create_subscription(JointState, "command", self._on_command, STREAM_QOS)
        self.create_subscription(
            Float64MultiArray, "recorder/progress", self._on_progress, LATCHED_QOS
        )

        self.done = False
        self.started = False
        self._awaiting: int | None = None  # step whose command we wait for
        self._command: float | None = None
        self._last_current = 0.0
        self._held_step = -1  # step of the command whose current is held
        self._recorded = -1
        self._finishing = False
        self._deadline_misses = 0
        self._rejected = 0
        self._timeouts = 0
        self._waiting_since = time.monotonic()
        self._complain = Throttle()
        self._start_timer = self.create_timer(0.01, self._try_start, clock=steady_clock())
        self._rt_timer: Any = None
        self._finish_started = 0.0
        self.create_timer(0.05, self._watchdog, clock=steady_clock())

    # -- start ---------------------------------------------------------------
    def _connected(self) -> bool:
        v = self._v
        if self._state_pub.get_subscription_count() < v["wait_for_state_subscribers"]:
            return False
        if self._status_pub.get_subscription_count() < v["wait_for_status_subscribers"]:
            return False
        if self._clock_pub is not None:
            if self._clock_pub.get_subscription_count() < v["wait_for_clock_subscribers"]:
                return False
        return not (v["flow_control"] and self._recorded < 0)

    def _try_start(self) -> None:
        if self.started or not self._connected():
            return
        self._start_timer.cancel()
        self.started = True
        self.get_logger().info(f"connected; running {self._steps} steps ({self._v['mode']})")
        self._publish(self.plant.output())
        if self._lockstep:
            self._awaiting = 0
            self._waiting_since = time.monotonic()
        else:
            self._rt_timer = self.create_timer(
                self._v["control_period_s"], self._realtime_tick, clock=steady_clock()
            )

    # -- callbacks -------------------------------------------------------------
    def _on_command(self, msg: JointState) -> None:
        try:
            cmd = msgs.command_from_msg(msg, axis=self._axis, period_ns_=self._period_ns)
        except SignalError as err:
            self._reject(f"command rejected: {err}")
            return
        expected = self.plant.step_index
        if not self._lockstep and self._held_step < cmd.step < expected:
            self._last_current, self._held_step = cmd.current_A, cmd.step
            return
        if cmd.step != expected:
            when = "stale" if cmd.step < expected else "future"
            self._reject(f"command rejected: {when} stamp (step {cmd.step}, expected {expected})")
            return
        self._command = cmd.current_A
        if self._lockstep:
            self._advance()

    def _on_progress(self, msg: Float64MultiArray) -> None:
        try:
            (recorded,) = msgs.labelled_array_values(msg, PROGRESS_LABELS)
        except SignalError as err:
            self._reject(f"recorder/progress rejected: {err}")
            return
        self._recorded = max(self._recorded, int(recorded))
        if self.started:
            self._advance()

    def _watchdog(self) -> None:
        if self._finishing and not self.done:
            if time.monotonic() - self._finish_started > FINISH_TIMEOUT_S:
                self.get_logger().error(
                    f"recorder acknowledged {self._recorded} of {self._steps} steps within "
                    f"{FINISH_TIMEOUT_S} s; stopping anyway"
                )
                self.done = True
            return
        if not self._lockstep or self._awaiting is None or self.done or self._command is not None:
            return
        if time.monotonic() - self._waiting_since > self._v["command_timeout_s"]:
            self._timeouts += 1
            self.get_logger().error(
                f"no valid command for step {self._awaiting} within "
                f"{self._v['command_timeout_s']} s: applying zero current"
            )
            self._command = 0.0
            self._advance()

    # -- stepping --------------------------------------------------------------
    def _advance(self) -> None:
        """Lockstep: integrate once the command is here and the recorder keeps up."""
        if self._finishing:
            if not self._v["flow_control"] or self._recorded >= self._steps:
                self.done = True
            return
        if self._command is None or self._awaiting is None:
            return
        next_step = self.plant.step_index + 1
        if next_step < self._steps and self._v["flow_control"]:
            if self._recorded < next_step - self._v["max_recorder_lag_steps"]:
                return  # the progress callback resumes us
        current, self._command = self._command, None
        out = self.plant.step(current)
        if out.step >= self._steps:
            self._awaiting = None
            self._finish()
            return
        self._awaiting = out.step
        self._waiting_since = time.monotonic()
        self._publish(out)

    def _realtime_tick(self) -> None:
        if self._finishing:
            return
        if self._command is None:
            self._deadline_misses += 1
            current = self._last_current
        else:
            current = self._command
            self._held_step = self.plant.step_index
        self._command = None
        self._last_current = current
        out = self.plant.step(current)
        if out.step >= self._steps:
            self._rt_timer.cancel()
            self._finish()
            return
        self._publish(out)

    def _finish(self) -> None:
        """After the last step: wait for the recorder to have everything.

        In realtime a last status carries the final deadline-miss count. In
        lockstep there is none: the recorder acknowledges only the per-sample
        topics, so a message after the last sample might or might not make
        it into the bag, and the bag must be the same every run.
        """
        self._finishing = True
        self._finish_started = time.monotonic()
        if not self._lockstep:
            self._publish_status()
        self._advance()

    def _publish(self, out: PlantOutput) -> None:
        if self._clock_pub is not None and out.step % self._v["clock_every_steps"] == 0:
            self._clock_pub.publish(msgs.clock_message(out.step, self._period_ns))
        self._state_pub.publish(
            msgs.write_state(
                self._state_msg,
                state_sample(out, self._params.lead_m_per_rad),
                period_ns_=self._period_ns,
            )
        )
        if out.step % self._v["status_every_steps"] == 0:
            self._publish_status()

    def _publish_status(self) -> None:
        self._status_pub.publish(
            msgs.labelled_array(
                STATUS_LABELS,
                [self.plant.step_index, self._deadline_misses, self._rejected, self._timeouts],
            )
        )

    def _reject(self, text: str) -> None:
        self._rejected += 1
        if self._complain.ready():
            self.get_logger().warning(f"{text} ({self._rejected} rejected so far)")


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.plant``."""
    return run_main("plant", [PlantNode], args, done=lambda nodes: all(n.done for n in nodes))


if __name__ == "__main__":
    raise SystemExit(main())
