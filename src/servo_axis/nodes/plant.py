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
Realtime: the plant publishes state 0 and, once its command is in (the loop
has closed once, every node has its inputs: a clock started earlier counts
misses of a loop still starting up), a thread of the plant's own
(:class:`~servo_axis.realtime.clock.ClockThread`) steps at absolute
deadlines ``d_j = start + j T_u`` of the monotonic clock (``start``: the
arrival of command 0). A command that has not arrived by its tick's
deadline is a deadline miss and the newest current received is held, as a
drive holds its last set-point (:class:`~servo_axis.realtime.late.HeldSetPoint`):
a command that arrives after its deadline is not applied for its own step
but replaces the held value (it is newer than what is held), and the miss
was counted at the tick. A tick that wakes more than a period late runs at
once with those that are due (:mod:`servo_axis.realtime.deadlines`). The
command arrives in the executor's thread: the state both threads touch is
guarded by a lock. The plant's report (``realtime``) holds the ticks, the
misses and the lateness of ticks and commands (p50, p99, max;
:class:`~servo_axis.realtime.clock.ClockRecord`).
With ``command_source: drive_setpoint`` (realtime only) the plant is a
drive behind ros2_control's topic-based hardware interface: a command is a
set-point of no step, the newest one whatever its stamp
(:func:`~servo_axis.wire.setpoint.setpoint_torque`), held until the next;
NaN (no command yet) is counted and never applied; the clock starts with
the first finite one; misses are judged against the commander's own period
(:class:`~servo_axis.realtime.late.DriveSetPoint`).

