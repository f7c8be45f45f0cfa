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
  the command of the same sample.

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
not answered (:class:`~servo_axis.nodes.realtime.CatchUp`), so that the node
catches up with the clock instead of answering a backlog; it still answers
at least every :data:`ANSWER_GAP` steps, and always the last state of the
run. The skipped ones are counted (``skipped_answers`` on
``/diagnostics``); in the plant's report they are commands missing.

Run: ``python -m servo_axis.nodes.feedback --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import time
from typing import Any

from servo_axis.core.drive import current_from_torque, torque_from_current
from servo_axis.core.errors import SignalError
from servo_axis.core.feedback.loop import Fault, LoopOutput
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import REALTIME_WINDOW, PeerWatch, SampleBuffer, stream_gate
from servo_axis.nodes.realtime import CatchUp
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.factories import build_deformation, build_loop, run_steps
from servo_axis.wire import messages as msgs
from servo_axis.wire.streams import StreamGate

#: Realtime: the most steps between two answered states (half the realtime
#: window, so the readers of ``command`` take every jump).
ANSWER_GAP = REALTIME_WINDOW // 2


class FeedbackNode(ServoNode):
    """Feedback loop; see the module docstring for its protocol."""

    realtime_below = 0  # the per-sample pair

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("feedback", **kwargs)
        values = self.values
        self.loop = build_loop(values)
        self._v = values
        self._axis = values["axis"]
        self._period_ns = msgs.period_ns(values["control_period_s"])
        self._lockstep = values["mode"] == "lockstep"
        self._kt = values["nominal.torque_constant_Nm_per_A"]

        # The per-sample path sends and takes CDR bytes (plant.py says why).
        self._command_codec = msgs.joint_codec(
            "command", axis=self._axis, period_ns_=self._period_ns
        )
        self._command_pub = self.publisher("command")
        self._fault_pub = self.publisher("fault")
        self._deformation = build_deformation(values)
        if self._deformation is not None:
            self._deformation_codec = msgs.array_codec("deformation")
            self._deformation_pub = self.publisher("deformation")

        self._references: SampleBuffer[msgs.ReferenceSample] = SampleBuffer()
        self._states = stream_gate(self._lockstep, first=0, period_ns=self._period_ns)
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
        self.catch_up = (
            None
            if self._lockstep
            else CatchUp(period_ns=self._period_ns, last_step=run_steps(values) - 1, gap=ANSWER_GAP)
        )
        self.inputs_subscribed = False
        # The plant starts only once this node subscribes to `state`; doing so
        # only after `command` is matched with its consumers means that no
        # command is lost to a reader still being discovered.
        self.graph.after_consumers_matched(
            [(self._command_pub, "command", values["wait_for_command_subscribers"])],
            self._subscribe_inputs,
        )
        self.create_timer(values["input_timeout_s"] / 10.0, self._watchdog, clock=steady_clock())

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
            msgs.joint_codec("state", axis=self._axis, period_ns_=self._period_ns).decode,
            self._on_state,
            raw=True,
            gate=self._states,
        )
        self.inputs_subscribed = True

    def _within_preview(self, ref: msgs.ReferenceSample) -> msgs.ReferenceSample:
        last_state = self._states.last if self._states.last is not None else 0
        # Realtime: the plant's clock may be ahead of the states taken (a
        # backlog after a stall); the preview counts from where it is.
        now_step = self._states.now_step()
        if now_step is not None:
            last_state = max(last_state, now_step)
        if ref.step > max(last_state, 0) + self._v["max_preview_steps"]:
            raise SignalError(f"step {ref.step} is too far in the future")
        return ref

    def _on_state(self, state: msgs.StateSample) -> None:
        self.realtime.start()
        if self.catch_up is not None:
            self.catch_up.arrived(state.step, time.monotonic_ns())
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
        self._command_pub.publish(
            self._command_codec.encode(
                msgs.CommandSample(
                    step=state.step,
                    torque_Nm=torque_from_current(out.current_A, torque_constant_Nm_per_A=self._kt),
                )
            )
        )
        if self._deformation is not None:
            sample = msgs.DeformationSample(
                state.step,
                d.d_r_m_per_rad,
                d.scale_increment_m,
                d.encoder_increment_rad,
                d.valid,
            )
            self._deformation_pub.publish(self._deformation_codec.encode(sample))

    def realtime_counts(self) -> dict[str, int]:
        return {
            "references_held": self.missed_references,
            "states_skipped": self._states.skipped,
            "answers_skipped": 0 if self.catch_up is None else self.catch_up.skipped,
        }

    def _watchdog(self) -> None:
        now = time.monotonic()
        self._feedforward.look(self.inputs.peer_alive("reference"), now)
        if self._pending is None or self.loop.tripped:
            return
        timeout = self._v["input_timeout_s"]
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
