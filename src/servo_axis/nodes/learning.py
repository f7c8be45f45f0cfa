"""Learning unit node: RPTC with the (n-times) learning filter, per cycle (paper 000).

Topics (relative to the namespace):

* subscribes ``state`` (JointState, every sample; it uses the reference
  instants ``k = 2i``);
* publishes ``learning/correction`` (JointState, ``Nd`` messages per cycle,
  stamped with the reference instants of the *next* cycle: ``position`` =
  correction of the target angle (rad), ``velocity`` = its central-difference
  velocity (rad/s)) and ``learning/cycle_stats`` (Float64MultiArray
  ``[cycle, rms_m, max_m, cycles_learned]``, once per cycle).

At the last reference instant of cycle ``j`` it has the whole error
``e_j = x/R - y`` against the *original* target (it builds the same reference
as the feedforward generator from ``reference.*``), learns
``c_{j+1} = c_j + Q~n e_j`` (eq. (9), (19)) if learning is on for that cycle
(``start_cycle``, the switch of 000 Fig. 17), publishes ``c_{j+1}`` and
writes its memory file. See docs/learning_protocol.md.

Run: ``python -m servo_axis.nodes.learning --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis import msgs
from servo_axis.core.errors import ParameterFileError, ServoAxisError, SignalError
from servo_axis.core.reference import make_reference
from servo_axis.core.rptc import LearningParams, PeriodicSignalGenerator, load_memory, save_memory
from servo_axis.nodes.common import STREAM_QOS, Throttle, run_main
from servo_axis.nodes.feedback import use_sim_time_by_default
from servo_axis.nodes.feedforward import REFERENCE_KEYS
from servo_axis.nodes.feedforward import SCHEMA as FF_SCHEMA
from servo_axis.nodes.plant import run_steps
from servo_axis.params import build, read_parameters, section

SCHEMA: dict[str, object] = {
    **{k: v for k, v in FF_SCHEMA.items() if k.startswith("reference.")},
    "cycle_s": 0.5,
    "nq": 20,
    "n": 1,
    "start_cycle": 2,
    "memory.file": "",
    "memory.resume": True,
    "memory.on_bad_file": "fail",
}

STATS_LABELS = ("cycle", "rms_m", "max_m", "cycles_learned")
ON_BAD_FILE = ("fail", "clear")


class LearningNode(Node):
    """Learning unit; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("learning", **kwargs)
        values = read_parameters(self, SCHEMA)
        use_sim_time_by_default(self)
        tu = values["control_period_s"]
        tr = 2.0 * tu
        nd = round(values["cycle_s"] / tr)
        if nd < 4 or not math.isclose(nd * tr, values["cycle_s"], rel_tol=1e-9):
            raise ParameterFileError(
                f"parameter 'cycle_s': expected a whole number (>= 4) of reference periods {tr!r} s, "
                f"got {values['cycle_s']!r}"
            )
        # In lockstep the plant can run up to one whole cycle ahead of this
        # node (the feedforward generator holds the next cycle until its
        # correction is out); the state stream's history must hold that much.
        if 2 * nd > STREAM_QOS.depth - 10:
            raise ParameterFileError(
                f"parameter 'cycle_s': at most {(STREAM_QOS.depth - 10) * tu!r} s "
                f"({STREAM_QOS.depth - 10} control samples) per learning cycle, got {values['cycle_s']!r}"
            )
        if values["start_cycle"] < 2:
            raise ParameterFileError(
                f"parameter 'start_cycle': expected >= 2 (nothing is learned before cycle 1 ends), "
                f"got {values['start_cycle']!r}"
            )
        if values["memory.on_bad_file"] not in ON_BAD_FILE:
            raise ParameterFileError(
                f"parameter 'memory.on_bad_file': expected one of {ON_BAD_FILE}, got {values['memory.on_bad_file']!r}"
            )
        params = build(
            "", LearningParams, samples_per_cycle=nd, nq=values["nq"], n=values["n"], period_s=tr
        )
        ref_values = section(values, "reference")
        kind = ref_values.pop("kind")
        if kind not in REFERENCE_KEYS:
            raise ParameterFileError(
                f"parameter 'reference.kind': expected one of {sorted(REFERENCE_KEYS)}"
            )
        self.reference = build(
            "reference.",
            make_reference,
            kind=kind,
            **{k: ref_values[k] for k in REFERENCE_KEYS[kind]},
        )
        self.psg = PeriodicSignalGenerator(params)
        self._v = values
        self._nd = nd
        self._tr = tr
        self._lead = values["lead_m_per_rad"]
        self._axis = values["axis"]
        self._period_ns = msgs.period_ns(tu)
        self._scenario = values["scenario.name"] or "unnamed"
        self._steps = run_steps(values)
        self._memory = Path(values["memory.file"]) if values["memory.file"] else None
        self._resume_memory()

        self._correction_msg = msgs.joint_state_template(
            msgs.motor_names(self._axis), ("position", "velocity")
        )
        self._correction_pub = self.create_publisher(JointState, "learning/correction", STREAM_QOS)
        self._stats_pub = self.create_publisher(
            Float64MultiArray, "learning/cycle_stats", STREAM_QOS
        )
        # raw: only every second sample (the reference instants) is decoded.
        self.create_subscription(JointState, "state", self._on_state, STREAM_QOS, raw=True)

        self._error = np.full(nd, math.nan)
        self._target = np.zeros(nd)
        self._target_cycle = -1
        self._last_step = -1
        self.rejected = 0
        self._complain = Throttle()

    def _resume_memory(self) -> None:
        if self._memory is None or not self._v["memory.resume"] or not self._memory.exists():
            return
        try:
            correction, cycles = load_memory(
                self._memory, params=self.psg.params, scenario=self._scenario
            )
        except (OSError, ServoAxisError) as err:
            if self._v["memory.on_bad_file"] == "fail":
                raise ParameterFileError(f"parameter 'memory.file': {err}") from err
            self.get_logger().warning(f"memory file not used, starting clean: {err}")
            return
        self.psg.load(correction, cycles)
        self.get_logger().info(f"resumed {cycles} learned cycles from {self._memory}")

    def _on_state(self, data: bytes) -> None:
        try:
            step, rem = divmod(msgs.stamp_ns_from_cdr(data), self._period_ns)
            if rem:
                raise SignalError(f"header.stamp: not on the control grid of {self._period_ns} ns")
            if step <= self._last_step:
                raise SignalError(f"stale stamp (step {step} after {self._last_step})")
            if step >= self._steps:
                raise SignalError(
                    f"stamp beyond the run's last step {self._steps - 1} (step {step})"
                )
            self._last_step = step
            if step % 2:
                return  # only the reference instants are learned from
            msg = deserialize_message(data, JointState)
            state = msgs.state_from_msg(msg, axis=self._axis, period_ns_=self._period_ns)
        except SignalError as err:
            self._reject(f"state rejected: {err}")
            return
        cycle, idx = divmod(state.step // 2, self._nd)
        if cycle != self._target_cycle:
            # The original target of a whole cycle in one call.
            t = (cycle * self._nd + np.arange(self._nd)) * self._tr
            self._target = self.reference.sample(t)[0] / self._lead
            self._target_cycle = cycle
        self._error[idx] = self._target[idx] - state.encoder_rad
        # The run's last cycle ends with the run: nothing after it would be
        # used, and a message published as the run stops may or may not make
        # it into the bag (which must be the same every run).
        if idx == self._nd - 1 and 2 * (cycle + 1) * self._nd < self._steps:
            self._end_of_cycle(cycle)

    def _end_of_cycle(self, cycle: int) -> None:
        error = self._error
        complete = bool(np.all(np.isfinite(error)))
        # Cycle ``cycle`` (0-based) ends; its correction is for 1-based cycle
        # ``cycle + 2``; learning is on from ``start_cycle`` (1-based, >= 2).
        if cycle + 2 >= self._v["start_cycle"]:
            if complete:
                self.psg.learn(error)
            else:
                # Started or restarted mid-cycle, or states were rejected: a
                # partial error would teach a wrong correction.
                received = int(np.count_nonzero(np.isfinite(error)))
                self.get_logger().warning(
                    f"cycle {cycle + 1} not learned: {received} of {self._nd} reference instants received"
                )
        # Persist before publishing: whatever a listener has seen of this
        # cycle (correction, stats) is already on disk if the unit dies now.
        if self._memory is not None:
            save_memory(self._memory, self.psg, scenario=self._scenario)
        position, velocity = self.psg.states()
        first = (cycle + 1) * self._nd
        for idx in range(self._nd):
            self._correction_pub.publish(
                msgs.write_correction(
                    self._correction_msg,
                    msgs.CorrectionSample(
                        2 * (first + idx), float(position[idx]), float(velocity[idx])
                    ),
                    period_ns_=self._period_ns,
                )
            )
        err_m = self._lead * error[np.isfinite(error)]
        rms = float(np.sqrt(np.mean(err_m**2))) if err_m.size else 0.0
        peak = float(np.max(np.abs(err_m))) if err_m.size else 0.0
        self._stats_pub.publish(
            msgs.labelled_array(STATS_LABELS, [cycle + 1, rms, peak, self.psg.cycles_learned])
        )
        self._error = np.full(self._nd, math.nan)

    def _reject(self, text: str) -> None:
        self.rejected += 1
        if self._complain.ready():
            self.get_logger().warning(f"{text} ({self.rejected} rejected so far)")


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.learning``."""
    return run_main("learning", [LearningNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
