"""Plant simulator node: the physical axis and, in lockstep, the simulation clock.

Topics (relative to the node's namespace):

* publishes ``state`` (JointState, every sample), ``/clock`` (every
  ``clock_every_steps`` samples: nodes use the clock for logs and timers,
  never for per-sample logic, so 100 Hz suffices and saves every node a
  callback per sample), ``plant/status`` (Float64MultiArray ``[step,
  deadline_misses, rejected_commands, command_timeouts]``, every
  ``status_every_steps``: the feedforward generator's progress signal);
* subscribes ``command`` (JointState: the motor torque reference, N m, which
  the plant, as a drive does, turns into its current reference with its own
  ``torque_constant_Nm_per_A``, :mod:`servo_axis.core.drive`, and saturates
  on ``current_limit_A``) and ``recorder/progress``
  (Float64MultiArray, for flow control).

The model is chosen by ``model`` from the registry of
:mod:`servo_axis.params.factories` (``ball_screw``).

Lockstep: the plant publishes ``state[k]`` and waits for ``command[k]``,
then integrates one control period. Before publishing ``state[k]`` it waits
until the recorder has acknowledged step ``k - max_recorder_lag_steps``;
after the last step it waits until the recorder has everything, then stops.
It takes exactly ``command[k]`` of the step it waits for, once; an
acknowledgement on ``recorder/progress`` must be a whole number, not below
the last one and not beyond the states published (others are rejected and
counted under that topic). It waits for the feedback and the recorder as
long as they live (liveliness of ``command``, ``recorder/progress``): only
once the feedback has been gone for ``command_timeout_s`` does it apply
zero current (every step while it stays gone; a fallback, counted as
command timeouts), and only once the recorder has been gone that long does
it switch flow control off (a fallback).
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

from servo_axis.core.drive import current_from_torque
from servo_axis.core.errors import ParameterFileError, SignalError
from servo_axis.core.models.base import PlantOutput
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import FlowControl, PeerWatch
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.factories import build_plant, plant_model, run_steps
from servo_axis.wire import messages as msgs

#: Wall time the plant waits at the end for the recorder to acknowledge
#: everything, in realtime or after a fallback (in lockstep it waits while
#: the recorder lives, and says so every this many seconds).
FINISH_TIMEOUT_S = 10.0
#: Steps applied with zero current per watchdog look (every 50 ms) while
#: the feedback is gone: the executor stays free for the recorder and for a
#: feedback that comes back.
ZERO_STEPS_PER_LOOK = 100


def state_sample(out: PlantOutput) -> msgs.StateSample:
    """The wire sample of a plant output."""
    return msgs.StateSample(
        step=out.step,
        encoder_rad=out.encoder_rad,
        scale_m=out.scale_m,
        velocity_rad_s=out.velocity_rad_s,
        velocity_m_s=out.velocity_m_s,
        motor_torque_Nm=out.motor_torque_Nm,
        friction_force_N=out.friction_force_N,
    )


class PlantNode(ServoNode):
    """Plant simulator; see the module docstring for its protocol."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("plant", **kwargs)
        values = self.values
        if self.get_parameter("use_sim_time").value:
            raise ParameterFileError(
                "parameter 'use_sim_time': the plant owns the clock; set it false"
            )
        self.plant = build_plant(values)
        for warning in plant_model(values["model"]).warnings(values):
            self.get_logger().warning(f"parameter check: {warning}")
        self._axis = values["axis"]
        self._period_ns = msgs.period_ns(values["control_period_s"])
        self._steps = run_steps(values)
        self._lockstep = values["mode"] == "lockstep"
        self._kt = values["torque_constant_Nm_per_A"]
        self._v = values
        self._flow = FlowControl(
            enabled=values["flow_control"],
            max_lag_steps=values["max_recorder_lag_steps"],
            steps=self._steps,
        )

        # One message per publisher, refilled each sample: publish() serialises
        # at once, and building a fresh JointState costs more than the physics.
        self._state_msg = msgs.joint_state_template(
            msgs.state_names(self._axis), ("position", "velocity", "effort")
        )
        self._state_pub = self.publisher("state")
        self._clock_pub = self.publisher("/clock") if values["publish_clock"] else None
        self._status_pub = self.publisher("plant/status")

        self.done = False
        self.started = False
        self._awaiting: int | None = None  # step whose command we wait for
        self._command: float | None = None
        self._published = 0  # states 0 .. _published - 1 are out
        self._feedback = PeerWatch()
        self._recorder = PeerWatch()
        self._feedback_gone_step: int | None = None  # first step of a zero-current fallback
        self._last_current = 0.0
        self._held_step = -1  # step of the command whose current is held
        self._finishing = False
        self._deadline_misses = 0
        self._timeouts = 0
        self._finish_started = 0.0
        period_ns, axis = self._period_ns, self._axis
        self.subscribe(
            "command",
            lambda m: self._awaited_command(
                msgs.command_from_msg(m, axis=axis, period_ns_=period_ns)
            ),
            self._on_command,
        )
        self.subscribe(
            "recorder/progress",
            lambda m: self._plausible_progress(
                msgs.labelled_array_values(m, msgs.PROGRESS_LABELS)[0]
            ),
            self._on_progress,
        )

        self._start_timer = self.create_timer(0.01, self._try_start, clock=steady_clock())
        self._rt_timer: Any = None
        self.create_timer(0.05, self._watchdog, clock=steady_clock())

    # -- start ---------------------------------------------------------------
    def diagnostic_values(self) -> list[tuple[str, Any]]:
        return [
            ("mode", self._v["mode"]),
            ("started", self.started),
            ("done", self.done),
            ("step", self.plant.step_index),
            ("steps", self._steps),
            ("deadline_misses", self._deadline_misses),
            ("command_timeouts", self._timeouts),
        ]

    def diagnostic_stamp_ns(self) -> int:
        """The simulation time of the plant's step (it owns the clock)."""
        return int(self.plant.step_index) * self._period_ns

    def _connected(self) -> bool:
        v = self._v
        if not self.consumers_matched(self._state_pub, "state", v["wait_for_state_subscribers"]):
            return False
        if not self.consumers_matched(
            self._status_pub, "plant/status", v["wait_for_status_subscribers"]
        ):
            return False
        if self._clock_pub is not None and not self.consumers_matched(
            self._clock_pub, "/clock", v["wait_for_clock_subscribers"]
        ):
            return False
        if self._lockstep and not self.input_matched("command"):
            # Whoever answers state[k] must be there before step 0: a stranger
            # subscribed to state must not stand in for an outside feedback
            # node that would miss what was sent before it matched.
            return False
        return self._flow.ready

    def _try_start(self) -> None:
        if self.started or not self._connected():
            return
        self._start_timer.cancel()
        self.started = True
        self.get_logger().info(f"connected; running {self._steps} steps ({self._v['mode']})")
        self._publish(self.plant.output())
        if self._lockstep:
            self._awaiting = 0
        else:
            self._rt_timer = self.create_timer(
                self._v["control_period_s"], self._realtime_tick, clock=steady_clock()
            )

    # -- input checks (nothing changes before a message is known good) ----------
    def _awaited_command(self, cmd: msgs.CommandSample) -> msgs.CommandSample:
        """Lockstep: the command of the step the plant waits for, once; realtime: a
        command not older than the held one and not ahead of the plant."""
        expected = self.plant.step_index
        if self._lockstep:
            if self._awaiting is None:
                raise SignalError(f"not waiting for a command (step {cmd.step})")
            if cmd.step < expected:
                raise SignalError(f"stale stamp (step {cmd.step}, expected {expected})")
            if cmd.step > expected:
                raise SignalError(
                    f"stamp ahead of the stream (step {cmd.step}, expected {expected})"
                )
            if self._command is not None:
                raise SignalError(f"a second command for step {cmd.step}")
        elif not self._held_step < cmd.step <= expected:
            when = "stale" if cmd.step <= self._held_step else "future"
            raise SignalError(f"{when} stamp (step {cmd.step}, expected {expected})")
        elif cmd.step == expected and self._command is not None:
            raise SignalError(f"a second command for step {cmd.step}")
        return cmd

    def _plausible_progress(self, value: float) -> int:
        """A recorder acknowledgement: a whole number of steps, not below the last
        one, not beyond the states published."""
        if value != int(value):
            raise SignalError(f"steps_recorded: expected a whole number, got {value!r}")
        recorded = int(value)
        if recorded < self._flow.recorded:
            raise SignalError(f"steps_recorded {recorded} below the last one {self._flow.recorded}")
        if recorded > self._published:
            raise SignalError(
                f"steps_recorded {recorded} beyond the {self._published} states published"
            )
        return recorded

    # -- callbacks -------------------------------------------------------------
    def _on_command(self, cmd: msgs.CommandSample) -> None:
        current = current_from_torque(cmd.torque_Nm, torque_constant_Nm_per_A=self._kt)
        if not self._lockstep and cmd.step < self.plant.step_index:
            # Late, but newer than the held current: it replaces it.
            self._last_current, self._held_step = current, cmd.step
            return
        self._command = current
        if self._lockstep:
            self._advance()

    def _on_progress(self, recorded: int) -> None:
        self._flow.acknowledge(recorded)
        if self.started:
            self._advance()

    def _watchdog(self) -> None:
        now = time.monotonic()
        grace = self._v["command_timeout_s"]
        self._feedback.look(self.peer_alive("command"), now)
        self._recorder.look(self.peer_alive("recorder/progress"), now)
        if self.done:
            return
        recorder_gone = self._recorder.gone_for(now)
        if self._lockstep and self._waits_for_recorder() and recorder_gone > grace:
            # A gone recorder gets command_timeout_s to come back; while it
            # lives the plant waits for it however long it takes.
            self._flow.enabled = False
            self.fallback(
                "recorder_gone",
                self.plant.step_index,
                f"the recorder (recorder/progress) has been gone for {recorder_gone:.3g} s at "
                f"{self._flow.recorded} steps acknowledged: flow control off",
            )
            self._advance()
            return
        if self._finishing:
            if self._lockstep and not self.health.fallbacks:
                if now - self._finish_started > FINISH_TIMEOUT_S:
                    self.get_logger().warning(
                        f"waiting for the recorder: {self._flow.recorded} of {self._steps} steps "
                        "acknowledged (it lives)"
                    )
                    self._finish_started = now
                return
            # Realtime, or a run that already went on by a fallback (whose
            # commands the recorder may never get): stop after FINISH_TIMEOUT_S.
            if now - self._finish_started > FINISH_TIMEOUT_S:
                self.get_logger().error(
                    f"recorder acknowledged {self._flow.recorded} of {self._steps} steps within "
                    f"{FINISH_TIMEOUT_S} s; stopping anyway"
                )
                self.done = True
            return
        if not self._lockstep or self._awaiting is None or self._command is not None:
            return
        gone = self._feedback.gone_for(now)
        if gone <= grace:
            # While the feedback lives, wait for its command however long it takes.
            self._feedback_gone_step = None
            return
        step = self._awaiting
        if self._feedback_gone_step is None:
            self._feedback_gone_step = step
            self.fallback(
                "command_timeout",
                step,
                f"the feedback (command) has been gone for {gone:.3g} s: zero current from "
                "this step while it stays gone",
            )
        for _ in range(ZERO_STEPS_PER_LOOK):
            # The steps the gone feedback leaves unanswered, a batch per look.
            if self._awaiting is None or self._command is not None or self._finishing:
                break
            self._timeouts += 1
            self._command = 0.0
            before = self.plant.step_index
            self._advance()
            if self.plant.step_index == before:
                break  # held back by flow control; the next look goes on

    def _waits_for_recorder(self) -> bool:
        """Flow control holds the plant (a step waiting for an acknowledgement, or the end)."""
        if not self._flow.enabled or not self.started:
            return False
        if self._finishing:
            return not self._flow.complete
        return self._command is not None and not self._flow.may_step_to(self.plant.step_index + 1)

    # -- stepping --------------------------------------------------------------
    def _advance(self) -> None:
        """Lockstep: integrate once the command is here and the recorder keeps up."""
        if self._finishing:
            if self._flow.complete:
                self.done = True
            return
        if self._command is None or self._awaiting is None:
            return
        if not self._flow.may_step_to(self.plant.step_index + 1):
            return  # the progress callback resumes us
        current, self._command = self._command, None
        out = self.plant.step(current)
        if out.step >= self._steps:
            self._awaiting = None
            self._finish()
            return
        self._awaiting = out.step
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
        self._published = out.step + 1
        if self._clock_pub is not None and out.step % self._v["clock_every_steps"] == 0:
            self._clock_pub.publish(msgs.clock_message(out.step, self._period_ns))
        self._state_pub.publish(
            msgs.write_state(self._state_msg, state_sample(out), period_ns_=self._period_ns)
        )
        if out.step % self._v["status_every_steps"] == 0:
            self._publish_status()

    def _publish_status(self) -> None:
        self._status_pub.publish(
            msgs.labelled_array(
                msgs.STATUS_LABELS,
                [
                    self.plant.step_index,
                    self._deadline_misses,
                    self.health.rejected.get("command", 0),
                    self._timeouts,
                ],
            )
        )


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.plant``."""
    return run_main("plant", [PlantNode], args, done=lambda nodes: all(n.done for n in nodes))


if __name__ == "__main__":
    raise SystemExit(main())
