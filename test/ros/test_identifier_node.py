"""Paper 003's identifier node and the feedforward's adaptive side, in one process.

What the nodes compute is compared with plain calls: the node graph of a
shortened ``dlpid_tilt_lpf2`` with :func:`servo_axis.simulate.simulate_identification`,
a lone :class:`IdentifierNode` with a core :class:`~servo_axis.core.identification.online.dlpid.Dlpid`
(:func:`~servo_axis.params.factories.build_identifier`) fed the same numbers,
a lone :class:`FeedforwardNode` with a core generator
(:func:`~servo_axis.params.factories.build_generator`).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from graph_support import graph_nodes, spin_until
from numpy.testing import assert_array_equal
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.core.drive import torque_from_current
from servo_axis.core.errors import ParameterFileError
from servo_axis.core.identification.online.dlpid import Estimate
from servo_axis.nodes.feedforward import FeedforwardNode
from servo_axis.nodes.identifier import IdentifierNode
from servo_axis.nodes.plant import PlantNode
from servo_axis.nodes.recorder import RecorderNode
from servo_axis.nodes.runtime import STREAM_QOS
from servo_axis.params.factories import build_generator, build_identifier, checked_values
from servo_axis.params.resolve import node_values
from servo_axis.params.scenario import load_scenario, node_params, roles_of
from servo_axis.recording.deserialize import read_messages
from servo_axis.simulate import simulate_identification
from servo_axis.storage import load_identifier_memory
from servo_axis.wire import messages as msgs

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parents[2] / "config"
SCENARIO = CONFIG / "dlpid_tilt_lpf2.yaml"
AXIS = "tilt"
TU = 4e-4
PERIOD_NS = 400_000  # T_u = 0.4 ms
R = 10  # T_RLS / T_u = 4 ms / 0.4 ms
LATENCY = 10  # latency_s / T_u
STEPS = 1000  # the shortened run: 0.4 s
#: The PD filters' double pole for the lone identifier: at the scenario's
#: 20 Hz the layers wait 239 samples (warm-up) and every estimate of the
#: first few RLS periods would be the initial one whatever came in; at
#: 600 Hz they run from step 8 on, so each estimate depends on the input.
FAST_PD_HZ = 600.0


def spin_for(ctx: Context, nodes: list[Node], seconds: float) -> None:
    deadline = time.monotonic() + seconds
    spin_until(ctx, nodes, lambda: time.monotonic() > deadline)


def destroy(nodes: list[Node]) -> None:
    for n in nodes:
        n.destroy_node()


def short_lpf2(tmp_path: Path, seconds: float = STEPS * TU) -> tuple[dict[str, Any], Path]:
    """``dlpid_tilt_lpf2`` cut to ``seconds``, as data and as a file in ``tmp_path``."""
    data = load_scenario(SCENARIO)
    data["/**"]["ros__parameters"]["duration_s"] = seconds
    path = tmp_path / "dlpid_tilt_lpf2_short.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return data, path


def parameters(values: dict[str, Any]) -> list[Parameter]:
    # An empty list has no ROS parameter type; the node leaves those at their default.
    return [Parameter(k, value=v) for k, v in values.items() if not (isinstance(v, list) and not v)]


# -- 1. the node graph against the plain calls -------------------------------------------


def test_identification_graph_equals_the_plain_call_loop(context: Context, tmp_path: Path) -> None:
    """Plant, feedback, adaptive feedforward, identifier and recorder in one process
    record the state, command and estimates of :func:`simulate_identification`, bit for bit."""
    data, path = short_lpf2(tmp_path)
    roles = roles_of(data)
    assert roles == ["recorder", "identifier", "feedforward", "feedback", "plant"]
    bag = tmp_path / "bag"
    nodes = graph_nodes(context, data, bag, path.parent)
    recorder, identifier, ff, plant = nodes[0], nodes[1], nodes[2], nodes[-1]
    assert isinstance(recorder, RecorderNode) and isinstance(plant, PlantNode)
    assert isinstance(identifier, IdentifierNode) and isinstance(ff, FeedforwardNode)
    try:
        spin_until(context, nodes, lambda: plant.done, timeout_s=60)
        counts = recorder.message_counts
    finally:
        recorder.close()
        destroy(nodes)
    core = simulate_identification(path)
    n_estimates = (STEPS - 1 - LATENCY) // R  # those applying inside the run: steps 9 .. 979
    assert core.estimates.shape == (n_estimates, 11)
    for topic in ("/state", "/command", "/reference"):
        assert counts[topic] == STEPS, topic
    state: dict[int, float] = {}
    command: dict[int, float] = {}
    reference: dict[int, float] = {}
    estimates: list[list[float]] = []
    for m in read_messages(bag):
        if m.topic == "/identifier/estimates":
            estimates.append(msgs.estimate_from_msg(m.message).values())
            continue
        if m.topic not in ("/state", "/command", "/reference"):
            continue
        k = msgs.step_from_stamp(m.message.header.stamp, PERIOD_NS)
        if m.topic == "/state":
            state[k] = m.message.position[0]
        elif m.topic == "/command":
            command[k] = m.message.effort[0]
        else:
            reference[k] = m.message.position[0]
    assert sorted(state) == sorted(command) == sorted(reference) == list(range(STEPS))
    assert_array_equal([state[k] for k in range(STEPS)], core.trajectory.encoder_rad)
    assert_array_equal([command[k] for k in range(STEPS)], core.trajectory.command_Nm)
    assert_array_equal([reference[k] for k in range(STEPS)], core.trajectory.reference_rad)
    # Every estimate, in the order published, with its schedule and flags.
    assert_array_equal(np.array(estimates).reshape(-1, 11), core.estimates)
    assert identifier.published == n_estimates and ff.estimates.taken == n_estimates
    assert (
        identifier.report.rejected == 0 and ff.report.rejected == 0 and plant.report.rejected == 0
    )
    assert not ff.report.health.fallbacks and not plant.report.health.fallbacks
    # The run is not trivial: J, D, U and C were updated along it and moved.
    assert core.estimates[:, 7:].sum(axis=0).min() > 0
    assert abs(core.estimates[-1, 2] - 0.002) > 1e-3  # J from the nominal 0.002 kg m^2
    # The runner's memory file holds the last estimate.
    state_saved, last = load_identifier_memory(
        tmp_path / "identifier_memory.json", method="dlpid", scenario="dlpid_tilt_lpf2"
    )
    assert_array_equal(last, core.estimates[-1])
    assert state_saved["last_step"] == core.estimates[-1, 0]


# -- 2. the feedforward refuses bad estimates ---------------------------------------------


def references_heard(probe: Node) -> list[msgs.ReferenceSample]:
    """The ``reference`` samples ``probe`` hears, in order (a list that grows as it spins)."""
    refs: list[msgs.ReferenceSample] = []
    probe.create_subscription(
        JointState,
        "reference",
        lambda m: refs.append(msgs.reference_from_msg(m, axis=AXIS, period_ns_=PERIOD_NS)),
        STREAM_QOS,
    )
    return refs


def as_references(samples: list[tuple[float, float, float]], kt: float) -> np.ndarray:
    """A core generator's ``(r, r', u_ff)`` as the wire's ``(r, r', K_T u_ff)`` rows."""
    out = np.array(samples)
    out[:, 2] = torque_from_current(out[:, 2], torque_constant_Nm_per_A=kt)
    return out


def rows_of(refs: list[msgs.ReferenceSample]) -> np.ndarray:
    """``(position, velocity, torque)`` rows of heard reference samples."""
    return np.array([(r.position_rad, r.velocity_rad_s, r.torque_Nm) for r in refs])


def estimate_msg(
    step: int, applies: int, *, j: float = 4e-3, d: float = 1.2e-2, u: float = 0.25, c: float = 0.02
) -> Float64MultiArray:
    return msgs.estimate_to_msg(
        msgs.EstimateData(
            step=step,
            applies_from_step=applies,
            inertia_kgm2=j,
            damping_Nms_per_rad=d,
            unbalance_Nm=u,
            coulomb_Nm=c,
            kappa=0.5,
            updated=(True, True, False, True),
        )
    )


def test_feedforward_rejects_bad_estimates_and_takes_a_repeat_silently(
    context: Context, tmp_path: Path
) -> None:
    data, _ = short_lpf2(tmp_path)
    values = node_values(data, "feedforward")
    assert values["adaptive.enabled"] and values["preview_steps"] == 200
    ff = FeedforwardNode(context=context, parameter_overrides=parameters(values))
    probe = Node("identifier", context=context)  # the producer, by name
    pub = probe.create_publisher(Float64MultiArray, "identifier/estimates", STREAM_QOS)
    refs = references_heard(probe)
    nodes = [ff, probe]
    first = R + LATENCY  # the first estimate (from step R - 1) applies from 20
    try:
        assert ff.generator.next_estimate_step == first
        spin_until(
            context,
            nodes,
            lambda: (
                pub.get_subscription_count() >= 1 and ff.published == first and len(refs) == first
            ),
        )
        # NaN (the encoder refuses it: by hand), a short array, wrong labels
        nan = estimate_msg(R - 1, first)
        nan.data = [math.nan if i == 2 else v for i, v in enumerate(nan.data)]
        short = estimate_msg(R - 1, first)
        short.data = list(short.data)[:-1]
        labels = list(msgs.ESTIMATE_LABELS)
        labels[2], labels[3] = labels[3], labels[2]
        wrong_labels = msgs.labelled_array(labels, estimate_msg(R - 1, first).data)
        bad = [
            nan,
            short,
            wrong_labels,
            estimate_msg(first, first),  # applies_from_step <= step
            estimate_msg(R - 2, first),  # the next application step, but not on the schedule
            estimate_msg(2 * R - 1, first + R),  # the period after the next: out of order
            estimate_msg(R - 1, first, j=0.0),  # J = 0
        ]
        for m in bad:
            pub.publish(m)
        spin_until(context, nodes, lambda: ff.report.rejected >= len(bad))
        spin_for(context, nodes, 0.2)  # nothing may still come of them
        assert ff.report.rejected == len(bad)
        assert ff.report.health.rejected == {"identifier/estimates": len(bad)}
        assert ff.estimates.taken == 0 and ff.estimates.last is None
        assert ff.generator.next_estimate_step == first
        assert ff.published == first and max(r.step for r in refs) == first - 1
        # The next estimate, valid: taken, and the preview moves on to the next one.
        good = estimate_msg(R - 1, first)
        pub.publish(good)
        spin_until(context, nodes, lambda: ff.estimates.taken == 1 and len(refs) == first + R)
        assert ff.generator.next_estimate_step == first + R
        assert ff.estimates.last == msgs.estimate_from_msg(good)
        assert ff.published == first + R and ff.report.rejected == len(bad)
        assert [r.step for r in refs] == list(range(first + R))
        # The samples from step 20 on are computed with the estimate: those of a
        # core generator given it.
        core = build_generator(values)
        core.set_estimate(
            first, inertia_kgm2=4e-3, damping_Nms_per_rad=1.2e-2, unbalance_Nm=0.25, coulomb_Nm=0.02
        )
        kt = values["nominal.torque_constant_Nm_per_A"]
        expected = as_references(core.samples(0, first + R), kt)
        assert_array_equal(rows_of(refs), expected)
        before = build_generator(values)
        before.set_estimate(
            first, inertia_kgm2=2e-3, damping_Nms_per_rad=1e-2, unbalance_Nm=0.1, coulomb_Nm=0.01
        )
        assert not np.array_equal(np.array(before.samples(0, first + R))[first:], expected[first:])
        # An exact repeat (a restarted identifier's) is taken silently: neither
        # rejected nor taken again. The next estimate, sent after it on the same
        # reliable stream, tells that it has been handled.
        pub.publish(good)
        pub.publish(estimate_msg(2 * R - 1, first + R, u=0.3))
        spin_until(context, nodes, lambda: ff.estimates.taken >= 2 and len(refs) == first + 2 * R)
        assert ff.report.rejected == len(bad) and ff.estimates.taken == 2
        assert ff.generator.next_estimate_step == first + 2 * R
        assert ff.published == first + 2 * R
    finally:
        destroy(nodes)


@pytest.mark.realtime
def test_realtime_feedforward_goes_on_without_an_estimate_once_its_samples_are_due(
    context: Context, tmp_path: Path
) -> None:
    """Realtime: an estimate is waited for until its samples are due by the plant's
    clock (plant/status); then the samples go out with the model in force, and the
    late estimate applies from the next sample not yet published (late_estimates)."""
    data, _ = short_lpf2(tmp_path)
    values = {**node_values(data, "feedforward"), "mode": "realtime", "thread_priority": 0}
    ff = FeedforwardNode(context=context, parameter_overrides=parameters(values))
    probe = Node("plant", context=context)
    status = probe.create_publisher(Float64MultiArray, "plant/status", STREAM_QOS)
    est = probe.create_publisher(Float64MultiArray, "identifier/estimates", STREAM_QOS)
    refs = references_heard(probe)
    nodes = [ff, probe]
    first = R + LATENCY
    kt = values["nominal.torque_constant_Nm_per_A"]

    try:
        spin_until(
            context,
            nodes,
            lambda: (
                status.get_subscription_count() >= 1
                and est.get_subscription_count() >= 1
                and len(refs) == first
            ),
        )
        # Before the plant says where its clock is, the first estimate is waited for.
        spin_for(context, nodes, 0.2)
        assert ff.published == first and len(refs) == first
        # The plant at step 150: the estimates up to there are due and none has
        # come; the window (200) goes out with the initial model as it falls due.
        status.publish(msgs.labelled_array(msgs.STATUS_LABELS, [150, 0, 0, 0]))
        spin_until(context, nodes, lambda: len(refs) == 350)
        spin_for(context, nodes, 0.1)
        assert ff.published == 350 and len(refs) == 350
        assert ff.estimates.taken == 0 and ff.estimates.late == 0 and not ff.report.health.fallbacks
        core = build_generator(values)
        core.stop_waiting_for_estimates()
        assert_array_equal(rows_of(refs[:350]), as_references(core.samples(0, 350), kt))
        # The first estimate, late: from sample 350 on.
        est.publish(estimate_msg(R - 1, first))
        spin_until(context, nodes, lambda: ff.estimates.taken == 1)
        assert ff.estimates.late == 1 and ff.generator.next_estimate_step == first + R
        # The plant at 250 (half the window used): the next samples follow.
        status.publish(msgs.labelled_array(msgs.STATUS_LABELS, [250, 0, 0, 0]))
        spin_until(context, nodes, lambda: len(refs) >= 400)
        applied = core.set_estimate(
            first, inertia_kgm2=4e-3, damping_Nms_per_rad=1.2e-2, unbalance_Nm=0.25, coulomb_Nm=0.02
        )
        assert applied == 350
        with_estimate = as_references(core.samples(350, 400), kt)
        assert_array_equal(rows_of(refs[350:400]), with_estimate)
        without = build_generator(values)
        without.stop_waiting_for_estimates()
        assert not np.array_equal(as_references(without.samples(0, 400), kt)[350:], with_estimate)
        assert ff.report.rejected == 0 and not ff.report.health.fallbacks
    finally:
        destroy(nodes)


# -- the lone identifier against a core Dlpid ----------------------------------------------


#: The nominal torque constant of the feeder's commands (N m/A).
FEEDER_KT = 0.8


def identifier_values(data: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """The identifier section of the scenario, with the fast PD filters and ``extra``.

    The nominal ``K_T`` is not 1 here: the feeder publishes the torque ``K_T i``
    a feedback with it would, and a current taken for the torque would show.
    """
    return {
        **node_params(data, "identifier"),
        "pd_cutoff_hz": FAST_PD_HZ,
        "nominal.torque_constant_Nm_per_A": FEEDER_KT,
        **extra,
    }


def sample(k: int) -> tuple[float, float]:
    """Angle (rad) and current (A) of step ``k``: above every condition of eq. (16)."""
    phase = 2 * math.pi * 25 * k * TU
    return 0.5 + 0.2 * math.sin(phase), 0.1 + 0.3 * math.cos(phase)


class Feeder(Node):
    """Publishes state and command as the plant and the feedback would; collects estimates."""

    def __init__(self, context: Context) -> None:
        super().__init__("feeder", context=context)
        self.state_pub = self.create_publisher(JointState, "state", STREAM_QOS)
        self.command_pub = self.create_publisher(JointState, "command", STREAM_QOS)
        self.estimates: list[msgs.EstimateData] = []
        self.create_subscription(
            Float64MultiArray,
            "identifier/estimates",
            lambda m: self.estimates.append(msgs.estimate_from_msg(m)),
            STREAM_QOS,
        )

    def matched(self) -> bool:
        return (
            self.state_pub.get_subscription_count() >= 1
            and self.command_pub.get_subscription_count() >= 1
        )

    def state(self, k: int, angle: float | None = None) -> JointState:
        y = sample(k)[0] if angle is None else angle
        return msgs.state_to_msg(
            msgs.StateSample(k, y, y, 0.0, 0.0, 0.0, 0.0), axis=AXIS, period_ns_=PERIOD_NS
        )

    def command(self, k: int, current: float | None = None) -> JointState:
        """``command[k]``: the motor torque reference ``K_T i`` of the current ``i`` (A)."""
        i = sample(k)[1] if current is None else current
        torque = torque_from_current(i, torque_constant_Nm_per_A=FEEDER_KT)
        return msgs.command_to_msg(msgs.CommandSample(k, torque), axis=AXIS, period_ns_=PERIOD_NS)

    def send(self, steps: range) -> None:
        for k in steps:
            self.state_pub.publish(self.state(k))
            self.command_pub.publish(self.command(k))


def core_estimates(values: dict[str, Any], steps: range) -> tuple[list[Estimate], Any]:
    """A core identifier of ``values`` fed :func:`sample` at ``steps``: its estimates, itself."""
    core = build_identifier(checked_values("identifier", values))
    assert values["nominal.torque_constant_Nm_per_A"] == FEEDER_KT
    out = []
    for k in steps:
        y, i = sample(k)
        e = core.update(k, y, FEEDER_KT * i)
        if e is not None:
            out.append(e)
    return out, core


def as_message_values(e: Estimate) -> list[float]:
    applies = e.step + 1 + LATENCY
    return [e.step, applies, e.J, e.D, e.U, e.C, e.kappa, *map(float, e.updated)]


# -- 3. input validation -------------------------------------------------------------------


def test_identifier_rejects_bad_samples_and_estimates_from_the_valid_ones(
    context: Context, tmp_path: Path
) -> None:
    data, _ = short_lpf2(tmp_path)
    values = identifier_values(data)
    node = IdentifierNode(context=context, parameter_overrides=parameters(values))
    feeder = Feeder(context)
    nodes = [node, feeder]
    try:
        spin_until(context, nodes, lambda: node.inputs_subscribed and feeder.matched())
        feeder.send(range(5))
        spin_until(context, nodes, lambda: node.identifier.last_step == 4)
        nan = feeder.state(5)
        nan.position = [math.nan, 0.5]
        short = feeder.command(5)
        short.effort = []
        bad_states = [
            nan,
            feeder.state(3, angle=0.9),  # stale: behind the stream
            feeder.state(7, angle=0.9),  # stamped ahead of the stream
            feeder.state(10**9, angle=0.9),  # beyond the run
        ]
        bad_commands = [
            short,
            feeder.command(4, current=5.0),  # stale
            feeder.command(6, current=5.0),  # ahead
        ]
        for m in bad_states:
            feeder.state_pub.publish(m)
        for m in bad_commands:
            feeder.command_pub.publish(m)
        n_bad = len(bad_states) + len(bad_commands)
        spin_until(context, nodes, lambda: node.report.rejected >= n_bad)
        spin_for(context, nodes, 0.1)
        assert node.report.rejected == n_bad
        assert node.report.health.rejected == {
            "state": len(bad_states),
            "command": len(bad_commands),
        }
        assert node.identifier.last_step == 4 and node.published == 0 and not feeder.estimates
        feeder.send(range(5, R))
        spin_until(context, nodes, lambda: len(feeder.estimates) >= 1)
        spin_for(context, nodes, 0.2)  # one estimate, no other
        (got,) = feeder.estimates
        expected, core = core_estimates(values, range(R))
        (e,) = expected
        assert e.step == R - 1 and e.updated == (True, True, True, True)
        assert_array_equal(got.values(), as_message_values(e))
        assert node.last_estimate == got and node.published == 1 and node.report.rejected == n_bad
        assert node.identifier.state() == core.state()
        # The estimate depends on the samples: U moved off its initial 0.1.
        assert e.U != values["initial.unbalance_Nm"]
    finally:
        destroy(nodes)


# -- 4. bad parameters --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("key", "value"),
    [("forgetting", [1.5, 0.9, 0.9]), ("latency_s", 0.0008), ("pe_window", 2)],
)
def test_identifier_refuses_a_bad_parameter_before_it_publishes(
    context: Context, tmp_path: Path, key: str, value: Any
) -> None:
    """The constructor raises naming the key, and no identifier/estimates publisher is
    left in the graph (a valid node's shows at once: the check can see one)."""
    data, _ = short_lpf2(tmp_path)
    given = node_params(data, "identifier")
    observer = Node("observer", context=context)
    nodes: list[Node] = [observer]

    def publishers() -> int:
        return observer.count_publishers("identifier/estimates")

    try:
        good = IdentifierNode(context=context, parameter_overrides=parameters(given))
        nodes.append(good)
        spin_until(context, [observer], lambda: publishers() == 1)
        nodes.remove(good)
        good.destroy_node()
        spin_until(context, [observer], lambda: publishers() == 0)
        with pytest.raises(ParameterFileError, match=rf"^parameter '{key}': "):
            IdentifierNode(context=context, parameter_overrides=parameters({**given, key: value}))
        spin_for(context, [observer], 0.2)
        assert publishers() == 0
    finally:
        destroy(nodes)


# -- 5. resume from the memory file ---------------------------------------------------------


def test_a_restarted_identifier_resumes_bit_identically_from_its_memory(
    context: Context, tmp_path: Path
) -> None:
    data, _ = short_lpf2(tmp_path)
    memory = tmp_path / "identifier_memory.json"
    values = identifier_values(data, **{"memory.file": str(memory)})
    expected, core = core_estimates(values, range(3 * R))
    assert [e.step for e in expected] == [R - 1, 2 * R - 1, 3 * R - 1]
    # Each one differs from the one before: a resume from the wrong point shows.
    assert len({(e.J, e.U, e.C) for e in expected}) == 3
    feeder = Feeder(context)
    first = IdentifierNode(context=context, parameter_overrides=parameters(values))
    try:
        spin_until(context, [first, feeder], lambda: first.inputs_subscribed and feeder.matched())
        feeder.send(range(2 * R))
        spin_until(context, [first, feeder], lambda: len(feeder.estimates) >= 2)
        assert first.identifier.last_step == 2 * R - 1
    finally:
        first.destroy_node()
    assert_array_equal(
        [e.values() for e in feeder.estimates], [as_message_values(e) for e in expected[:2]]
    )
    saved_state, saved_last = load_identifier_memory(
        memory, method="dlpid", scenario="dlpid_tilt_lpf2"
    )
    assert saved_state["last_step"] == 2 * R - 1
    assert_array_equal(saved_last, as_message_values(expected[1]))
    # While it is down the stream goes on (into the feeder's history, which
    # also holds samples 0 .. 2R-1 the restarted one must skip).
    feeder.send(range(2 * R, 2 * R + 5))
    second = IdentifierNode(
        context=context, parameter_overrides=parameters({**values, "late_join": True})
    )
    nodes = [second, feeder]
    try:
        assert second.identifier.last_step == 2 * R - 1
        assert second.last_estimate is not None
        assert_array_equal(second.last_estimate.values(), as_message_values(expected[1]))
        # It publishes its last estimate again on start.
        spin_until(context, nodes, lambda: len(feeder.estimates) >= 3)
        assert feeder.estimates[2] == feeder.estimates[1]
        spin_until(context, nodes, lambda: second.identifier.last_step == 2 * R + 4)
        feeder.send(range(2 * R + 5, 3 * R))
        spin_until(context, nodes, lambda: len(feeder.estimates) >= 4)
        spin_for(context, nodes, 0.1)
        assert len(feeder.estimates) == 4
        assert_array_equal(feeder.estimates[3].values(), as_message_values(expected[2]))
        assert second.identifier.state() == core.state()
        # The history it already had is skipped, not rejected.
        assert second.report.rejected == 0 and second.published == 1
    finally:
        destroy(nodes)
    # A fresh start (not late_join) with that memory on disk starts at step 0
    # and ignores it: a state is the middle of a run.
    fresh = IdentifierNode(context=context, parameter_overrides=parameters(values))
    try:
        assert fresh.identifier.last_step is None and fresh.last_estimate is None
    finally:
        fresh.destroy_node()


# -- 5. realtime: a command that never comes ------------------------------------------------


@pytest.mark.realtime
def test_realtime_identifier_holds_the_last_torque_for_a_command_that_never_comes(
    context: Context, tmp_path: Path
) -> None:
    """The feedback skips answering a state it is too late for (or a command is lost):
    the plant holds the last current, as a drive does, and so does the identifier,
    instead of waiting for the missing step for the rest of the run."""
    data, _ = short_lpf2(tmp_path)
    values = identifier_values(data, mode="realtime", thread_priority=0)
    node = IdentifierNode(context=context, parameter_overrides=parameters(values))
    feeder = Feeder(context)
    nodes = [node, feeder]
    missing = 3
    try:
        spin_until(context, nodes, lambda: node.inputs_subscribed and feeder.matched())
        for k in range(R):
            feeder.state_pub.publish(feeder.state(k))
            if k != missing:
                feeder.command_pub.publish(feeder.command(k))
        spin_until(context, nodes, lambda: len(feeder.estimates) >= 1)
        assert node.held_torques == 1
        # The estimate is the core's with step 3's current replaced by step 2's.
        core = build_identifier(checked_values("identifier", values))
        estimates = []
        for k in range(R):
            y = sample(k)[0]
            e = core.update(k, y, FEEDER_KT * sample(k - 1 if k == missing else k)[1])
            if e is not None:
                estimates.append(e)
        expected = estimates[0]
        assert_array_equal(feeder.estimates[0].values(), as_message_values(expected))
    finally:
        destroy(nodes)
