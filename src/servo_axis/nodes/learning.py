"""Learning unit node: runs the learning law of ``law`` per period.

A cycle law with target-side corrections (``rptc``, paper 000) or a trial law
with input-side ones (``silc``, ``pilc_bf``, ``pilc_bfft``, paper 001).

Topics (relative to the namespace):

* subscribes ``state`` (JointState, every sample; a target-side law uses the
  reference instants ``k = ratio * i``, an input-side law every sample);
* publishes, for a target-side law, ``learning/correction`` (JointState,
  ``Nd`` messages per cycle, stamped with the reference instants of the
  *next* cycle: ``position`` = correction of the target angle (rad),
  ``velocity`` = its central-difference velocity (rad/s)); for an
  input-side law ``learning/input_correction`` (``N`` messages per trial,
  stamped with the control samples of the next trial: ``effort`` = the
  torque ``K_T,n f_{j+1}`` (N m) of the law's current ``f_{j+1}`` (A), with
  ``nominal.torque_constant_Nm_per_A``, :mod:`servo_axis.core.drive`);
  ``learning/cycle_stats`` (Float64MultiArray
  ``[cycle, rms_m, max_m, cycles_learned]``, once per period); and, for a
  projection-based law, ``learning/parameters`` and
  ``learning/friction_table``.

At the last sample of period ``j`` it has the whole error ``e_j = x/R - y``
against the *original* target (it builds the same reference as the
feedforward generator from ``reference.*``) and the controlled output ``y``
the feedback uses (``sensor``, :func:`controlled_output`), learns (from
``start_cycle`` on, the switch of 000 Fig. 17), writes its memory file,
publishes the stats (and what the law identified) and then the correction
of period ``j + 1``. See docs/learning_protocol.md.

The ``state`` stream is taken raw: only the reference instants are
deserialised, validated whole and then passed through a
:class:`~servo_axis.wire.streams.StreamGate` of stride ``ratio`` (exactly
the next instant in lockstep, from step 0, or from the first one received
with ``late_join``); the samples between them are skipped once their stamp
is read, and never move the gate. A message stamped ahead, or one that is
not valid, changes nothing.

Run: ``python -m servo_axis.nodes.learning --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import numpy as np

from servo_axis.core.drive import torque_from_current
from servo_axis.core.errors import ParameterFileError, ServoAxisError, SignalError
from servo_axis.core.feedback.output import controlled_output
from servo_axis.core.learning.base import IdentifyingLaw
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import PeriodCollector, stream_gate
from servo_axis.nodes.runtime import LATE_JOIN_QOS, STREAM_QOS, run_main
from servo_axis.params.factories import (
    build_learning_law,
    build_reference,
    grid,
    learning_law,
    run_steps,
)
from servo_axis.params.values import LearningValues
from servo_axis.storage import load_memory, save_memory
from servo_axis.wire import messages as msgs


class LearningNode(ServoNode):
    """Learning unit; see the module docstring."""

    # Realtime: the default scheduler. Only the per-sample pair's executor
    # threads and the plant's clock run under SCHED_FIFO: a node of the
    # reference path at FIFO (as before, one or two below the pair) starved
    # the pair's middleware threads, which stay SCHED_OTHER (issue 30).
    realtime_below = None

    values: LearningValues

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("learning", **kwargs)
        values = self.values
        self._grid = grid(values)
        self.law = build_learning_law(values)
        self._kt = values.nominal.torque_constant_Nm_per_A
        law_outputs = learning_law(values.law).outputs
        self._side = self.law.side
        # A target-side law learns from the reference instants, an input-side
        # (trial) law from every control sample.
        self._stride = self._grid.ratio if self._side == "target" else 1
        nd = self.law.samples_per_period
        # In lockstep the plant can run up to one whole period ahead of this
        # node (the feedforward generator holds the next period until its
        # correction is out); the state stream's history must hold that much.
        if nd * self._stride > STREAM_QOS.depth - 10:
            tu = values.control_period_s
            raise ParameterFileError(
                f"parameter 'cycle_s': at most {(STREAM_QOS.depth - 10) * tu!r} s "
                f"({STREAM_QOS.depth - 10} control samples) per learning period, got {values.cycle_s!r}"
            )
        self.reference = build_reference(values)
        self._nd = nd
        self._lead = values.lead_m_per_rad
        self._axis = values.axis
        self._period_ns = msgs.period_ns(values.control_period_s)
        self._state_codec = msgs.joint_codec("state", axis=values.axis, period_ns_=self._period_ns)
        self._scenario = values.scenario.name or "unnamed"
        self._steps = run_steps(values)
        self._memory = Path(values.memory.file) if values.memory.file else None
        self._resume_memory()

        self._correction_topic = (
            "learning/correction" if self._side == "target" else "learning/input_correction"
        )
        # Sent as CDR bytes, as the per-sample streams: the bytes are the
        # codec's, padding included (a message object's padding is what the
        # middleware's buffer held), so the bag is the same every run.
        self._correction_codec = msgs.joint_codec(
            self._correction_topic, axis=self._axis, period_ns_=self._period_ns
        )
        outputs = self._make_publishers(law_outputs)
        self._gate = stream_gate(
            values.mode == "lockstep",
            first=None if values.late_join else 0,
            limit=self._steps,
            stride=self._stride,
            period_ns=self._period_ns,
        )
        self._error = PeriodCollector(nd)
        self._target = np.zeros(nd)
        self._target_cycle = -1
        # The plant starts only once this node subscribes to `state`; doing so
        # only after its own outputs are matched means that nothing it
        # publishes is lost to a reader still being discovered.
        self.state_subscribed = False
        self.graph.after_consumers_matched(outputs, self._subscribe_state)

    def _make_publishers(self, law_outputs: Any) -> list[tuple[Any, str, int]]:
        """The node's publishers, each with its topic and the consumers it waits for."""
        values = self.values
        self._correction_pub = self.publisher(self._correction_topic)
        self._stats_pub = self.publisher("learning/cycle_stats")
        stats = values.wait_for_stats_subscribers
        outputs = [
            (
                self._correction_pub,
                self._correction_topic,
                values.wait_for_correction_subscribers,
            ),
            (self._stats_pub, "learning/cycle_stats", stats),
        ]
        # What a projection-based law identified, recorded with the stats.
        self._parameters_pub = self._table_pub = None
        if "learning/parameters" in law_outputs:
            self._parameters_pub = self.publisher("learning/parameters")
            outputs.append((self._parameters_pub, "learning/parameters", stats))
        if "learning/friction_table" in law_outputs:
            self._table_pub = self.publisher("learning/friction_table")
            outputs.append((self._table_pub, "learning/friction_table", stats))
        return outputs

    def _subscribe_state(self) -> None:
        # raw: only the samples learned from are decoded; the gate sees only
        # those, once they are known valid.
        # A late joiner takes no history: it resumes from what comes next.
        qos = LATE_JOIN_QOS if self.values.late_join else None
        self.inputs.subscribe(
            "state", self._decode_state, self._on_state, raw=True, gate=self._gate, qos=qos
        )
        self.state_subscribed = True
        self.get_logger().info("outputs matched; subscribed to state")

    def _resume_memory(self) -> None:
        if self._memory is None or not self.values.memory.resume or not self._memory.exists():
            return
        try:
            state = load_memory(self._memory, self.law, scenario=self._scenario)
            self.law.load_state(state)
        except (OSError, ServoAxisError) as err:
            if self.values.memory.on_bad_file == "fail":
                raise ParameterFileError(f"parameter 'memory.file': {err}") from err
            self.get_logger().warning(f"memory file not used, starting clean: {err}")
            return
        self.get_logger().info(
            f"resumed {self.law.periods_learned} learned cycles from {self._memory}"
        )

    def _decode_state(self, data: bytes) -> msgs.StateSample | None:
        """The state of a sample learned from, validated whole; None for the samples between them.

        Nothing changes here: the base node passes the returned sample's step
        through the gate afterwards (a None leaves it alone).
        """
        step, rem = divmod(msgs.stamp_ns_from_cdr(data), self._period_ns)
        if rem or step < 0:
            raise SignalError(f"header.stamp: not on the control grid of {self._period_ns} ns")
        if step % self._stride:
            return None  # a target-side law learns from the reference instants only
        self._gate.check(step)  # cheap refusal of stale or far stamps before deserialising
        return self._state_codec.decode(data)

    def _on_state(self, state: msgs.StateSample | None) -> None:
        self.realtime.start()
        if state is None:
            return
        cycle, idx = divmod(state.step // self._stride, self._nd)
        if cycle != self._target_cycle:
            # The original target of a whole period in one call.
            t = (
                (cycle * self._nd + np.arange(self._nd))
                * self._stride
                * self._grid.control_period_s
            )
            self._target = self.reference.sample(t)[0] / self._lead
            self._target_cycle = cycle
        y = controlled_output(
            self.values.sensor,
            encoder_rad=state.encoder_rad,
            scale_m=state.scale_m,
            lead_m_per_rad=self._lead,
        )
        self._error.put(idx, self._target[idx] - y)
        # The run's last period ends with the run: nothing after it would be
        # used, and a message published as the run stops may or may not make
        # it into the bag (which must be the same every run).
        if idx == self._nd - 1 and (cycle + 1) * self._nd * self._stride < self._steps:
            self._end_of_cycle(cycle)

    def _end_of_cycle(self, cycle: int) -> None:
        complete = self._error.complete
        received = self._error.received
        error = self._error.restart()
        # The error is in rad at the motor; a trial law learns in m at the table.
        scale = 1.0 if self._side == "target" else self._lead
        # Period ``cycle`` (0-based) ends; its correction is for 1-based period
        # ``cycle + 2``; learning is on from ``start_cycle`` (1-based, >= 2).
        if cycle + 2 >= self.values.start_cycle:
            if complete:
                try:
                    self.law.learn(scale * error, period=cycle + 1)
                except ServoAxisError as err:
                    # The law refuses this period's data (a singular projection,
                    # say): the axis goes on with the correction it has.
                    self.get_logger().error(f"{self.law.period} {cycle + 1} not learned: {err}")
            else:
                # Started or restarted mid-period, or states were rejected: a
                # partial error would teach a wrong correction.
                self.get_logger().warning(
                    f"{self.law.period} {cycle + 1} not learned: {received} of {self._nd} "
                    "samples received"
                )
        # Persist before publishing: whatever a listener has seen of this
        # period (correction, stats) is already on disk if the unit dies now.
        if self._memory is not None:
            save_memory(self._memory, self.law, scenario=self._scenario)
        # The stats (and what the law identified) go out before the correction:
        # the run cannot end before the correction has been used, so they are
        # in the bag by then (they are not counted streams; published after
        # it, a descheduled unit let the run end without the last stats,
        # 1 run in 20 under CPU load).
        err_m = self._lead * error[np.isfinite(error)]
        rms = float(np.sqrt(np.mean(err_m**2))) if err_m.size else 0.0
        peak = float(np.max(np.abs(err_m))) if err_m.size else 0.0
        self._stats_pub.publish(
            msgs.labelled_array(msgs.STATS_LABELS, [cycle + 1, rms, peak, self.law.periods_learned])
        )
        if self._parameters_pub is not None:
            p = cast(IdentifyingLaw, self.law).physical_parameters()
            self._parameters_pub.publish(
                msgs.labelled_array(
                    msgs.PARAMETER_LABELS,
                    [cycle + 1, *(p[k] for k in msgs.PARAMETER_LABELS[1:])],
                )
            )
        if self._table_pub is not None:
            x_r, torque = cast(IdentifyingLaw, self.law).friction_table()
            self._table_pub.publish(msgs.friction_table_to_msg(cycle + 1, x_r, torque))
        self._publish_correction(cycle + 1)

    def _publish_correction(self, cycle: int) -> None:
        """The correction for 0-based period ``cycle`` (1-based ``cycle + 1``), sample by sample."""
        first = cycle * self._nd
        if self._side == "target":
            position, velocity = self.law.next_correction(period=cycle + 1)
            for idx in range(self._nd):
                self._correction_pub.publish(
                    self._correction_codec.encode(
                        msgs.CorrectionSample(
                            self._grid.step_of(first + idx),
                            float(position[idx]),
                            float(velocity[idx]),
                        )
                    )
                )
            return
        (current,) = self.law.next_correction(period=cycle + 1)
        kt = self._kt
        for idx in range(self._nd):
            torque = torque_from_current(float(current[idx]), torque_constant_Nm_per_A=kt)
            self._correction_pub.publish(
                self._correction_codec.encode(msgs.InputCorrectionSample(first + idx, torque))
            )


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.learning``."""
    return run_main("learning", [LearningNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
