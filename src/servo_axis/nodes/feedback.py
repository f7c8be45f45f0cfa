"""Feedback loop node: PID + DOB, sums feedforward and feedback, trips on faults.

Topics (relative to the namespace):

* subscribes ``state`` (JointState, every sample) and ``reference``
  (JointState, published ahead by the feedforward generator);
* publishes ``command`` (JointState, every sample: the motor torque
  reference ``K_T,n i_ref``, N m), ``fault`` (Float64MultiArray ``[step,
  code, value]``, latched, once on a trip) and, with ``deformation.enabled``,
  ``deformation`` (Float64MultiArray ``[step, d_r_m_per_rad,
  scale_increment_m, encoder_increment_rad, valid]``, every sample: the
  deformation ratio ``d_r`` of paper 004 eqs. (5)-(7) from the scale and
  the encoder, :mod:`servo_axis.core.deformation`), published just before
  the command of the same sample; with ``forward_commands_topic`` each
  command also as ros2_control's forward command controllers take it
  (``std_msgs/Float64MultiArray``, ``data = [torque]``, no stamp), just
  after it.

The loop computes in currents (A); the wire carries torques: the
feedforward torque of ``reference`` becomes a current and the loop's current
reference a torque with the nominal torque constant
``nominal.torque_constant_Nm_per_A`` (:mod:`servo_axis.core.drive`).

For ``state[k]`` the node answers ``command[k]`` as soon as
``reference[k]`` is here. The controlled output is
:func:`servo_axis.core.feedback.output.controlled_output` of the ``sensor``
parameter.

Streams: ``state`` is taken exactly in order in lockstep (the next step
only; realtime: at most :data:`~servo_axis.nodes.lockstep.REALTIME_WINDOW`
steps ahead, or further when the wall clock makes it plausible: a feedback
that fell behind takes the newest state and goes on), ``reference`` exactly
in order (the generator publishes it so; realtime: a jump is taken) and at
most ``max_preview_steps`` ahead of the last state (realtime: of where the
plant's clock is, as the states' arrivals show it): a message stamped ahead
of that is refused and never displaces the stream.

Handshake: with ``wait_for_command_subscribers``, the node subscribes to
``reference`` only once its ``command`` publisher is matched with the plant
and the recorder (:meth:`~servo_axis.nodes.graph.GraphWatch.consumers_matched`),
so that no command is published unheard, and to ``state`` (which the plant
waits for before step 0) only once ``reference`` has a matched publisher,
so that no reference is sent unheard by a volatile generator.

Fallback: in lockstep the node waits for ``reference[k]`` as long as the
generator lives (liveliness of ``reference``); once it has been gone for
``input_timeout_s`` while a state waits, the loop trips (fault
``input_timeout``, zero current from then on, recorded as a fallback) and
every later state is answered with zero current, so the plant runs to the
end. A generator that dies makes the loop trip within
``LIVELINESS_LEASE_S + input_timeout_s + input_timeout_s / 10`` (the lease
after which it is seen gone, the grace, the watchdog period) of its death
or of the first state it leaves unanswered, whichever is later. In realtime
the wall-clock rule stays: ``input_timeout_s`` after a state came without
its reference.

Catching up (realtime): every state goes through the loop, in order, but a
state whose command could no longer reach the plant in time to be used is
not answered (:class:`~servo_axis.realtime.late.CatchUp`), so that the node
catches up with the clock instead of answering a backlog; it still answers
at least every :data:`ANSWER_GAP` steps, and always the last state of the
run. The skipped ones are counted (``skipped_answers`` on
``/diagnostics``); in the plant's report they are commands missing.

Run: ``python -m servo_axis.nodes.feedback --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

from rclpy.qos import QoSProfile
from std_msgs.msg import Float64MultiArray

from servo_axis.core.drive import current_from_torque, torque_from_current
from servo_axis.core.errors import SignalError
from servo_axis.core.feedback.loop import Fault, LoopOutput
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import (
    REALTIME_WINDOW,
    FlowControl,
    PeerWatch,
    SampleBuffer,
    stream_gate,
)
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.factories import build_deformation, build_loop, run_steps
from servo_axis.params.values import FeedbackValues
from servo_axis.realtime.clock import LoopTimes
from servo_axis.realtime.late import CatchUp
from servo_axis.wire import messages as msgs
from servo_axis.wire.streams import StampOrigin, StreamGate

#: Realtime: the most steps between two answered states (half the realtime
#: window, so the readers of ``command`` take every jump).
ANSWER_GAP = REALTIME_WINDOW // 2


#: Seconds an outside plant's flow control waits for a recorder whose
#: liveliness lapsed before it lets the commands go: a stopped recorder
#: (SIGSTOP, a loaded machine) lapses its 1 s lease as a dead one does, and
#: a dead one is the runner's to handle (measured: a 2 s SIGSTOP lost 783
#: states of a keep-last 10 plant with the 0.5 s input timeout here).
RECORDER_TIMEOUT_S = 10.0


class FeedbackNode(ServoNode):
    """Feedback loop; see the module docstring for its protocol."""

    realtime_below = 0  # the per-sample pair
    values: FeedbackValues

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("feedback", **kwargs)
        values = self.values
        self.loop = build_loop(values)
        self._axis = values.axis
        self._period_ns = msgs.period_ns(values.control_period_s)
        self._lockstep = values.mode == "lockstep"
        self._kt = values.nominal.torque_constant_Nm_per_A

        # The per-sample path sends and takes CDR bytes (plant.py says why).
        self._command_codec = msgs.joint_codec(
            "command", axis=self._axis, period_ns_=self._period_ns
        )
        self._outside_plant = values.wait_for_state_readers > 0
        # An outside plant publishes state[0] once `command` has a publisher:
        # with one, the publisher comes last (_publish_command_once_read).
        self._command_pub = None if self._outside_plant else self.publisher("command")
        self._answering = not self._outside_plant
        self._fault_pub = self.publisher("fault")
        # ros2_control's forward command controllers subscribe with the
        # system default QoS: a reliable, volatile writer matches it either way.
        self._forward_pub = None
        if values.forward_commands_topic:
            self._forward_pub = self.create_publisher(
                Float64MultiArray, values.forward_commands_topic, QoSProfile(depth=10)
            )
            self._forward_msg = Float64MultiArray(data=[0.0])
        self._deformation = build_deformation(values)
        if self._deformation is not None:
            self._deformation_codec = msgs.array_codec("deformation")
            self._deformation_pub = self.publisher("deformation")

        self._references: SampleBuffer[msgs.ReferenceSample] = SampleBuffer()
        # A plant that owns its clock (issue 31): steps from its stamps, and
        # each command echoes its state's stamp.
        self._origin = (
            StampOrigin(self._period_ns)
            if values.state_stamps == "plant_clock" and not self._lockstep
            else None
        )
        self._stamps: dict[int, int] = {}  # step -> the plant's stamp, ns, until answered
        if self._origin is None:
            self._states = stream_gate(self._lockstep, first=0, period_ns=self._period_ns)
        else:
            self._command_codec = msgs.joint_codec("command", axis=self._axis, period_ns_=1)
            # Its timer may skip samples; junk ahead is the origin's to refuse.
            self._states = StreamGate(window=run_steps(values), first=0)
        # Exactly in order: the generator publishes it so. Realtime: a
        # feedback that fell behind lost references its reader could not hold
        # and takes the stream again where it is, within the preview of where
        # the plant's clock is (_within_preview).
        self._refs = (
            StreamGate(window=1, first=0)
            if self._lockstep
            else StreamGate(window=1, first=0, plausible=lambda step: True)
        )
        self._held: msgs.ReferenceSample | None = None
        self._pending: msgs.StateSample | None = None
        self._pending_since = 0.0
        self._feedforward = PeerWatch()
        self.missed_references = 0
        # A plant that owns its clock: every state is answered (its deadlines
        # are the plant's; a jittering timer's states would look late).
        self.catch_up = (
            None
            if self._lockstep or self._origin is not None
            else CatchUp(period_ns=self._period_ns, last_step=run_steps(values) - 1, gap=ANSWER_GAP)
        )
        # An outside plant reports no clock: the loop is measured here.
        self.loop_times = (
            LoopTimes(steps=run_steps(values), period_ns=self._period_ns)
            if self._outside_plant and not self._lockstep
            else None
        )
        self.inputs_subscribed = False
        self._flow = FlowControl(
            enabled=values.recorder_lag_steps > 0,
            max_lag_steps=max(1, values.recorder_lag_steps),
            steps=run_steps(values),
        )
        self._recorder = PeerWatch()
        if self._flow.enabled:
            self.inputs.subscribe(
                "recorder/progress",
                lambda m: self._plausible_progress(
                    msgs.labelled_array_values(m, msgs.PROGRESS_LABELS)[0]
                ),
                self._on_progress,
            )
        if self._command_pub is None:
            self._subscribe_inputs()
        else:
            # The plant starts only once this node subscribes to `state`; doing so
            # only after `command` is matched with its consumers means that no
            # command is lost to a reader still being discovered.
            self.graph.after_consumers_matched(
                [(self._command_pub, "command", values.wait_for_command_subscribers)],
                self._subscribe_inputs,
            )
        self.create_timer(values.input_timeout_s / 10.0, self._watchdog, clock=steady_clock())

    def diagnostic_values(self) -> list[tuple[str, Any]]:
        fault = self.loop.fault
        return [
            ("tripped", self.loop.tripped),
            ("fault", "none" if fault is None else fault.name.lower()),
            ("missed_references", self.missed_references),
            ("skipped_answers", 0 if self.catch_up is None else self.catch_up.skipped),
            ("states_skipped", self._states.skipped),
            ("scheduling", "fifo" if self.realtime.fifo else "other"),
        ]

    def diagnostic_error(self) -> str | None:
        fault = self.loop.fault
        return None if fault is None else f"tripped: {fault.name.lower()}, zero current"

    def _subscribe_inputs(self) -> None:
        reference = msgs.joint_codec("reference", axis=self._axis, period_ns_=self._period_ns)
        self.inputs.subscribe(
            "reference",
            lambda data: self._within_preview(reference.decode(data)),
            self._on_reference,
            raw=True,
            gate=self._refs,
        )
        # `state` (which starts the plant) only once `reference` is matched,
        # and a volatile generator's match has settled on its side too: one
        # with the default profile that answers state[k] with reference[k]
        # would otherwise send reference[0] to no one.
        self._reference_wait = self.create_timer(
            0.01, self._subscribe_state_once_referenced, clock=steady_clock()
        )

    def _subscribe_state_once_referenced(self) -> None:
        if not self.inputs.matched("reference"):
            return
        self._reference_wait.cancel()
        self.destroy_timer(self._reference_wait)
        self.inputs.subscribe(
            "state",
            self._state_decoder(),
            self._on_state,
            raw=True,
            gate=self._states,
        )
        self.inputs_subscribed = True
        if self._command_pub is None:
            self._readers_wait = self.create_timer(
                0.01, self._publish_command_once_read, clock=steady_clock()
            )

    def _state_decoder(self) -> Any:
        """The decoder of ``state``: on the grid, or by the plant's own clock."""
        origin = self._origin
        if origin is None:
            return msgs.joint_codec("state", axis=self._axis, period_ns_=self._period_ns).decode
        by_ns = msgs.joint_codec("state", axis=self._axis, period_ns_=1)

        def decode(data: Any) -> msgs.StateSample:
            sample = by_ns.decode(data)  # its step is its stamp, ns
            step = origin.state_step(sample.step, time.monotonic_ns())
            self._states.check(step)
            self._stamps[step] = sample.step
            return dataclasses.replace(sample, step=step)

        return decode

    def _publish_command_once_read(self) -> None:
        """An outside plant: make ``command`` once the run's readers of ``state`` are in.

        The plant publishes ``state[0]`` once ``command`` has a publisher, so
        every reader of ``state`` must be subscribed first (held
        :data:`~servo_axis.nodes.graph.MATCH_SETTLE_S`: the plant's volatile
        writer must have matched them on its side). The first answer waits
        until ``command`` has its own consumers matched too.
        """
        wanted = self.values.wait_for_state_readers
        if not (self.inputs.matched("state") and self.graph.readers_settled("state", wanted)):
            # Say what the wait is for (a user's plant waits for `command` meanwhile).
            self.get_logger().info(
                f"waiting for {wanted} readers of state before publishing command (the "
                f"outside plant's start sign): {len(self.graph.subscriptions('state'))} "
                "subscribed",
                throttle_duration_sec=5.0,
            )
            return
        self._readers_wait.cancel()
        self.destroy_timer(self._readers_wait)
        self._command_pub = self.publisher("command")
        if not self._lockstep:
            # Its clock runs from state[0]: a command lost to a reader still
            # matching is a miss, a wait for the match would be hundreds.
            self._start_answering()
            return
        self.graph.after_consumers_matched(
            [(self._command_pub, "command", self.values.wait_for_command_subscribers)],
            self._start_answering,
        )

    def _start_answering(self) -> None:
        self._answering = True
        self._try_answer()

    def _plausible_progress(self, value: float) -> int:
        """A recorder acknowledgement: a whole number of steps, not below the last one,
        not beyond the states taken."""
        if value != int(value):
            raise SignalError(f"steps_recorded: expected a whole number, got {value!r}")
        recorded = int(value)
        if recorded < self._flow.recorded:
            raise SignalError(f"steps_recorded {recorded} below the last one {self._flow.recorded}")
        taken = 0 if self._states.last is None else self._states.last + 1
        if recorded > taken:
            raise SignalError(f"steps_recorded {recorded} beyond the {taken} states taken")
        return recorded

    def _on_progress(self, recorded: int) -> None:
        self._flow.acknowledge(recorded)
        self._try_answer()

    def _within_preview(self, ref: msgs.ReferenceSample) -> msgs.ReferenceSample:
        last_state = self._states.last if self._states.last is not None else 0
        # Realtime: the plant's clock may be ahead of the states taken (a
        # backlog after a stall); the preview counts from where it is.
        now_step = self._states.now_step()
        if now_step is not None:
            last_state = max(last_state, now_step)
        if ref.step > max(last_state, 0) + self.values.max_preview_steps:
            raise SignalError(f"step {ref.step} is too far in the future")
        return ref

    def _on_state(self, state: msgs.StateSample) -> None:
        self.realtime.start()
        if self.catch_up is not None:
            self.catch_up.arrived(state.step, time.monotonic_ns())
        if self.loop_times is not None:
            self.loop_times.arrived(state.step, time.monotonic_ns())
        self._pending = state
        self._pending_since = time.monotonic()
        self._try_answer()

    def _on_reference(self, ref: msgs.ReferenceSample) -> None:
        self._references.put(ref.step, ref)
        self._try_answer()

    def _try_answer(self) -> None:
        state = self._pending
        if state is None or not self._answering:
            return
        # An outside plant answers command[k] with state[k + 1]: hold the
        # command until the recorder keeps up (issue 31; a no-op otherwise).
        if not self._flow.may_step_to(state.step + 1):
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
        # The command's stamp: its state's (a plant's own clock: by ns).
        stamp = state.step if self._origin is None else self._stamps.pop(state.step)
        if state.step % 1000 == 0:  # drop references of samples that never came
            self._references.drop_before(state.step)
            # And the stamps of states caught up past (CatchUp): never answered.
            for old in [s for s in self._stamps if s < state.step]:
                del self._stamps[old]
        if ref is None:
            out = LoopOutput(0.0, 0.0, 0.0, 0.0)
        else:
            out = self.loop.step(
                encoder_rad=state.encoder_rad,
                scale_m=state.scale_m,
                reference_rad=ref.position_rad,
                feedforward_A=current_from_torque(ref.torque_Nm, torque_constant_Nm_per_A=self._kt),
            )
        if out.fault is not None:
            self._publish_fault(state.step, out.fault, out.fault_value)
        if self._deformation is not None:
            d = self._deformation.update(state.encoder_rad, state.scale_m)
        if self.catch_up is not None and not self.catch_up.answer(state.step, time.monotonic_ns()):
            return
        # The command first: it is what the plant waits for.
        assert self._command_pub is not None  # answering
        torque = torque_from_current(out.current_A, torque_constant_Nm_per_A=self._kt)
        self._command_pub.publish(
            self._command_codec.encode(msgs.CommandSample(step=stamp, torque_Nm=torque))
        )
        if self.loop_times is not None:
            self.loop_times.sent(state.step, time.monotonic_ns())
        if self._forward_pub is not None:
            self._forward_msg.data[0] = torque
            self._forward_pub.publish(self._forward_msg)
        if self._deformation is not None:
            sample = msgs.DeformationSample(
                state.step,
                d.d_r_m_per_rad,
                d.scale_increment_m,
                d.encoder_increment_rad,
                d.valid,
            )
            self._deformation_pub.publish(self._deformation_codec.encode(sample))

    def realtime_counts(self) -> dict[str, Any]:
        loop = None if self.loop_times is None else self.loop_times.report()
        return {
            **(loop or {}),
            "references_held": self.missed_references,
            "states_skipped": self._states.skipped,
            "answers_skipped": 0 if self.catch_up is None else self.catch_up.skipped,
        }

    def _watchdog(self) -> None:
        now = time.monotonic()
        self._feedforward.look(self.inputs.peer_alive("reference"), now)
        if self._flow.enabled:
            self._watch_recorder(now)
        if self._pending is None or self.loop.tripped:
            return
        timeout = self.values.input_timeout_s
        if self._lockstep:
            # Wait as long as the generator lives; a gone one gets
            # input_timeout_s to come back, counted from when a state began
            # to wait (a generator that answers state[k] with reference[k]
            # is not there before the first state).
            waited = min(self._feedforward.gone_for(now), now - self._pending_since)
            detail = f"the feedforward generator (reference) has been gone for {waited:.3g} s"
        else:
            waited = now - self._pending_since
            detail = f"no reference within {waited:.3g} s of wall time"
        if waited > timeout:
            step = self._pending.step
            self.loop.trip(Fault.INPUT_TIMEOUT)
            self._publish_fault(step, Fault.INPUT_TIMEOUT, waited)
            self.report.fallback(
                "input_timeout", step, f"{detail}: tripped, zero current from here"
            )
            self._try_answer()

    def _watch_recorder(self, now: float) -> None:
        """Flow control off (a fallback) once the recorder has been gone for :data:`RECORDER_TIMEOUT_S`."""
        self._recorder.look(self.inputs.peer_alive("recorder/progress"), now)
        gone = self._recorder.gone_for(now)
        if self._flow.recorded < 0 or gone <= RECORDER_TIMEOUT_S:
            return
        self._flow.enabled = False
        self.report.fallback(
            "recorder_gone",
            self._flow.recorded,
            f"the recorder (recorder/progress) has been gone for {gone:.3g} s: "
            "commands no longer wait for it",
        )
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
