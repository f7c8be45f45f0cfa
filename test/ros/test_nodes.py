"""Nodes in one process: the lockstep loop against the core-only loop, bad input, parameters."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from graph_support import graph_nodes, spin_until
from numpy.testing import assert_allclose, assert_array_equal
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from host_load import RunQueueWait, said
from servo_axis.core.errors import ParameterFileError
from servo_axis.nodes.feedback import FeedbackNode
from servo_axis.nodes.feedforward import FeedforwardNode
from servo_axis.nodes.graph import MATCH_SETTLE_S
from servo_axis.nodes.learning import LearningNode
from servo_axis.nodes.plant import PlantNode
from servo_axis.nodes.recorder import RecorderNode
from servo_axis.nodes.runtime import LATCHED_QOS, LIVELINESS_LEASE_S, STREAM_QOS
from servo_axis.params.run_params import handshake_overrides
from servo_axis.params.scenario import (
    axes_of,
    axis_view,
    load_scenario,
    node_params,
    roles_of,
    shared,
)
from servo_axis.recording.deserialize import read_messages
from servo_axis.simulate import simulate
from servo_axis.wire import messages as msgs

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parents[2] / "config"
PERIOD_NS = 1_000_000


def overrides(scenario: Path, role: str, **extra: Any) -> list[Parameter]:
    values = {**node_params(load_scenario(scenario), role), **extra}
    return [Parameter(k, value=v) for k, v in values.items()]


def test_composed_lockstep_equals_core_only_loop(context: Context, tmp_path: Path) -> None:
    """The node graph in one process computes exactly what plain calls compute."""
    scenario = CONFIG / "ptc_friction.yaml"
    steps = 300
    bag = tmp_path / "bag"
    data = load_scenario(scenario)
    data["/**"]["ros__parameters"]["duration_s"] = 0.3
    nodes = graph_nodes(context, data, bag, scenario.parent)
    plant = nodes[-1]
    try:
        spin_until(context, nodes, lambda: plant.done)
        counts = nodes[0].message_counts
    finally:
        nodes[0].close()
        for n in nodes:
            n.destroy_node()
    for topic in ("/state", "/command", "/reference"):
        assert counts[topic] == steps, topic
    assert counts["/clock"] == steps // 10  # /clock every 10 samples
    recorded: dict[str, dict[int, Any]] = {"/state": {}, "/command": {}, "/reference": {}}
    for m in read_messages(bag):
        if m.topic in recorded:
            recorded[m.topic][msgs.step_from_stamp(m.message.header.stamp, PERIOD_NS)] = m.message
    core = simulate(scenario, steps=steps)
    assert_array_equal([recorded["/state"][k].position[0] for k in range(steps)], core.encoder_rad)
    assert_array_equal(
        [recorded["/reference"][k].position[0] for k in range(steps)], core.reference_rad
    )
    assert_array_equal([recorded["/command"][k].effort[0] for k in range(steps)], core.command_Nm)
    # The run is not trivial: friction makes the axis lag, the loop reacts.
    assert np.max(np.abs(core.command_Nm)) > 1.0


class Probe(Node):
    """Publishes hand-made messages to a node under test and collects its output."""

    def __init__(self, context: Context) -> None:
        super().__init__("probe", context=context)
        self.state_pub = self.create_publisher(JointState, "state", STREAM_QOS)
        self.ref_pub = self.create_publisher(JointState, "reference", STREAM_QOS)
        self.commands: list[msgs.CommandSample] = []
        self.faults: list[list[float]] = []
        self.cmd_sub = self.create_subscription(JointState, "command", self._on_command, STREAM_QOS)
        self.fault_sub = self.create_subscription(
            Float64MultiArray, "fault", lambda m: self.faults.append(list(m.data)), LATCHED_QOS
        )

    def _on_command(self, msg: JointState) -> None:
        self.commands.append(msgs.command_from_msg(msg, axis="x", period_ns_=PERIOD_NS))

    def state(self, step: int, angle: float = 0.0) -> JointState:
        return msgs.state_to_msg(
            msgs.StateSample(step, angle, angle * 1.91e-3, 0, 0, 0, 0),
            axis="x",
            period_ns_=PERIOD_NS,
        )

    def reference(self, step: int, angle: float = 0.0, torque: float = 0.0) -> JointState:
        """``reference[step]``: the angle (rad) and the feedforward torque (N m)."""
        return msgs.reference_to_msg(
            msgs.ReferenceSample(step, angle, 0.0, torque), axis="x", period_ns_=PERIOD_NS
        )


def connected(probe: Probe, fb: FeedbackNode) -> Callable[[], bool]:
    """Both directions matched: probe -> feedback and feedback -> probe."""
    return lambda: (
        probe.state_pub.get_subscription_count() >= 1
        and probe.ref_pub.get_subscription_count() >= 1
        and probe.cmd_sub.get_publisher_count() >= 1
        and probe.fault_sub.get_publisher_count() >= 1
    )


def test_feedback_rejects_bad_input_and_passes_nothing_on(context: Context) -> None:
    fb = FeedbackNode(
        context=context, parameter_overrides=[Parameter("input_timeout_s", value=30.0)]
    )
    probe = Probe(context)
    nodes = [fb, probe]
    spin_until(context, nodes, connected(probe, fb))
    probe.ref_pub.publish(probe.reference(0, 0.0, 1.5))
    bad_ref = probe.reference(1)
    bad_ref.position = [math.nan]
    probe.ref_pub.publish(bad_ref)  # NaN: rejected
    short = probe.reference(1)
    short.effort = []
    probe.ref_pub.publish(short)  # wrong length: rejected
    nan_state = probe.state(0)
    nan_state.position = [math.nan, 0.0]
    probe.state_pub.publish(nan_state)  # rejected, no command for it
    probe.state_pub.publish(probe.state(0, 0.0))  # good: answered with the feedforward 1.5 N m
    spin_until(context, nodes, lambda: len(probe.commands) >= 1 and fb.report.rejected >= 3)
    probe.state_pub.publish(probe.state(0, 0.0))  # stale stamp: rejected
    off_grid = probe.state(1)
    off_grid.header.stamp.nanosec += 17
    probe.state_pub.publish(off_grid)  # not on the control grid: rejected
    spin_until(context, nodes, lambda: fb.report.rejected >= 5)
    assert [c.step for c in probe.commands] == [0]
    # The PID sees zero error: the feedforward torque comes back, through the
    # current 1.5 / K_T,n and the torque K_T,n i, up to rounding.
    assert probe.commands[0].torque_Nm == pytest.approx(1.5, rel=2.3e-16)
    assert not probe.faults
    fb.destroy_node()
    probe.destroy_node()


def test_feedback_trips_on_following_error_and_holds_zero(context: Context) -> None:
    fb = FeedbackNode(
        context=context,
        parameter_overrides=[
            Parameter("limits.following_error_m", value=1e-6),
            Parameter("input_timeout_s", value=30.0),
        ],
    )
    probe = Probe(context)
    nodes = [fb, probe]
    spin_until(context, nodes, connected(probe, fb))
    for k in range(3):
        probe.ref_pub.publish(probe.reference(k, 0.01, 2.0))  # 0.01 rad = 19 um error
    for k in range(3):
        probe.state_pub.publish(probe.state(k, 0.0))
    spin_until(context, nodes, lambda: len(probe.commands) >= 3 and len(probe.faults) >= 1)
    assert [c.torque_Nm for c in probe.commands] == [0.0, 0.0, 0.0]
    step, code, value = probe.faults[0]
    assert (step, code) == (0, 1)
    assert value == pytest.approx(0.01 * 1.91e-3, rel=1e-12)
    fb.destroy_node()
    probe.destroy_node()


@pytest.mark.realtime
def test_feedback_trips_when_reference_stops_arriving(context: Context) -> None:
    fb = FeedbackNode(
        context=context, parameter_overrides=[Parameter("input_timeout_s", value=0.3)]
    )
    probe = Probe(context)
    nodes = [fb, probe]
    spin_until(context, nodes, connected(probe, fb))
    probe.destroy_publisher(probe.ref_pub)  # the generator is gone: no reference will come
    t0 = time.monotonic()
    host = RunQueueWait()
    probe.state_pub.publish(probe.state(0))
    spin_until(context, nodes, lambda: len(probe.faults) >= 1 and len(probe.commands) >= 1)
    elapsed = time.monotonic() - t0
    assert probe.faults[0][:2] == [0.0, 4.0]
    assert probe.commands[0].torque_Nm == 0.0
    # Within the stated bound: lease + input_timeout_s + the watchdog period
    # (+ 0.2 s for this test's spinning), + what a busy host withheld.
    bound, wait = LIVELINESS_LEASE_S + 0.3 + 0.03 + 0.2, host.seconds()
    assert 0.3 <= elapsed < bound + wait, said(elapsed, bound, wait)
    assert [f.kind for f in fb.report.health.fallbacks] == ["input_timeout"]
    # Every later state is answered, with zero current: the plant runs to the end.
    for k in range(1, 4):
        probe.state_pub.publish(probe.state(k))
    spin_until(context, nodes, lambda: len(probe.commands) >= 4)
    assert [(c.step, c.torque_Nm) for c in probe.commands] == [(k, 0.0) for k in range(4)]
    fb.destroy_node()
    probe.destroy_node()


@pytest.mark.parametrize(
    ("node_cls", "name", "value", "match"),
    [
        (PlantNode, "inertia_kgm", 0.01, "unknown parameter 'inertia_kgm'"),
        (PlantNode, "inertia_kgm2", "heavy", "parameter 'inertia_kgm2': expected a number"),
        (PlantNode, "inertia_kgm2", -0.01, "parameter 'inertia_kgm2'"),
        (PlantNode, "friction.elements", 0, "parameter 'friction.elements'"),
        (PlantNode, "dead_time_s", 75e-6, "parameter 'dead_time_s'"),
        (FeedbackNode, "bandwidth_hz", -40.0, "bandwidth_hz"),
        (FeedbackNode, "sensor", "laser", "parameter 'sensor'"),
        (FeedforwardNode, "reference.kind", "square", "parameter 'reference.kind'"),
        (FeedforwardNode, "mode", "fast", "parameter 'mode'"),
    ],
)
def test_bad_parameters_stop_the_node_before_it_publishes(
    context: Context, node_cls: type, name: str, value: object, match: str
) -> None:
    watcher = Node("watcher", context=context)
    with pytest.raises(ParameterFileError, match=match):
        node_cls(context=context, parameter_overrides=[Parameter(name, value=value)])
    # Parameters are read before any publisher is made: nothing was offered.
    for topic in ("state", "command", "reference", "/clock"):
        assert watcher.count_publishers(topic) == 0
    watcher.destroy_node()


def test_plant_rejects_bad_commands_and_waits_for_a_valid_one(context: Context) -> None:
    plant = PlantNode(
        context=context, parameter_overrides=[Parameter("wait_for_state_subscribers", value=1)]
    )
    probe = Node("feedback", context=context)  # the plant waits for the expected consumers
    cmd_pub = probe.create_publisher(JointState, "command", STREAM_QOS)
    states: list[msgs.StateSample] = []
    probe.create_subscription(
        JointState,
        "state",
        lambda m: states.append(msgs.state_from_msg(m, axis="x", period_ns_=PERIOD_NS)),
        STREAM_QOS,
    )
    nodes = [plant, probe]
    spin_until(
        context,
        nodes,
        lambda: plant.started and cmd_pub.get_subscription_count() >= 1 and len(states) == 1,
    )

    def command(step: int, torque: float) -> JointState:
        return msgs.command_to_msg(msgs.CommandSample(step, torque), axis="x", period_ns_=PERIOD_NS)

    nan_cmd = command(0, 0.0)
    nan_cmd.effort = [math.nan]
    wrong_name = command(0, 1.0)
    wrong_name.name = ["y_motor"]
    for bad in (nan_cmd, wrong_name, command(1, 1.0)):  # NaN, wrong axis, future stamp
        cmd_pub.publish(bad)
    spin_until(context, nodes, lambda: plant.report.rejected >= 3)
    assert len(states) == 1 and plant.plant.step_index == 0  # nothing moved
    cmd_pub.publish(command(0, 2.0))  # 2 N m: the plant's current 2 / K_T, its torque 2 N m
    spin_until(context, nodes, lambda: len(states) == 2)
    assert states[1].step == 1 and states[1].motor_torque_Nm == pytest.approx(2.0, rel=1e-15)
    cmd_pub.publish(command(0, 2.0))  # stale: step 0 is done
    spin_until(context, nodes, lambda: plant.report.rejected >= 4)
    assert plant.plant.step_index == 1
    plant.destroy_node()
    probe.destroy_node()


def test_plant_starts_only_once_the_node_that_answers_state_listens(
    context: Context, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    """Another subscriber of `state` (an outside reference generator that answers it too)
    does not stand in for the node that publishes `command`: with the expected count met
    and settled, and `command` matched, the plant waits until that node subscribes, and
    says what it waits for."""
    monkeypatch.setattr("servo_axis.nodes.plant.START_REPORT_S", 0.5)
    plant = PlantNode(
        context=context, parameter_overrides=[Parameter("wait_for_state_subscribers", value=1)]
    )
    assert plant._waiting_for() == "1 subscribers of state (the graph lists 0, 0 matched)"
    generator = Node("my_sine_reference", context=context)
    generator.create_subscription(JointState, "state", lambda m: None, 10)
    controller = Node("my_controller", context=context)
    controller.create_publisher(JointState, "command", 10)
    nodes = [plant, generator, controller]
    settled = time.monotonic() + 2 * MATCH_SETTLE_S + 0.5
    spin_until(context, nodes, lambda: time.monotonic() > settled)
    assert plant.graph.consumers_matched(plant._state_pub, "state", 1)
    assert plant.inputs.matched("command") and not plant.started
    waiting = "the node that publishes command to subscribe to state"
    assert plant._waiting_for() == waiting
    assert f"waiting for {waiting}" in capfd.readouterr().err
    states: list[JointState] = []
    controller.create_subscription(JointState, "state", states.append, 10)
    spin_until(context, nodes, lambda: plant.started and len(states) == 1)
    assert states[0].header.stamp.sec == 0 and states[0].header.stamp.nanosec == 0
    for n in nodes:
        n.destroy_node()


@pytest.mark.realtime
def test_realtime_plant_holds_the_newest_command_and_counts_misses(context: Context) -> None:
    period_ns = 100_000_000  # 0.1 s ticks: the probe answers well within one
    plant = PlantNode(
        context=context,
        parameter_overrides=[
            Parameter("mode", value="realtime"),
            Parameter("control_period_s", value=0.1),
            Parameter("sim_step_s", value=1e-3),
            Parameter("duration_s", value=0.6),
            Parameter("flow_control", value=False),
            Parameter("wait_for_state_subscribers", value=1),
            # In the test's own process: not under SCHED_FIFO (test_scheduling).
            Parameter("thread_priority", value=0),
        ],
    )
    probe = Node("feedback", context=context)
    cmd_pub = probe.create_publisher(JointState, "command", STREAM_QOS)

    def command(step: int, torque: float) -> JointState:
        return msgs.command_to_msg(msgs.CommandSample(step, torque), axis="x", period_ns_=period_ns)

    # What the probe sends when it sees state k: command 0 (it starts the
    # plant's clock), nothing, a late one, on time, one older than the held
    # one, on time.
    answers = {
        0: [command(0, 1.0)],
        2: [command(1, 2.0)],
        3: [command(3, 3.0)],
        4: [command(2, 5.0)],
        5: [command(5, 4.0)],
    }
    states: list[msgs.StateSample] = []

    def on_state(m: JointState) -> None:
        states.append(msgs.state_from_msg(m, axis="x", period_ns_=period_ns))
        for answer in answers.get(states[-1].step, []):
            cmd_pub.publish(answer)

    probe.create_subscription(JointState, "state", on_state, STREAM_QOS)
    spin_until(context, [plant, probe], lambda: bool(plant.report.health.realtime), timeout_s=30)
    assert [s.step for s in states] == [0, 1, 2, 3, 4, 5]
    # tick 1: command 0, in at d_0; tick 2: nothing (held 1.0); tick 3: step
    # 1's command came after its tick, yet is the newest: held; tick 4: on
    # time; tick 5: step 2's command is older than the held one: stale,
    # rejected, changes nothing; tick 6 (no state after the last): on time.
    assert_allclose(
        [s.motor_torque_Nm for s in states[1:6]], [1.0, 1.0, 2.0, 3.0, 3.0], rtol=1e-15, atol=0.0
    )
    assert plant.clock_record.misses == 3 and plant.report.rejected == 1
    report = plant.report.health.realtime
    assert report["ticks"] == 6 and report["misses"] == 3
    # Step 1 came late, steps 2 (rejected) and 4 never: the misses of ticks 2, 3, 5.
    assert report["commands_late"] == 1 and report["commands_missing"] == 2
    assert report["command_late_us"]["max"] > 100_000.0  # step 1's, after its tick
    # thread_priority 0: the default scheduler, for the executor and the clock thread.
    assert report["scheduling"]["policy"] == "other"
    assert report["scheduling"]["clock"] == {"policy": "other", "priority": 0}
    assert "fifo" not in report["scheduling"]["threads"]
    assert report["clock_slips"] == 0 and report["slipped_periods"] == 0
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
    plant.destroy_node()
    probe.destroy_node()


def test_feedforward_rejects_a_bad_status_and_publishes_ahead(context: Context) -> None:
    ff = FeedforwardNode(
        context=context, parameter_overrides=[Parameter("preview_steps", value=20)]
    )
    probe = Node("status_probe", context=context)
    status_pub = probe.create_publisher(Float64MultiArray, "plant/status", STREAM_QOS)
    refs: list[msgs.ReferenceSample] = []
    probe.create_subscription(
        JointState,
        "reference",
        lambda m: refs.append(msgs.reference_from_msg(m, axis="x", period_ns_=PERIOD_NS)),
        STREAM_QOS,
    )
    nodes = [ff, probe]
    spin_until(context, nodes, lambda: status_pub.get_subscription_count() >= 1 and len(refs) == 20)
    bad = msgs.labelled_array(
        ("step", "deadline_misses", "rejected_commands", "command_timeouts"), [15, 0, 0, 0]
    )
    bad.layout.dim[1].label = "misses"
    status_pub.publish(bad)
    spin_until(context, nodes, lambda: ff.report.rejected >= 1)
    assert len(refs) == 20  # a bad status moves nothing
    status_pub.publish(
        msgs.labelled_array(
            ("step", "deadline_misses", "rejected_commands", "command_timeouts"), [15, 0, 0, 0]
        )
    )
    spin_until(context, nodes, lambda: len(refs) == 35)
    assert [r.step for r in refs] == list(range(35))
    ff.destroy_node()
    probe.destroy_node()


def test_learning_node_bad_memory_file_fails_or_starts_clean(
    context: Context, tmp_path: Path
) -> None:
    from servo_axis.core.learning.rptc import LearningParams, PeriodicSignalGenerator
    from servo_axis.nodes.learning import LearningNode
    from servo_axis.storage import save_memory

    memory = tmp_path / "memory.json"
    memory.write_text('{"format": "servo_axis rptc memory v1", "correction": [0.1, ')  # truncated

    def node(**extra: object) -> LearningNode:
        overrides = {"memory.file": str(memory), "scenario.name": "rptc_ideal", **extra}
        return LearningNode(
            context=context,
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
        )

    with pytest.raises(ParameterFileError, match=r"memory\.file.*corrupt or truncated"):
        node()
    clean = node(**{"memory.on_bad_file": "clear"})
    assert clean.law.cycles_learned == 0 and not clean.law.correction.any()
    clean.destroy_node()
    # A sound file of another scenario is not silently used either.
    other = PeriodicSignalGenerator(
        LearningParams(samples_per_cycle=250, nq=20, n=1, period_s=2e-3)
    )
    other.learn(np.ones(250))
    save_memory(memory, other, scenario="rptc_detailed")
    with pytest.raises(ParameterFileError, match="scenario"):
        node()
    save_memory(memory, other, scenario="rptc_ideal")
    resumed = node()
    assert resumed.law.cycles_learned == 1
    np.testing.assert_array_equal(resumed.law.correction, other.correction)
    resumed.destroy_node()


def test_feedforward_rejects_bad_corrections(context: Context) -> None:
    ff = FeedforwardNode(
        context=context,
        parameter_overrides=[
            Parameter("learning.enabled", value=True),
            Parameter("learning.cycle_s", value=0.02),  # 20 samples, 10 reference instants
            Parameter("preview_steps", value=100),
        ],
    )
    probe = Node("corr_probe", context=context)
    pub = probe.create_publisher(JointState, "learning/correction", STREAM_QOS)
    nodes = [ff, probe]
    spin_until(context, nodes, lambda: pub.get_subscription_count() >= 1 and ff.published == 18)
    assert ff.generator.ready_until() == 18  # the boundary samples wait for cycle 2's correction

    def corr(step: int, pos: float = 1e-6) -> JointState:
        return msgs.correction_to_msg(
            msgs.CorrectionSample(step, pos, 0.0), axis="x", period_ns_=PERIOD_NS
        )

    nan = corr(20)
    nan.position[0] = math.nan  # the encoder refuses NaN; a foreign publisher might not
    # NaN, not a reference instant, a cycle under way, cycles too far ahead
    bad = [nan, corr(21), corr(0), corr(60), corr(10**6)]
    short = corr(22)
    short.velocity = []
    for m in [*bad, short]:
        pub.publish(m)
    spin_until(context, nodes, lambda: ff.report.rejected >= 6)
    assert ff.generator.ready_until() == 18 and ff.published == 18  # nothing moved
    for k in range(20, 40, 2):
        pub.publish(corr(k))
    spin_until(context, nodes, lambda: ff.published == 38)
    assert ff.generator.ready_until() == 38
    ff.destroy_node()
    probe.destroy_node()


def test_learning_node_learns_only_from_whole_cycles_of_valid_states(context: Context) -> None:
    from servo_axis.nodes.learning import LearningNode

    def node(**extra: object) -> LearningNode:
        values = {"cycle_s": 0.02, "nq": 2, **extra}  # 10 reference instants per cycle
        return LearningNode(
            context=context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
        )

    with pytest.raises(ParameterFileError, match=r"'cycle_s': at most"):
        node(cycle_s=2.0)  # more than the state stream's history can hold
    learning = node(late_join=True)  # respawned mid-run: joins at the first state it gets
    probe = Probe(context)
    stats: list[list[float]] = []
    probe.create_subscription(
        Float64MultiArray, "learning/cycle_stats", lambda m: stats.append(list(m.data)), STREAM_QOS
    )
    nodes = [learning, probe]
    spin_until(context, nodes, lambda: probe.state_pub.get_subscription_count() >= 1)
    probe.state_pub.publish(probe.state(10**6))  # beyond the run's 2,000 steps: rejected
    spin_until(context, nodes, lambda: learning.report.rejected >= 1)
    for k in range(4, 40):  # joins at step 4: cycle 1 lacks two of its instants
        probe.state_pub.publish(probe.state(k))
    spin_until(context, nodes, lambda: len(stats) >= 2)
    assert learning.report.rejected == 1
    # Cycle 1 was seen in part: reported but not learned; cycle 2 is learned.
    assert [s[0] for s in stats] == [1.0, 2.0] and [s[3] for s in stats] == [0.0, 1.0]
    # The axis stood still at 0: the error is the reference itself.
    target_m = learning.reference.sample(np.arange(10, 20) * 2e-3)[0]
    np.testing.assert_allclose(stats[1][1], np.sqrt(np.mean(target_m**2)), rtol=1e-12)
    np.testing.assert_allclose(stats[1][2], np.max(np.abs(target_m)), rtol=1e-12)
    learning.destroy_node()
    probe.destroy_node()


def test_feedforward_ends_the_run_without_waiting_for_a_correction_after_it(
    context: Context,
) -> None:
    ff = FeedforwardNode(
        context=context,
        parameter_overrides=[
            Parameter("learning.enabled", value=True),
            Parameter("learning.cycle_s", value=0.02),  # 20 samples, 10 reference instants
            Parameter("duration_s", value=0.04),  # two cycles
            Parameter("preview_steps", value=100),
        ],
    )
    probe = Node("end_probe", context=context)
    pub = probe.create_publisher(JointState, "learning/correction", STREAM_QOS)
    nodes = [ff, probe]
    spin_until(context, nodes, lambda: pub.get_subscription_count() >= 1 and ff.published == 18)
    for k in range(20, 40, 2):  # the correction of cycle 2, the run's last
        pub.publish(
            msgs.correction_to_msg(
                msgs.CorrectionSample(k, 1e-6, 0.0), axis="x", period_ns_=PERIOD_NS
            )
        )
    # Samples 38 and 39 look into a cycle after the run, for which no
    # correction comes: all 40 go out at once, not after learning.timeout_s.
    spin_until(context, nodes, lambda: ff.published == 40)
    assert ff.corrections.missed == 0 and ff.report.rejected == 0
    ff.destroy_node()
    probe.destroy_node()


SCENARIOS = sorted(CONFIG.glob("*.yaml"))


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_every_scenario_is_accepted_by_each_of_its_nodes(
    context: Context, scenario: Path, tmp_path: Path
) -> None:
    from servo_axis.nodes.identifier import IdentifierNode
    from servo_axis.nodes.learning import LearningNode

    data = load_scenario(scenario)
    # `python -m servo_axis list` shows it; the summary carries it.
    assert shared(data)["scenario"]["description"]
    classes = {
        "plant": PlantNode,
        "feedback": FeedbackNode,
        "feedforward": FeedforwardNode,
        "learning": LearningNode,
        "identifier": IdentifierNode,
        "recorder": RecorderNode,
    }
    # A multi-axis scenario: each axis's merged view, as the bringup runs it.
    views = [axis_view(data, a, scenario.parent) for a in axes_of(data)] or [data]
    for number, view in enumerate(views):
        roles = roles_of(view)
        assert {"plant", "feedback"} <= set(roles)
        extra = handshake_overrides(view, roles, tmp_path / f"{number}" / "bag", scenario.parent)
        for role in roles:
            values = {**node_params(view, role), **extra.get(role, {})}
            # The full validation of the node's constructor (schema, ranges,
            # physical consistency, files): it raises on anything wrong.
            node = classes[role](
                context=context,
                parameter_overrides=[Parameter(k, value=v) for k, v in values.items()],
            )
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()


def toy_scenario(tmp_path: Path) -> tuple[dict[str, Any], Path]:
    """ptc_nominal on the test-only toy model, its nominal model equal to the toy (D = 0)."""
    data = load_scenario(CONFIG / "ptc_nominal.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = 0.5
    data["/**"]["ros__parameters"]["nominal"]["damping_Nms_per_rad"] = 0.0
    data["plant"] = {
        "ros__parameters": {
            "model": "toy_rigid_body",
            "inertia_kgm2": 0.01,
            "torque_constant_Nm_per_A": 0.715,
        }
    }
    path = tmp_path / "toy.yaml"
    path.write_text(yaml.safe_dump(data))
    return data, path


@pytest.fixture
def toy_model() -> Iterator[None]:
    """The toy plant model registered in this process for one test, and gone after it
    (the parameter reference of a later test lists the installed extensions only)."""
    import toy_plant_model

    from servo_axis.params.factories import PLANT_MODELS, register_plant_model

    if toy_plant_model.NAME not in PLANT_MODELS:  # imported before, then removed
        register_plant_model(
            toy_plant_model.NAME, schema=toy_plant_model.SCHEMA, build=toy_plant_model.build
        )
    yield
    PLANT_MODELS.unregister(toy_plant_model.NAME)


def test_a_new_plant_model_runs_headless_and_in_the_node_graph(
    context: Context, tmp_path: Path, toy_model: None
) -> None:
    """A model added as one module + its registration (toy_plant_model) runs through
    simulate (no ROS) and through the node graph, with identical numbers."""

    data, path = toy_scenario(tmp_path)
    steps = 500
    core = simulate(path)
    # PTC on a nominal model equal to the plant tracks exactly at the T_r
    # instants (000 Sect. III-A): the toy is really the plant that ran.
    even = np.arange(0, steps, 2)
    stroke = 0.02 / 1.91e-3
    assert np.max(np.abs(core.reference_rad[even] - core.encoder_rad[even])) < 1e-12 * stroke
    assert np.max(np.abs(core.command_Nm)) > 1.0
    bag = tmp_path / "bag"
    nodes = graph_nodes(context, data, bag, path.parent)
    plant = nodes[-1]
    try:
        spin_until(context, nodes, lambda: plant.done)
    finally:
        nodes[0].close()
        for n in nodes:
            n.destroy_node()
    recorded: dict[str, dict[int, Any]] = {"/state": {}, "/command": {}}
    for m in read_messages(bag):
        if m.topic in recorded:
            recorded[m.topic][msgs.step_from_stamp(m.message.header.stamp, PERIOD_NS)] = m.message
    assert_array_equal([recorded["/state"][k].position[0] for k in range(steps)], core.encoder_rad)
    assert_array_equal([recorded["/command"][k].effort[0] for k in range(steps)], core.command_Nm)
    # An unknown model name stops the plant naming the key and the registered ones.
    with pytest.raises(ParameterFileError, match=r"parameter 'model': expected one of \["):
        PlantNode(context=context, parameter_overrides=[Parameter("model", value="no_such")])


def test_the_learning_unit_learns_against_the_controlled_output(
    context: Context, tmp_path: Path
) -> None:
    """With ``feedback.sensor: scale`` the learning unit's error is target - scale / R.

    On the detailed axis the 100 nm scale differs from R x the 2^20 encoder
    (11 nm), so the per-cycle statistics tell which sensor was learned from;
    they are recomputed here from the bag's own state stream and the
    reference the scenario states (plain numpy, not the suite's code).
    """
    data = load_scenario(CONFIG / "rptc_detailed.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = 1.5  # three cycles: stats of two
    data["feedback"]["ros__parameters"]["sensor"] = "scale"
    bag = tmp_path / "bag"
    nodes = graph_nodes(context, data, bag, CONFIG)
    plant = nodes[-1]
    try:
        spin_until(context, nodes, lambda: plant.done, timeout_s=120)
    finally:
        nodes[0].close()
        for n in nodes:
            n.destroy_node()
    scale: dict[int, float] = {}
    encoder: dict[int, float] = {}
    stats = []
    for m in read_messages(bag):
        if m.topic == "/state":
            k = msgs.step_from_stamp(m.message.header.stamp, PERIOD_NS)
            encoder[k], scale[k] = m.message.position[0], m.message.position[1]
        elif m.topic == "/learning/cycle_stats":
            stats.append(list(m.message.data))
    assert [s[0] for s in stats] == [1.0, 2.0]
    ref = data["feedforward"]["ros__parameters"]["reference"]
    lead = 1.91e-3
    for cycle, rms, peak, _ in stats:
        k = np.arange(int(cycle - 1) * 500, int(cycle) * 500, 2)  # the T_r instants
        target = ref["offset_m"] + ref["amplitude_m"] * np.sin(
            2 * np.pi * ref["frequency_hz"] * k * 1e-3 + ref["phase_rad"]
        )
        by_scale = target - np.array([scale[i] for i in k])
        by_encoder = target - lead * np.array([encoder[i] for i in k])
        assert_allclose(rms, np.sqrt(np.mean(by_scale**2)), rtol=1e-9)
        assert_allclose(peak, np.max(np.abs(by_scale)), rtol=1e-9)
        # Not the encoder: the two sensors differ by more than the tolerance.
        assert abs(rms - np.sqrt(np.mean(by_encoder**2))) > 1e-6 * rms


def test_the_learning_unit_listens_only_once_its_outputs_are_heard(context: Context) -> None:
    """It subscribes to `state` (which the plant waits for before step 0) only after its
    correction publisher has the subscribers the run expects, so its first
    correction cannot be lost to a reader still being discovered."""
    learning = LearningNode(
        context=context,
        parameter_overrides=[
            Parameter("cycle_s", value=0.02),
            Parameter("nq", value=2),
            Parameter("wait_for_correction_subscribers", value=1),
        ],
    )
    probe = Node("feedforward", context=context)  # the expected consumer, by name
    nodes = [learning, probe]
    deadline = time.monotonic() + 0.5
    spin_until(context, nodes, lambda: time.monotonic() > deadline)
    assert probe.count_subscribers("state") == 0 and not learning.state_subscribed
    probe.create_subscription(JointState, "learning/correction", lambda m: None, STREAM_QOS)
    spin_until(context, nodes, lambda: learning.state_subscribed)
    assert learning._correction_pub.get_subscription_count() >= 1
    # A subscription is made once its topic has a publisher (with the profile that matches it).
    probe.create_publisher(JointState, "state", STREAM_QOS)
    spin_until(context, nodes, lambda: probe.count_subscribers("state") == 1)
    learning.destroy_node()
    probe.destroy_node()


# -- streams, peers and handshakes (issue 7) -------------------------------------------


def test_stamps_ahead_of_the_stream_do_not_displace_it(context: Context, tmp_path: Path) -> None:
    """A valid-looking state and reference stamped step + 1000 and 1e9 s, mid-run, from a
    node that is not the plant: never applied (a stranger's, counted apart, before any
    check); the run goes on and every step is commanded once."""
    scenario = CONFIG / "ptc_nominal.yaml"
    steps = 300
    data = load_scenario(scenario)
    data["/**"]["ros__parameters"]["duration_s"] = 0.3
    nodes = graph_nodes(context, data, tmp_path / "bag", scenario.parent)
    recorder, feedback, plant = nodes[0], nodes[roles_of(data).index("feedback")], nodes[-1]
    assert isinstance(feedback, FeedbackNode) and isinstance(plant, PlantNode)
    junk = Probe(context)
    junk_at = 100
    far = 10**12  # 1e9 s at 1 ms

    def on_state(m: JointState) -> None:
        if msgs.step_from_stamp(m.header.stamp, PERIOD_NS) == junk_at:
            for step in (junk_at + 1000, far):
                junk.state_pub.publish(junk.state(step))
                junk.ref_pub.publish(junk.reference(step, 0.5, 3.0))

    junk.create_subscription(JointState, "state", on_state, STREAM_QOS)
    try:
        spin_until(context, [*nodes, junk], lambda: plant.done, timeout_s=30)
        counts = recorder.message_counts
    finally:
        recorder.close()
        for n in [*nodes, junk]:
            n.destroy_node()
    assert counts["/command"] == steps
    assert counts["/state"] == steps + 2  # the recorder keeps what was on the wire
    assert feedback.report.health.stranger_messages == {"state": 2, "reference": 2}
    assert feedback.report.health.rejected == {}
    assert not feedback.loop.tripped and not plant.report.health.fallbacks
    assert plant.report.health.rejected == {}


def test_learning_unit_validates_a_state_before_it_moves_its_gate(context: Context) -> None:
    """NaN, short and wrong-name states a little ahead leave the collected error alone."""
    learning = LearningNode(
        context=context,
        parameter_overrides=[Parameter("cycle_s", value=0.02), Parameter("nq", value=2)],
    )
    probe = Probe(context)
    stats: list[list[float]] = []
    probe.create_subscription(
        Float64MultiArray, "learning/cycle_stats", lambda m: stats.append(list(m.data)), STREAM_QOS
    )
    nodes = [learning, probe]
    spin_until(context, nodes, lambda: probe.state_pub.get_subscription_count() >= 1)
    for k in range(10):
        probe.state_pub.publish(probe.state(k))
    spin_until(context, nodes, lambda: learning._gate.last == 8)
    collected = learning._error.error.copy()
    nan = probe.state(12)
    nan.position = [math.nan, 0.0]
    short = probe.state(12)
    short.effort = [0.0]
    wrong = probe.state(12)
    wrong.name = ["y_motor", "y_table"]
    ahead_nan = probe.state(10)
    ahead_nan.velocity = [math.inf, 0.0]
    for m in (nan, short, wrong, ahead_nan):
        probe.state_pub.publish(m)
    spin_until(context, nodes, lambda: learning.report.rejected >= 4)
    assert learning._gate.last == 8
    np.testing.assert_array_equal(learning._error.error, collected)
    for k in range(10, 40):
        probe.state_pub.publish(probe.state(k))
    spin_until(context, nodes, lambda: len(stats) >= 2)
    # Cycle 1 was whole after all: learned (cycles_learned 1 after it).
    assert learning.report.rejected == 4 and learning.report.health.rejected == {"state": 4}
    assert [s[0] for s in stats] == [1.0, 2.0] and [s[3] for s in stats] == [1.0, 2.0]
    target_m = learning.reference.sample(np.arange(0, 10) * 2e-3)[0]
    np.testing.assert_allclose(stats[0][1], np.sqrt(np.mean(target_m**2)), rtol=1e-12)
    learning.destroy_node()
    probe.destroy_node()


def progress_message(value: float) -> Float64MultiArray:
    """A recorder/progress message with any value (the encoder refuses NaN/inf)."""
    msg = msgs.labelled_array(msgs.PROGRESS_LABELS, [0])
    msg.data = [value]
    return msg


def test_plant_rejects_implausible_recorder_progress_under_its_topic(context: Context) -> None:
    steps = 30
    plant = PlantNode(
        context=context,
        parameter_overrides=[
            Parameter("duration_s", value=steps * 1e-3),
            Parameter("flow_control", value=True),
            Parameter("max_recorder_lag_steps", value=5),
            Parameter("wait_for_state_subscribers", value=1),
        ],
    )
    feedback = Node("feedback", context=context)
    cmd_pub = feedback.create_publisher(JointState, "command", STREAM_QOS)
    states: list[int] = []
    recorder = Node("recorder", context=context)
    progress_pub = recorder.create_publisher(Float64MultiArray, "recorder/progress", LATCHED_QOS)
    auto_ack = [False]

    def on_state(m: JointState) -> None:
        step = msgs.step_from_stamp(m.header.stamp, PERIOD_NS)
        states.append(step)
        if auto_ack[0]:
            progress_pub.publish(progress_message(len(states)))
        cmd_pub.publish(
            msgs.command_to_msg(msgs.CommandSample(step, 0.0), axis="x", period_ns_=PERIOD_NS)
        )

    feedback.create_subscription(JointState, "state", on_state, STREAM_QOS)
    nodes = [plant, feedback, recorder]
    spin_until(context, nodes, lambda: cmd_pub.get_subscription_count() >= 1)
    progress_pub.publish(progress_message(0))  # ready
    spin_until(context, nodes, lambda: len(states) == 6 and plant._command is not None)
    assert plant.plant.step_index == 5  # held at the lag: step 6 needs step 1 recorded
    # NaN, inf, not whole, beyond the 6 states published (one at a time: depth 1)
    for count, bad in enumerate((math.nan, math.inf, 2.5, 1000.0), start=1):
        progress_pub.publish(progress_message(bad))
        spin_until(context, nodes, lambda n=count: plant.report.rejected >= n)
    progress_pub.publish(progress_message(3.0))  # good: the plant may go to step 8
    spin_until(context, nodes, lambda: len(states) == 9)
    progress_pub.publish(progress_message(2.0))  # below the last one
    spin_until(context, nodes, lambda: plant.report.rejected >= 5)
    assert plant._flow.recorded == 3 and plant.plant.step_index == 8
    auto_ack[0] = True
    progress_pub.publish(progress_message(len(states)))
    spin_until(context, nodes, lambda: plant.done)
    assert states == list(range(steps))
    assert plant.report.health.rejected == {"recorder/progress": 5}  # not counted as commands
    assert not plant.report.health.fallbacks and plant._flow.enabled
    for n in nodes:
        n.destroy_node()


@pytest.mark.realtime
def test_plant_waits_for_a_slow_feedback_and_falls_back_only_once_it_is_gone(
    context: Context,
) -> None:
    steps = 10
    plant = PlantNode(
        context=context,
        parameter_overrides=[
            Parameter("duration_s", value=steps * 1e-3),
            Parameter("command_timeout_s", value=0.2),
            Parameter("wait_for_state_subscribers", value=1),
        ],
    )
    feedback = Node("feedback", context=context)
    cmd_pub = feedback.create_publisher(JointState, "command", STREAM_QOS)
    states: list[msgs.StateSample] = []
    feedback.create_subscription(
        JointState,
        "state",
        lambda m: states.append(msgs.state_from_msg(m, axis="x", period_ns_=PERIOD_NS)),
        STREAM_QOS,
    )
    nodes = [plant, feedback]
    spin_until(context, nodes, lambda: len(states) == 1 and cmd_pub.get_subscription_count() >= 1)
    slow = time.monotonic() + 4 * 0.2  # four command timeouts, and more than the 1 s lease
    spin_until(context, nodes, lambda: time.monotonic() > slow + LIVELINESS_LEASE_S)
    assert (
        plant._timeouts == 0 and plant.plant.step_index == 0 and not plant.report.health.fallbacks
    )
    cmd_pub.publish(msgs.command_to_msg(msgs.CommandSample(0, 2.0), axis="x", period_ns_=PERIOD_NS))
    spin_until(context, nodes, lambda: len(states) == 2)
    assert states[1].motor_torque_Nm == pytest.approx(2.0, rel=1e-15)
    t0 = time.monotonic()
    host = RunQueueWait()
    feedback.destroy_publisher(cmd_pub)  # the feedback is gone
    spin_until(context, nodes, lambda: plant.done, timeout_s=30)
    # lease + command_timeout_s + the watchdog period (+ 0.5 s for the rest of
    # the 10 steps and this test's spinning), + what a busy host withheld.
    elapsed, wait = time.monotonic() - t0, host.seconds()
    bound = LIVELINESS_LEASE_S + 0.2 + 0.05 + 0.5
    assert elapsed < bound + wait, said(elapsed, bound, wait)
    spin_until(context, nodes, lambda: len(states) == steps)
    (fallback,) = plant.report.health.fallbacks
    assert (fallback.kind, fallback.step) == ("command_timeout", 1)
    assert plant._timeouts == steps - 1
    assert [s.step for s in states] == list(range(steps))
    for n in nodes:
        n.destroy_node()


@pytest.mark.realtime
def test_feedforward_keeps_the_last_correction_only_once_the_learning_unit_is_gone(
    context: Context,
) -> None:
    ff = FeedforwardNode(
        context=context,
        parameter_overrides=[
            Parameter("learning.enabled", value=True),
            Parameter("learning.cycle_s", value=0.02),  # 20 samples, 10 reference instants
            Parameter("learning.timeout_s", value=0.2),
            Parameter("preview_steps", value=100),
        ],
    )
    learning = Node("learning", context=context)
    pub = learning.create_publisher(JointState, "learning/correction", STREAM_QOS)
    nodes = [ff, learning]
    spin_until(context, nodes, lambda: pub.get_subscription_count() >= 1 and ff.published == 18)
    later = time.monotonic() + 5 * 0.2  # the plant stands still, the unit lives: wait
    spin_until(context, nodes, lambda: time.monotonic() > later)
    assert ff.corrections.missed == 0 and ff.published == 18 and not ff.report.health.fallbacks
    t0 = time.monotonic()
    host = RunQueueWait()
    learning.destroy_publisher(pub)
    spin_until(context, nodes, lambda: ff.corrections.missed == 1)
    # lease + learning.timeout_s + the watchdog period (+ 0.5 s for this
    # test's spinning), + what a busy host withheld.
    elapsed, wait = time.monotonic() - t0, host.seconds()
    bound = LIVELINESS_LEASE_S + 0.2 + 0.04 + 0.5
    assert elapsed < bound + wait, said(elapsed, bound, wait)
    (fallback,) = ff.report.health.fallbacks
    assert (fallback.kind, fallback.step) == ("learning_timeout", 18)
    assert ff.published == 38  # cycle 2 runs with the last (zero) correction
    for n in nodes:
        n.destroy_node()


@pytest.mark.realtime
def test_realtime_feedforward_never_waits_for_a_correction_and_takes_a_late_one(
    context: Context,
) -> None:
    """Realtime: the boundary goes by with the last correction (no wait, no fallback);
    a correction for a cycle already published whole is refused, one for a cycle not
    yet published whole applies from the next sample (late_corrections)."""
    ff = FeedforwardNode(
        context=context,
        parameter_overrides=[
            Parameter("mode", value="realtime"),
            Parameter("thread_priority", value=0),  # in the test's own process
            Parameter("learning.enabled", value=True),
            Parameter("learning.cycle_s", value=0.02),  # 20 samples, 10 reference instants
            Parameter("preview_steps", value=100),
        ],
    )
    probe = Node("corr_probe", context=context)
    pub = probe.create_publisher(JointState, "learning/correction", STREAM_QOS)
    nodes = [ff, probe]
    spin_until(context, nodes, lambda: pub.get_subscription_count() >= 1 and ff.published >= 60)
    assert ff.corrections.missed == 0 and not ff.report.health.fallbacks

    def cycle(index: int) -> list[JointState]:
        return [
            msgs.correction_to_msg(
                msgs.CorrectionSample(20 * index + 2 * i, 1e-6, 0.0), axis="x", period_ns_=PERIOD_NS
            )
            for i in range(10)
        ]

    published = ff.published
    for m in cycle(1):  # cycle 2, samples 20-39: out whole already
        pub.publish(m)
    spin_until(context, nodes, lambda: ff.report.rejected >= 10)
    assert ff.report.health.rejected == {"learning/correction": 10} and ff.corrections.late == 0
    under_way = published // 20  # its last samples are not out yet
    for m in cycle(under_way):
        pub.publish(m)
    spin_until(context, nodes, lambda: ff.corrections.late == 1)
    assert ff.report.rejected == 10 and not ff.report.health.fallbacks
    for n in nodes:
        n.destroy_node()


def test_feedback_listens_only_once_its_command_is_heard(context: Context) -> None:
    """Its `command` consumers are counted by topic, whatever their node is called: an
    outside plant with rclpy's default profile (volatile, no lease) counts once it has held
    for the settle time; before anyone listens, or before a reference generator is matched
    and settled, the feedback does not subscribe to state."""
    fb = FeedbackNode(
        context=context, parameter_overrides=[Parameter("wait_for_command_subscribers", value=1)]
    )
    plant_side = Node("my_axis_driver", context=context)  # not called `plant`
    state_pub = plant_side.create_publisher(JointState, "state", 10)
    nodes = [fb, plant_side]
    deadline = time.monotonic() + 0.7
    spin_until(context, nodes, lambda: time.monotonic() > deadline)
    assert not fb.inputs_subscribed and state_pub.get_subscription_count() == 0
    plant_side.create_subscription(JointState, "command", lambda m: None, 10)
    # Heard, but no reference generator yet: a volatile one's reference[0] would be lost.
    deadline = time.monotonic() + 0.7
    spin_until(context, nodes, lambda: time.monotonic() > deadline)
    assert not fb.inputs_subscribed and state_pub.get_subscription_count() == 0
    host = RunQueueWait()
    reference_pub = plant_side.create_publisher(JointState, "reference", 10)
    spin_until(context, nodes, lambda: reference_pub.get_subscription_count() == 1)
    matched = time.monotonic()
    noticed = host.seconds()  # a busy host lets this loop see the match late by at most this
    spin_until(context, nodes, lambda: fb.inputs_subscribed)
    # A volatile generator's match settles first: it must have matched on its own side.
    settled = time.monotonic() - matched
    assert settled > MATCH_SETTLE_S / 2 - noticed, (settled, noticed)
    # Its state subscription matches the default-QoS publisher.
    spin_until(context, nodes, lambda: state_pub.get_subscription_count() == 1)
    for n in nodes:
        n.destroy_node()


def test_the_recorder_reports_a_stream_gone_only_when_no_writer_comes_back(
    context: Context, tmp_path: Path
) -> None:
    from types import SimpleNamespace

    scenario = load_scenario(CONFIG / "ptc_nominal.yaml")
    roles = roles_of(scenario)
    extra = handshake_overrides(scenario, roles, tmp_path / "bag", CONFIG)["recorder"]
    values = {**node_params(scenario, "recorder"), **extra}
    recorder = RecorderNode(
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
    )
    try:
        on_liveliness = recorder._liveliness("/state")

        def info(alive: int, not_alive: int, alive_change: int, not_alive_change: int) -> Any:
            return SimpleNamespace(
                alive_count=alive,
                not_alive_count=not_alive,
                alive_count_change=alive_change,
                not_alive_count_change=not_alive_change,
            )

        # A restarted producer exits cleanly at the end while the killed
        # one's lapsed writer is still listed: nothing is gone.
        on_liveliness(info(0, 1, -1, 0))
        assert recorder.report.health.fallbacks == [] and not recorder._gone
        # A writer's lease lapses and none is alive: not counted from now on,
        # but not reported yet (a busy host can hold back a lease's renewal).
        on_liveliness(info(0, 1, -1, 1))
        assert "/state" in recorder._gone and recorder.report.health.fallbacks == []
        # Alive again (the lease renewed, or a restart): counted again, and a
        # lapse while another writer is alive changes nothing.
        on_liveliness(info(1, 1, 1, 0))
        on_liveliness(info(1, 2, 0, 1))
        assert not recorder._gone and recorder.lapses_recovered == 1
        # A stream recorded to its last step whose writer then lapses (its
        # producer exiting under load at the end of the run) is not gone.
        on_liveliness(info(0, 1, -1, 0))
        gate = recorder._gates["/state"][1]
        for step in range(recorder._steps):
            gate.accept(step)
        on_liveliness(info(0, 2, 0, 1))
        assert "/state" not in recorder._gone
        # A writer in this process (a composed run) lapses a lease after its
        # last message while it lives: not gone, until it leaves the graph.
        on_streams = recorder._liveliness("/reference")
        producer = Node("feedforward", context=context)
        pub = producer.create_publisher(JointState, "/reference", STREAM_QOS)
        spin_until(
            context, [recorder, producer], lambda: recorder.graph.published_in_process("/reference")
        )
        on_streams(info(0, 1, -1, 1))
        assert "/reference" not in recorder._gone
        producer.destroy_publisher(pub)
        spin_until(
            context,
            [recorder, producer],
            lambda: not recorder.graph.published_in_process("/reference"),
        )
        on_streams(info(0, 1, 0, 1))
        assert "/reference" in recorder._gone and recorder.report.health.fallbacks == []
        # Never alive again by the end of the run: gone, at the step it lapsed.
        recorder.close()
        (gone,) = recorder.report.health.fallbacks
        assert gone.kind == "publisher_gone" and gone.step == 0 and "/reference" in gone.detail
        producer.destroy_node()
    finally:
        recorder.close()
        recorder.destroy_node()


def test_the_recorder_counts_a_plant_clocks_commands_taken_before_their_states(
    context: Context, tmp_path: Path
) -> None:
    """``state_stamps: plant_clock`` (realtime): each command echoes its state's stamp, on
    the plant's own clock. A recorder that fell behind has both queues full and takes them
    in its executor's order: here every command before any state. Each is kept until its
    state comes and counted then; a command whose state never comes is refused."""
    scenario = load_scenario(CONFIG / "ptc_nominal.yaml")
    roles = roles_of(scenario)
    extra = handshake_overrides(scenario, roles, tmp_path / "bag", CONFIG)["recorder"]
    values = {
        **node_params(scenario, "recorder"),
        **extra,
        "mode": "realtime",
        "state_stamps": "plant_clock",
        "wait_for_publishers": False,
        # The two streams of the plant's clock (no reference, /clock, plant/status).
        "topics": ["state", "command", "fault"],
        "types": ["sensor_msgs/msg/JointState"] * 2 + ["std_msgs/msg/Float64MultiArray"],
        "counted_topics": ["state", "command"],
        "latched_topics": ["fault"],
        "final_topics": [""],
        "final_every_steps": [1],
    }
    recorder = RecorderNode(
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
    )
    plant, feedback = Node("plant", context=context), Node("feedback", context=context)
    state_pub = plant.create_publisher(JointState, "state", STREAM_QOS)
    command_pub = feedback.create_publisher(JointState, "command", STREAM_QOS)
    nodes = [recorder, plant, feedback]
    t0 = time.monotonic_ns()  # the plant's own epoch: not on the k T_u grid
    stamps = [t0 + k * PERIOD_NS + (k % 3) * 1000 for k in range(50)]

    def joint(stamp_ns: int, names: list[str], **arrays: list[float]) -> JointState:
        msg = JointState(name=names, **arrays)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
        return msg

    spin_until(
        context,
        nodes,
        lambda: (
            state_pub.get_subscription_count() == 1 and command_pub.get_subscription_count() == 1
        ),
    )
    recorder._check_ready()
    for ns in [*stamps, stamps[-1] + PERIOD_NS // 2]:  # the last one's state never comes
        command_pub.publish(joint(ns, ["x_motor"], effort=[0.1]))
    spin_until(context, nodes, lambda: recorder.message_counts["/command"] == 51)
    assert recorder.recorded == 0 and recorder.report.health.rejected == {}
    for ns in stamps:
        zeros = [0.0, 0.0]
        state_pub.publish(joint(ns, ["x_motor", "x_table"], position=zeros, velocity=zeros,
                                effort=zeros))  # fmt: skip
    spin_until(context, nodes, lambda: recorder.message_counts["/state"] == 50)
    assert recorder.recorded == 50  # every command counted at its state
    state_pub.publish(joint(stamps[-1] + PERIOD_NS, ["x_motor", "x_table"], position=[0.0, 0.0],
                            velocity=[0.0, 0.0], effort=[0.0, 0.0]))  # fmt: skip
    spin_until(context, nodes, lambda: recorder.message_counts["/state"] == 51)
    assert recorder.report.health.rejected == {"command": 1}  # its state never came
    recorder.close()
    for n in nodes:
        n.destroy_node()
