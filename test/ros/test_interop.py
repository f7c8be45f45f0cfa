"""What a ROS 2 user's own node meets: default QoS, any node name (issue 17).

* :func:`matching_reader_qos` against the profiles of rclpy (default,
  sensor data) and of the suite's own publishers;
* every subscription of every node matches a publisher with rclpy's default
  profile (or best effort on a sensor stream) when that is what the topic
  has, whatever the publisher's node is called;
* an ``echo``-like subscriber with the default profile receives every stream
  of a running node graph.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
from graph_support import NODE_CLASSES, graph_nodes, spin_until
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.nodes.runtime import (
    LATCHED_QOS,
    LATCHED_READ_QOS,
    LIVELINESS_LEASE_S,
    STREAM_QOS,
    matching_reader_qos,
)
from servo_axis.params.run_params import handshake_overrides
from servo_axis.params.scenario import load_scenario, node_params, roles_of
from servo_axis.wire import topics

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parents[2] / "config"
DEFAULT = QoSProfile(depth=10)  # rclpy's (and rclcpp's) default: reliable, volatile, no lease
CLASSES: dict[str, Any] = {
    topics.JOINT_STATE: JointState,
    topics.FLOAT64_MULTI_ARRAY: Float64MultiArray,
    topics.CLOCK: Clock,
}


def lease_s(profile: QoSProfile) -> float:
    return profile.liveliness_lease_duration.nanoseconds / 1e9


# -- the profile a reader asks for ----------------------------------------------------


def test_no_publisher_no_profile() -> None:
    assert matching_reader_qos(STREAM_QOS, []) is None


def test_the_suites_own_publisher_gets_a_reader_as_strong_as_before() -> None:
    profile = matching_reader_qos(STREAM_QOS, [STREAM_QOS])
    assert profile is not None
    assert profile.reliability == ReliabilityPolicy.RELIABLE
    assert profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert lease_s(profile) == pytest.approx(LIVELINESS_LEASE_S)
    assert profile.depth == STREAM_QOS.depth


def test_a_default_publisher_gets_a_volatile_reader_without_lease() -> None:
    profile = matching_reader_qos(STREAM_QOS, [DEFAULT])
    assert profile is not None
    assert profile.reliability == ReliabilityPolicy.RELIABLE
    assert profile.durability == DurabilityPolicy.VOLATILE
    # No lease asked for: a reader's lease must not be shorter than a writer's (infinite).
    assert profile.liveliness_lease_duration.nanoseconds == 0
    assert profile.depth == STREAM_QOS.depth


def test_a_sensor_data_publisher_gets_a_best_effort_reader() -> None:
    profile = matching_reader_qos(STREAM_QOS, [qos_profile_sensor_data])
    assert profile is not None
    assert profile.reliability == ReliabilityPolicy.BEST_EFFORT
    assert profile.durability == DurabilityPolicy.VOLATILE


def test_the_strongest_offer_wins_when_both_are_there() -> None:
    """With the suite's own producer on the topic, a default-QoS stranger is not let in."""
    profile = matching_reader_qos(STREAM_QOS, [DEFAULT, STREAM_QOS])
    assert profile is not None
    assert profile.durability == DurabilityPolicy.TRANSIENT_LOCAL


def test_a_volatile_wish_stays_volatile() -> None:
    """A late joiner that asks for no history gets none, whatever is offered."""
    volatile = QoSProfile(depth=50, durability=DurabilityPolicy.VOLATILE)
    profile = matching_reader_qos(volatile, [STREAM_QOS])
    assert profile is not None and profile.durability == DurabilityPolicy.VOLATILE
    assert lease_s(profile) == pytest.approx(LIVELINESS_LEASE_S)


# -- every subscription matches a default-QoS publisher ------------------------------


def subscribed_topics(node: Any, role: str) -> list[str]:
    """The table topics the node subscribes to (the recorder: its list), /clock aside."""
    names = node.values["topics"] if role == "recorder" else node.inputs.topics
    return [n for n in names if n != "/clock"]


@pytest.mark.parametrize(
    ("scenario", "role"),
    [
        ("rptc_detailed", "plant"),
        ("rptc_detailed", "feedback"),
        ("rptc_detailed", "feedforward"),
        ("rptc_detailed", "learning"),
        ("rptc_detailed", "recorder"),
        ("dlpid_tilt_lpf2", "identifier"),
        ("pilc_ref_change_bf", "feedforward"),
    ],
)
def test_every_subscription_matches_a_default_qos_publisher(
    context: Context, tmp_path: Path, scenario: str, role: str
) -> None:
    """The role's node alone, its inputs published by a node of another name with
    rclpy's default profile (best effort on `state`): every one of them is matched."""
    path = CONFIG / f"{scenario}.yaml"
    data = load_scenario(path)
    roles = roles_of(data)
    extra = handshake_overrides(data, roles, tmp_path / "bag", path.parent)[role]
    extra = {
        k: 0 if k.startswith("wait_for_") and "subscribers" in k else v for k, v in extra.items()
    }
    # The node alone, fed by a node of another name, as a user starts it by
    # hand: it takes whoever publishes (a run waits for its own producers).
    extra["wait_for_producers"] = False
    outside = Node("someone_elses_node", context=context)
    node = NODE_CLASSES[role](
        context=context,
        parameter_overrides=[
            Parameter(k, value=v) for k, v in {**node_params(data, role), **extra}.items()
        ],
    )
    inputs = subscribed_topics(node, role)
    assert inputs, "the node subscribes to nothing?"
    pubs = {}
    for name in inputs:
        entry = topics.topic(name)
        qos = qos_profile_sensor_data if name == "state" else DEFAULT
        pubs[name] = outside.create_publisher(CLASSES[entry.type_name], name, qos)
    spin_until(
        context,
        [node, outside],
        lambda: all(p.get_subscription_count() >= 1 for p in pubs.values()),
        timeout_s=10.0,
    )
    for name, pub in pubs.items():
        assert pub.get_subscription_count() == 1, name
    node.destroy_node()
    outside.destroy_node()


