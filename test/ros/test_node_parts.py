"""The parts every node shares, each on a plain rclpy node (no role): inputs, graph watch,
and the base node's last look for strangers."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from graph_support import NODE_CLASSES, spin_until
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.nodes.feedforward import FeedforwardNode
from servo_axis.nodes.graph import GraphWatch
from servo_axis.nodes.inputs import Inputs
from servo_axis.nodes.lockstep import stream_gate
from servo_axis.nodes.runtime import STREAM_QOS
from servo_axis.wire import messages as msgs

pytestmark = pytest.mark.ros

PERIOD_NS = 1_000_000


def state(step: int, angle: float = 0.0) -> JointState:
    return msgs.state_to_msg(
        msgs.StateSample(step, angle, 0.0, 0.0, 0.0, 0.0, 0.0), axis="x", period_ns_=PERIOD_NS
    )


def test_inputs_subscribe_once_published_and_hand_on_only_what_decodes_and_gates(
    context: Context,
) -> None:
    host = Node("feedback", context=context)
    graph = GraphWatch(host, external_roles=(), wait_for_producers=True)
    rejected: list[tuple[str, str]] = []
    inputs = Inputs(host, graph, reject=lambda topic, text: rejected.append((topic, text)))
    taken: list[int] = []
    inputs.subscribe(
        "state",
        lambda m: msgs.state_from_msg(m, axis="x", period_ns_=PERIOD_NS),
        lambda s: taken.append(s.step),
        gate=stream_gate(True, first=0),
    )
    assert inputs.topics == ("state",) and not inputs.matched("state")
    # A stranger publishes first: with wait_for_producers no reader is made on it.
    stranger = Node("junk", context=context)
    stranger.create_publisher(JointState, "state", STREAM_QOS)
    end = time.monotonic() + 0.5
    spin_until(context, [host, stranger], lambda: time.monotonic() > end)
    assert host.count_subscribers("state") == 0 and not inputs.matched("state")
    producer = Node("plant", context=context)
    pub = producer.create_publisher(JointState, "state", STREAM_QOS)
    nodes = [host, stranger, producer]
    spin_until(context, nodes, lambda: inputs.matched("state") and pub.get_subscription_count())
    nan = state(0)
    nan.position = [math.nan, 0.0]
    for m in (nan, state(1), state(0), state(0)):  # NaN, ahead, the next one, stale
        pub.publish(m)
    spin_until(context, nodes, lambda: len(rejected) == 3 and taken == [0])
    assert [t for t, _ in rejected] == ["state"] * 3
    assert all(text.startswith("state rejected: ") for _, text in rejected)
    assert "ahead of the stream" in rejected[1][1] and "stale stamp" in rejected[2][1]
    # A publisher of this process lives while it is in the graph.
    assert inputs.peer_alive("state")
    stranger.destroy_node()
    producer.destroy_publisher(pub)
    nodes = [host, producer]
    spin_until(context, nodes, lambda: not graph.published_in_process("state"))
    spin_until(context, nodes, lambda: not inputs.peer_alive("state"), timeout_s=5.0)
    for n in nodes:
        n.destroy_node()


def test_graph_watch_counts_consumers_and_tells_who_answers(context: Context) -> None:
    host = Node("plant", context=context)
    graph = GraphWatch(host, external_roles=(), wait_for_producers=True)
    state_pub = host.create_publisher(JointState, "state", STREAM_QOS)
    assert graph.consumers_matched(state_pub, "state", 0)  # nobody to wait for
    listener = Node("my_reference_generator", context=context)  # answers state too
    listener.create_subscription(JointState, "state", lambda m: None, STREAM_QOS)
    nodes = [host, listener]
    spin_until(context, nodes, lambda: graph.consumers_matched(state_pub, "state", 1))
    assert not graph.consumers_matched(state_pub, "state", 2)
    assert not graph.answerer_listens("command", "state")  # nobody publishes command
    controller = Node("my_controller", context=context)
    controller.create_publisher(JointState, "command", STREAM_QOS)
    nodes.append(controller)
    end = time.monotonic() + 0.5
    spin_until(context, nodes, lambda: time.monotonic() > end)
    assert not graph.answerer_listens("command", "state")  # it does not listen to state
    controller.create_subscription(JointState, "state", lambda m: None, STREAM_QOS)
    spin_until(context, nodes, lambda: graph.answerer_listens("command", "state"))
    # Two subscribers where two are expected, both of the suite's profile: at once.
    assert graph.consumers_matched(state_pub, "state", 2)
    assert graph.published_in_process("command")
    for n in nodes:
        n.destroy_node()


def test_graph_watch_names_the_strangers_of_a_topic_once(context: Context) -> None:
    host = Node("feedforward", context=context)
    graph = GraphWatch(host, external_roles=(), wait_for_producers=True)
    plant = Node("plant", context=context)
    plant.create_publisher(Float64MultiArray, "plant/status", STREAM_QOS)
    intruder = Node("not_the_plant", context=context)
    intruder.create_publisher(Float64MultiArray, "plant/status", 10)
    nodes = [host, plant, intruder]
    found: list[tuple[str, str, str]] = []

    def look() -> bool:
        found.extend(graph.strangers(["plant/status"]))
        return bool(found)

    spin_until(context, nodes, look)
    ((topic, who, declared),) = found
    assert topic == "plant/status" and who.startswith("/not_the_plant ")
    assert declared == "/plant"
    assert graph.strangers(["plant/status"]) == []  # reported once
    for n in nodes:
        n.destroy_node()


def test_a_stranger_after_the_last_look_at_the_graph_is_reported_when_the_node_closes(
    context: Context,
) -> None:
    """The graph is looked at every STRANGER_CHECK_S; a publisher that joined since
    (a short lockstep run ends within 0.2 s) is still reported: the node looks once
    more when it closes."""
    ff = FeedforwardNode(context=context)
    intruder = Node("not_the_plant", context=context)
    intruder.create_publisher(Float64MultiArray, "plant/status", 10)
    try:
        assert ff.report.health.strangers == {}  # not spun: no periodic look has run
        ff.close()
        whos = [who for found in ff.report.health.strangers.values() for who in found]
        assert any("/not_the_plant " in who for who in whos), ff.report.health.strangers
    finally:
        intruder.destroy_node()
        ff.destroy_node()


@pytest.mark.parametrize("role", sorted(NODE_CLASSES))
def test_no_role_replaces_what_rclpy_keeps_on_its_node(
    context: Context, tmp_path: Path, role: str
) -> None:
    """A role's attribute of the name of one of rclpy's own (``_clock``, ``_publishers``)
    would replace it: the node's clock, its timers or its publishers would break."""
    extra = {"output_dir": str(tmp_path / "bag")} if role == "recorder" else {}
    node = NODE_CLASSES[role](
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in extra.items()]
    )
    plain = Node(f"plain_{role}", context=context)
    try:
        replaced = {
            name: type(vars(node)[name]).__name__
            for name, value in vars(plain).items()
            if type(vars(node)[name]) is not type(value)
        }
        assert replaced == {}
    finally:
        node.destroy_node()
        plain.destroy_node()