Run: ``python -m servo_axis.nodes.plant --ros-args --params-file config/<scenario>.yaml``
"""

from __future__ import annotations

import copy
import math
import threading
import time
from typing import Any

from servo_axis.core.drive import current_from_torque
from servo_axis.core.errors import ParameterFileError, SignalError
from servo_axis.core.models.base import Plant, PlantOutput
from servo_axis.nodes.base import ServoNode
from servo_axis.nodes.lockstep import FlowControl, PeerWatch
from servo_axis.nodes.reporting import Throttle
from servo_axis.nodes.runtime import run_main, steady_clock
from servo_axis.params.factories import build_plant, drive_constant, plant_model, run_steps
from servo_axis.params.values import PlantValues
from servo_axis.realtime.clock import ClockRecord, ClockThread
from servo_axis.realtime.late import DriveSetPoint, HeldSetPoint
from servo_axis.realtime.scheduling import thread_policies
from servo_axis.wire import messages as msgs
from servo_axis.wire.cdr import decode_joint_state
from servo_axis.wire.setpoint import setpoint_torque

#: Wall time the plant waits at the end for the recorder to acknowledge
#: everything, in realtime or after a fallback (in lockstep it waits while
#: the recorder lives, and says so every this many seconds).
FINISH_TIMEOUT_S = 10.0
#: Steps applied with zero current per watchdog look (every 50 ms) while
#: the feedback is gone: the executor stays free for the recorder and for a
#: feedback that comes back.
ZERO_STEPS_PER_LOOK = 100
#: Realtime: wall time without a tick of the clock after which the run ends
#: with the fault ``clock_stalled``, s (a clock stopped longer than a few
#: hundred ms slips and goes on: :data:`~servo_axis.realtime.clock.SLIP_PERIODS`).
CLOCK_STALL_S = 2.0
#: Realtime: wall time without any command after which the run ends with
#: the fault ``loop_open``, s: far beyond a 0.3 s stall of the feedback,
#: after which the loop closes again.
LOOP_OPEN_S = 2.0
#: Wall time the plant waits at the end of a realtime run it ended itself
#: (``clock_stalled``, ``loop_open``) for the recorder, s.
FAULT_FINISH_S = 1.0
#: Wall time before step 0 after which the plant says, every as many seconds,
#: what it still waits for, s (the runner gives up after its stall timeout).
START_REPORT_S = 10.0


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


def warm_up(plant: Plant) -> None:
    """Load (or compile) the model's compiled kernels, on a copy of ``plant``.

    They load on their first call: now, while the nodes discover each other,
    not in the first step (0.2-0.5 s: a realtime clock's first tick, or a
    lockstep run's wall time, which counts from state 0).
    """
    spare = copy.deepcopy(plant)
    for _ in range(3):
        spare.step(0.0)


class PlantNode(ServoNode):
    """Plant simulator; see the module docstring for its protocol."""

    realtime_below = 0  # the per-sample pair
    values: PlantValues

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("plant", **kwargs)
        values = self.values
        if self.get_parameter("use_sim_time").value:
            raise ParameterFileError(
                "parameter 'use_sim_time': the plant owns the clock; set it false"
            )
        self.plant = build_plant(values)
        warm_up(self.plant)
        for warning in plant_model(values.model).warnings(values):
            self.get_logger().warning(f"parameter check: {warning}")
        self._axis = values.axis
        self._period_ns = msgs.period_ns(values.control_period_s)
        self._steps = run_steps(values)
        self._lockstep = values.mode == "lockstep"
        self._kt = drive_constant(values)
        self._flow = FlowControl(
            enabled=values.flow_control,
            max_lag_steps=values.max_recorder_lag_steps,
            steps=self._steps,
        )

        # The per-sample path sends and takes CDR bytes: a JointState object
        # costs more to fill, convert and serialise than the physics' step.
        self._state_codec = msgs.joint_codec("state", axis=self._axis, period_ns_=self._period_ns)
        command_codec = msgs.joint_codec("command", axis=self._axis, period_ns_=self._period_ns)
        self._state_pub = self.publisher("state")
        self._clock_pub = self.publisher("/clock") if values.publish_clock else None
        self._status_pub = self.publisher("plant/status")

        self.done = False
        self.started = False
        self._awaiting: int | None = None  # lockstep: step whose command we wait for
        self._command: float | None = None  # lockstep: its current, once in
        self._published = 0  # states 0 .. _published - 1 are out
        self._feedback = PeerWatch()
        self._recorder = PeerWatch()
        self._feedback_gone_step: int | None = None  # first step of a zero-current fallback
        self._finishing = False
        self._timeouts = 0
        self._finish_started = 0.0
        self._first_step_s = 0.0  # time.monotonic() when state 0 went out
        self._last_command_ns = 0  # realtime: monotonic ns of the newest command's arrival
        self._finish_timeout_s = FINISH_TIMEOUT_S
        # A drive's set-point (ros2_control's topic-based hardware), or the
        # command of a stamped step (the suite's feedback).
        self._drive: DriveSetPoint | None = None
        if values.command_source == "drive_setpoint":
            self._drive = DriveSetPoint(
                period_ns=msgs.period_ns(values.setpoint_period_s or values.control_period_s),
                threshold_Nm=values.setpoint_threshold_Nm,
            )
            motor = f"{self._axis}_motor"
            self.inputs.subscribe(
                "command",
                lambda data: setpoint_torque(decode_joint_state(data), motor=motor),
                self._on_setpoint,
                raw=True,
            )
        else:
            self.inputs.subscribe(
                "command",
                lambda data: self._awaited_command(command_codec.decode(data)),
                self._on_command,
                raw=True,
            )
        self.inputs.subscribe(
            "recorder/progress",
            lambda m: self._plausible_progress(
                msgs.labelled_array_values(m, msgs.PROGRESS_LABELS)[0]
            ),
            self._on_progress,
        )

        self._created_s = time.monotonic()
        self._start_complaint = Throttle(START_REPORT_S)
        self._start_timer = self.create_timer(0.01, self._try_start, clock=steady_clock())
        # Realtime: the clock thread, what it records, the set-point it applies,
        # and the lock on what it shares with the executor's thread.
        self._lock = threading.Lock()
        self.clock_record = ClockRecord(steps=self._steps, period_ns=self._period_ns)
        self._setpoint = HeldSetPoint()
        self._clock_thread = ClockThread(
            period_ns=self._period_ns, tick=self._realtime_tick, name="plant-clock"
        )
        self.create_timer(0.05, self._watchdog, clock=steady_clock())

    # -- start ---------------------------------------------------------------
    def diagnostic_values(self) -> list[tuple[str, Any]]:
        return [
            ("mode", self.values.mode),
            ("started", self.started),
            ("done", self.done),
            ("step", self.plant.step_index),
            ("steps", self._steps),
            ("deadline_misses", self.clock_record.misses),
            ("command_timeouts", self._timeouts),
        ]

    def diagnostic_stamp_ns(self) -> int:
        """The simulation time of the plant's step (it owns the clock)."""
        return int(self.plant.step_index) * self._period_ns

    def _waiting_for(self) -> str | None:
        """What the plant still waits for before step 0, or None once every peer is in."""
        v, graph = self.values, self.graph
        for pub, topic, count in (
            (self._state_pub, "state", v.wait_for_state_subscribers),
            (self._status_pub, "plant/status", v.wait_for_status_subscribers),
            (self._clock_pub, "/clock", v.wait_for_clock_subscribers),
        ):
            missing = None if pub is None else graph.consumers_missing(pub, topic, count)
            if missing is not None:
                return missing
        if not self.inputs.matched("command"):
            return "a matched publisher of command"
        if not graph.answerer_listens("command", "state"):
            # Whoever answers state[k] must be there before step 0: a stranger
            # subscribed to state, or an outside reference generator that
            # answers state too, must not stand in for a feedback node that
            # would miss what was sent before it matched, or that still
            # waits for its reference (its generator's reference[0] would go
            # to no one). In realtime too: a clock that starts before the
            # commands can reach it counts misses that are no one's and
            # holds zero current while the feedback winds up.
            return "the node that publishes command to subscribe to state"
        if not self._flow.ready:
            return "the recorder's first recorder/progress (flow control)"
        return None

    def _try_start(self) -> None:
        if self.started:
            return
        waiting = self._waiting_for()
        if waiting is not None:
            if self._start_complaint.ready():
                # A start that never comes is otherwise silent ("no progress").
                waited = time.monotonic() - self._created_s
                if waited >= START_REPORT_S:
                    self.get_logger().warning(
                        f"not started after {waited:.0f} s: waiting for {waiting}"
                    )
            return
        self._start_timer.cancel()
        self.started = True
        self.get_logger().info(f"connected; running {self._steps} steps ({self.values.mode})")
        if self._lockstep:
            self._publish(self.plant.output())
            self._awaiting = 0
            return
        self._clock_thread.prepare()
        # State 0 goes out; the clock starts when its command is in (the
        # loop has closed once: every node has its inputs), d_0 = then.
        with self._lock:
            self._publish(self.plant.output())

    # -- input checks (nothing changes before a message is known good) ----------
    def _awaited_command(self, cmd: msgs.CommandSample) -> msgs.CommandSample:
        """Lockstep: the command of the step the plant waits for, once; realtime: a
        command not older than the held one and not ahead of the plant."""
        if self._lockstep:
            return self._checked_command(cmd)
        with self._lock:
            return self._checked_command(cmd)

    def _checked_command(self, cmd: msgs.CommandSample) -> msgs.CommandSample:
        expected = self.plant.step_index
        if not self._lockstep:
            self._setpoint.check(cmd.step, expected)
            return cmd
        if self._awaiting is None:
            raise SignalError(f"not waiting for a command (step {cmd.step})")
        if cmd.step < expected:
            raise SignalError(f"stale stamp (step {cmd.step}, expected {expected})")
        if cmd.step > expected:
            raise SignalError(f"stamp ahead of the stream (step {cmd.step}, expected {expected})")
        if self._command is not None:
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
        if self._lockstep:
            self._command = current
            self._advance()
            return
        with self._lock:
            now = time.monotonic_ns()
            self._last_command_ns = now
            if not self._clock_thread.started:
                # Command 0, the only one the plant can wait for: d_0 = now.
                self.realtime.start()  # this (the executor's) thread only
                self.clock_record.start_ns = now
                self._clock_thread.start(now, priority=self.realtime.asked or 0)
            self.clock_record.arrived(cmd.step, now)
            self._setpoint.arrived(cmd.step, current, now, self.plant.step_index)

    def _on_setpoint(self, torque_Nm: float) -> None:
        """Realtime, ``drive_setpoint``: the newest set-point, held from now on (NaN: none yet)."""
        drive = self._drive
        assert drive is not None
        with self._lock:
            if math.isnan(torque_Nm):
                # The plugin's command before a controller is active: never applied.
                if drive.unset == 0:
                    self.get_logger().info(
                        "command: NaN (no controller active yet): zero current held"
                    )
                drive.unset += 1
                return
            now = time.monotonic_ns()
            self._last_command_ns = now
            if not self._clock_thread.started:
                # The first set-point: the loop has closed once, d_0 = now.
                self.realtime.start()
                self.clock_record.start_ns = now
                self._clock_thread.start(now, priority=self.realtime.asked or 0)
            # It answers the newest state out (its lateness: since that state's tick).
            self.clock_record.arrived(self.plant.step_index, now)
            current = current_from_torque(torque_Nm, torque_constant_Nm_per_A=self._kt)
            drive.arrived(current, now)

    def _on_progress(self, recorded: int) -> None:
        if self._lockstep:
            self._flow.acknowledge(recorded)
            if self.started:
                self._advance()
            return
        with self._lock:
            self._flow.acknowledge(recorded)
            if self.started:
                self._advance()

    def _watchdog(self) -> None:
        """Every 50 ms: the clock thread's failure, the peers, the end, the fallbacks."""
        if self._clock_thread.error is not None:
            raise RuntimeError(f"the plant's realtime clock failed: {self._clock_thread.error!r}")
        now = time.monotonic()
        self._feedback.look(self.inputs.peer_alive("command"), now)
        self._recorder.look(self.inputs.peer_alive("recorder/progress"), now)
        if self.done:
            return
        if self._lockstep and self._recorder_gone(now):
            return
        if self._finishing:
            self._watch_the_end(now)
        elif self._lockstep and self._awaiting is not None and self._command is None:
            self._answer_for_a_gone_feedback(now)
        elif not self._lockstep and self._clock_thread.started:
            self._watch_the_loop(time.monotonic_ns())

    def _watch_the_loop(self, now_ns: int) -> None:
        """Realtime: end the run with a fault when the clock stalled or the loop is open.

        A realtime run must end by itself: a clock that has not ticked for
        :data:`CLOCK_STALL_S` (``clock_stalled``), or a loop from which no
        command came for :data:`LOOP_OPEN_S` (``loop_open``: the plant would
        hold the last current for ever), ends it with that reason.
        """
        stalled_s = (
            now_ns - max(self._clock_thread.last_tick_ns, self.clock_record.start_ns)
        ) * 1e-9
        open_s = (now_ns - self._last_command_ns) * 1e-9
        if (
            self._drive is not None
            and self._drive.silent_when_unchanged
            and self.inputs.peer_alive("command")
        ):
            # A commander silent while its command does not change: the loop
            # is open only once it has left the graph.
            open_s = 0.0
        if stalled_s > CLOCK_STALL_S:
            kind, detail = (
                "clock_stalled",
                f"the plant's clock has not ticked for {stalled_s:.3g} s",
            )
        elif open_s > LOOP_OPEN_S:
            kind = "loop_open"
            detail = (
                f"no command for {open_s:.3g} s (the newest for step "
                f"{self._setpoint.held_step}): the loop is open"
            )
        else:
            return
        with self._lock:
            if self._finishing:
                return
            step = self.plant.step_index
            self.report.fallback(kind, step, f"{detail}; the run ends at step {step}")
            self._realtime_report()
            self._flow.steps = self._published  # the recorder has all there will be
            # The recorder counts commands too, and they stopped: no long wait.
            self._finish_timeout_s = FAULT_FINISH_S
            self._finish()

    def _recorder_gone(self, now: float) -> bool:
        """Lockstep: flow control off (a fallback) once the recorder it waits for is gone."""
        gone = self._recorder.gone_for(now)
        if not (self._waits_for_recorder() and gone > self.values.command_timeout_s):
            # A gone recorder gets command_timeout_s to come back; while it
            # lives the plant waits for it however long it takes.
            return False
        self._flow.enabled = False
        self.report.fallback(
            "recorder_gone",
            self.plant.step_index,
            f"the recorder (recorder/progress) has been gone for {gone:.3g} s at "
            f"{self._flow.recorded} steps acknowledged: flow control off",
        )
        self._advance()
        return True

    def _watch_the_end(self, now: float) -> None:
        """After the last step: wait for the recorder (lockstep: while it lives)."""
        if self._lockstep and not self.report.health.fallbacks:
            if now - self._finish_started > FINISH_TIMEOUT_S:
                self.get_logger().warning(
                    f"waiting for the recorder: {self._flow.recorded} of {self._steps} steps "
                    "acknowledged (it lives)"
                )
                self._finish_started = now
            return
        # Realtime, or a run that already went on by a fallback (whose
        # commands the recorder may never get): stop after FINISH_TIMEOUT_S
        # (a realtime run the plant ended early: FAULT_FINISH_S).
        if now - self._finish_started > self._finish_timeout_s:
            self.get_logger().error(
                f"recorder acknowledged {self._flow.recorded} of {self._flow.steps} steps "
                f"within {self._finish_timeout_s} s; stopping anyway"
            )
            self.done = True

    def _answer_for_a_gone_feedback(self, now: float) -> None:
        """Lockstep: zero current (a fallback) for the steps of a feedback gone for good."""
        gone = self._feedback.gone_for(now)
        if gone <= self.values.command_timeout_s:
            # While the feedback lives, wait for its command however long it takes.
            self._feedback_gone_step = None
            return
        step = self._awaiting
        if self._feedback_gone_step is None:
            self._feedback_gone_step = step
            self.report.fallback(
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

    def _realtime_tick(self, tick: int, deadline: int) -> bool:
        """The clock thread's tick ``tick`` (due at ``deadline``, ns); True after the last step."""
        with self._lock:
            if self._finishing:
                return True
            self.clock_record.ticked(tick, deadline, time.monotonic_ns())
            if self._drive is not None:
                current, on_time = self._drive.take(deadline)
            else:
                current, on_time = self._setpoint.take(deadline, self.plant.step_index)
            if not on_time:
                self.clock_record.misses += 1
            out = self.plant.step(current)
            if out.step >= self._steps:
                self._realtime_report()
                self._finish()
                return True
            self._publish(out)
            return False

    def _realtime_report(self) -> None:
        """The clock's figures into the report (``health.realtime``), with who runs at which policy."""
        clock = self._clock_thread
        scheduling = {
            **(self.realtime.applied or {"policy": "other", "priority": 0}),
            "clock": clock.scheduling,
            "threads": thread_policies(),
        }
        report = self.clock_record.report(
            self.plant.step_index,
            scheduling,
            slips=clock.slips,
            slipped_periods=clock.slipped_periods,
        )
        if self._drive is not None:
            # A set-point answers no step: a miss is a tick without a fresh one.
            report.update(
                commands_missing=report["misses"],
                commands_late=0,
                setpoints=self._drive.report(),
            )
        self.report.health.realtime = report

    def close(self) -> None:
        """Stop the clock thread (a run stopped from outside), then the base's close.

        A realtime run stopped before its last step still reports its clock.
        """
        self._clock_thread.stop()
        if self._clock_thread.started and not self.report.health.realtime:
            with self._lock:
                self._realtime_report()
        super().close()

    def _finish(self) -> None:
        """After the last step: wait for the recorder to have everything.

        In realtime a last status carries the final deadline-miss count. In
        lockstep there is none: the recorder acknowledges only the per-sample
        topics, so a message after the last sample might or might not make
        it into the bag, and the bag must be the same every run.
        """
        self._finishing = True
        self._finish_started = time.monotonic()
        # The run's wall time is its steps': the start-up before state 0 and
        # the wait for the recorder after the last step are the runner's.
        self.report.health.stepping = {
            "steps": self._steps,
            "first_s": self._first_step_s,
            "last_s": self._finish_started,
        }
        if not self._lockstep:
            self._publish_status()
        self._advance()

    def _publish(self, out: PlantOutput) -> None:
        self._published = out.step + 1
        if out.step == 0:
            self._first_step_s = time.monotonic()
        # The state first: it is what the feedback waits for.
        self._state_pub.publish(self._state_codec.encode(state_sample(out)))
        if self._clock_pub is not None and out.step % self.values.clock_every_steps == 0:
            self._clock_pub.publish(msgs.clock_message(out.step, self._period_ns))
        if out.step % self.values.status_every_steps == 0:
            self._publish_status()

    def _publish_status(self) -> None:
        self._status_pub.publish(
            msgs.labelled_array(
                msgs.STATUS_LABELS,
                [
                    self.plant.step_index,
                    self.clock_record.misses,
                    self.report.health.rejected.get("command", 0),
                    self._timeouts,
                ],
            )
        )


def main(args: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis.nodes.plant``."""
    return run_main("plant", [PlantNode], args, done=lambda nodes: all(n.done for n in nodes))


if __name__ == "__main__":
    raise SystemExit(main())