# -- an echo with the default profile receives every stream ---------------------------


def test_a_default_qos_echo_receives_every_stream(context: Context, tmp_path: Path) -> None:
    """`ros2 topic echo`-like subscribers (default profile, any name) on every topic a
    run publishes get its messages, while the run goes on as usual."""
    path = CONFIG / "ptc_nominal.yaml"
    data = load_scenario(path)
    data["/**"]["ros__parameters"]["duration_s"] = 0.3
    echo = Node("echo_1234", context=context)
    received: dict[str, int] = {}
    published = [
        t
        for t in topics.TOPICS
        if t.producer in roles_of(data) and t.name != "fault" and not t.enabled_by
    ]
    for t in published:
        received[t.name] = 0
        # A latched topic's late reader asks for the writer's last message, as echo does.
        qos = (
            QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
            if t.qos == "latched"
            else DEFAULT
        )
        echo.create_subscription(
            CLASSES[t.type_name],
            t.name,
            lambda m, n=t.name: received.__setitem__(n, received[n] + 1),
            qos,
        )
    nodes = [*graph_nodes(context, data, tmp_path / "bag", path.parent), echo]
    plant = next(n for n in nodes if type(n).__name__ == "PlantNode")
    spin_until(context, nodes, lambda: plant.done and all(received.values()), timeout_s=60.0)
    assert all(received.values()), received
    assert received["state"] >= 1 and received["command"] >= 1
    for n in nodes:
        n.destroy_node()


def test_latched_profiles_are_what_a_default_reader_can_match() -> None:
    """The offered profiles stay as strong as before: reliable, transient-local."""
    for offered in (STREAM_QOS, LATCHED_QOS, LATCHED_READ_QOS):
        assert offered.reliability == ReliabilityPolicy.RELIABLE
        assert offered.durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert lease_s(offered) == pytest.approx(LIVELINESS_LEASE_S)


# -- a run's node subscribes once its producer publishes, not on a stranger first ---------


@pytest.mark.parametrize(
    ("wait", "external", "made_on_stranger"),
    [(True, [""], False), (False, [""], True), (True, ["plant"], True)],
    ids=["run", "by_hand", "outside_plant"],
)
def test_a_run_node_subscribes_once_its_producer_publishes(
    context: Context, wait: bool, external: list[str], made_on_stranger: bool
) -> None:
    """A stranger publishes ``plant/status`` before the plant exists. With
    ``wait_for_producers`` the feedforward generator makes no reader on it; once a
    node called ``plant`` publishes, the reader is made and matches both. Started by
    hand (false), or with the plant an outside role, the stranger's publisher is
    enough: that is the first publisher seen."""
    data = load_scenario(CONFIG / "ptc_nominal.yaml")
    stranger = Node("junk", context=context)
    stranger_pub = stranger.create_publisher(Float64MultiArray, "plant/status", STREAM_QOS)
    overrides = {
        **node_params(data, "feedforward"),
        "wait_for_producers": wait,
        "external_roles": external,
        "wait_for_reference_subscribers": 0,
    }
    node = NODE_CLASSES["feedforward"](
        context=context,
        parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
    )
    nodes = [node, stranger]
    if made_on_stranger:
        spin_until(context, nodes, lambda: stranger_pub.get_subscription_count() == 1, 10.0)
    else:
        end = time.monotonic() + 1.0
        spin_until(context, nodes, lambda: time.monotonic() > end, 5.0)
        # 1 s: a hundred looks at the graph, which has listed the stranger all along.
        assert stranger.get_publishers_info_by_topic("/plant/status")
        assert stranger_pub.get_subscription_count() == 0
        assert stranger.get_subscriptions_info_by_topic("/plant/status") == []
    plant = Node("plant", context=context)
    plant_pub = plant.create_publisher(Float64MultiArray, "plant/status", STREAM_QOS)
    nodes.append(plant)
    spin_until(
        context,
        nodes,
        lambda: (
            plant_pub.get_subscription_count() == 1 and stranger_pub.get_subscription_count() == 1
        ),
        10.0,
    )
    readers = plant.get_subscriptions_info_by_topic("/plant/status")
    assert [(i.node_name, i.node_namespace) for i in readers] == [("feedforward", "/")]
    for n in nodes:
        n.destroy_node()
