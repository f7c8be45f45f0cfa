"""The base of every node: strict parameters and one way to take messages in.

* Parameters: every key the node was given (parameter file, ``-p``,
  ``parameter_overrides``) is checked against the node's schema
  (:func:`servo_axis.params.factories.checked_values`): an unknown key, a
  wrong type, NaN/inf or a value out of range raises
  :class:`ParameterFileError` naming the full key, in the constructor,
  before any publisher exists. The given keys are read through public rclpy
  API (``automatically_declare_parameters_from_overrides``); then every key
  of the schema is declared (the rest with its default) with a read-only
  descriptor made from the schema (:mod:`servo_axis.nodes.parameters`:
  meaning, unit, range), so that ``ros2 param describe`` shows it and a
  ``ros2 param set`` while running is refused with a reason.
* Input: :meth:`ServoNode.subscribe` decodes and validates each message
  with a pure function of :mod:`servo_axis.wire.messages` before the
  node's handler sees it; a message that fails is dropped, counted
  (``rejected``) and logged (throttled): nothing derived from it is
  published.
* Streams: a per-sample subscription may take a
  :class:`~servo_axis.wire.streams.StreamGate`; its stamp is checked after
  the payload is validated and before the handler sees it, so a message
  ahead of or behind the stream never displaces it.
* Peers: every subscription follows its publishers' liveliness
  (:data:`~servo_axis.nodes.runtime.LIVELINESS_LEASE_S`);
  :meth:`ServoNode.peer_alive` is what a lockstep node asks before it falls
  back (it never does on a wall-clock timeout while its peer lives), and
  :meth:`ServoNode.fallback` records that it did.
* Strangers: twice a second each subscribed topic's publishers are compared,
  through the ROS graph, with the one the run started (the table's
  producer, in this node's namespace); any other is logged and reported.
* Handshake: :meth:`ServoNode.consumers_matched` tells whether a
  publisher's expected consumers (the table's consumers and the recorder)
  are matched, not only how many subscribers there are, so that a stranger
  subscribed to the topic does not stand in for a peer that is still being
  discovered.
* Report: :mod:`servo_axis.wire.health`, written to ``report_dir`` on each
  fallback, on each new stranger and when the node closes.
* Diagnostics: about once a second of wall time and when it closes, a
  ``DiagnosticArray`` on ``/diagnostics`` (:mod:`servo_axis.nodes.diagnostics`):
  the report above with a level, and what :meth:`ServoNode.diagnostic_values`
  adds.
* QoS and message types come from the topic table (:mod:`servo_axis.wire.topics`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Protocol, TypeVar

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from servo_axis.core.errors import SignalError
from servo_axis.nodes.diagnostics import (
    DIAGNOSTICS_PERIOD_S,
    DIAGNOSTICS_TOPIC,
    Status,
    diagnostic_array,
    node_status,
)
from servo_axis.nodes.parameters import descriptor
from servo_axis.nodes.runtime import (
    LATCHED_QOS,
    LATCHED_READ_QOS,
    STREAM_QOS,
    Throttle,
    steady_clock,
)
from servo_axis.params.factories import checked_values, node_schema
from servo_axis.params.schema import BUILTIN, Param
from servo_axis.wire import topics
from servo_axis.wire.health import Fallback, NodeHealth, write_health
from servo_axis.wire.streams import StreamGate


class Stamped(Protocol):
    step: int


T = TypeVar("T")

#: The node name the ROS graph gives an endpoint whose node it has not learnt yet.
UNKNOWN_NODE_NAME = "_NODE_NAME_UNKNOWN_"
#: Seconds between two looks at the graph for strangers.
STRANGER_CHECK_S = 0.5
#: Seconds a second endpoint of the producer's own name may stay in the graph
#: before it counts as a stranger: longer than the participant lease (5 s) of
#: a dead node replaced by a restarted one.
TWIN_GRACE_S = 7.0
#: Seconds the expected consumers of a topic must have been matched when a
#: stranger subscriber makes the matched count ambiguous (see
#: :meth:`ServoNode.consumers_matched`).
MATCH_SETTLE_S = 0.5

QOS: dict[str, QoSProfile] = {"stream": STREAM_QOS, "latched": LATCHED_QOS}
#: What the subscriptions ask for (a deep queue on latched topics too).
READER_QOS: dict[str, QoSProfile] = {"stream": STREAM_QOS, "latched": LATCHED_READ_QOS}
MESSAGE_CLASSES: dict[str, Any] = {
    topics.JOINT_STATE: JointState,
    topics.FLOAT64_MULTI_ARRAY: Float64MultiArray,
    topics.CLOCK: Clock,
}


def topic_qos(name: str) -> QoSProfile:
    """The QoS profile of a topic of the table (its publisher's)."""
    return QOS[topics.topic(name).qos]


def reader_qos(name: str) -> QoSProfile:
    """The QoS profile a subscription to a topic of the table asks for."""
    return READER_QOS[topics.topic(name).qos]


class ServoNode(Node):
    """A node of the suite: checked parameters in :attr:`values`, validated input.

    Parameters
    ----------
    role : str
        The node's name and schema (``plant``, ``feedback``, ...).
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ...).
    """

    def __init__(self, role: str, **kwargs: Any) -> None:
        super().__init__(
            role,
            automatically_declare_parameters_from_overrides=True,
            **kwargs,
        )
        given = {
            name: _plain(self.get_parameter(name).value)
            for name in self.list_parameters([], 0).names
            if name not in BUILTIN
        }
        self.values: dict[str, Any] = checked_values(role, given)
        self._describe_parameters(node_schema(role, given), set(given))
        self.rejected = 0
        self.health = NodeHealth(role)
        self._report_dir = Path(self.values["report_dir"]) if self.values["report_dir"] else None
        self._complain = Throttle()
        self._alive: dict[str, int] = {}
        self._lapsed: dict[str, int] = {}
        self._subscriptions_by_topic: dict[str, Subscription] = {}
        self._watched: list[str] = []
        self._stranger_gids: set[str] = set()
        self._twin_looks: dict[str, dict[str, int]] = {}
        self._matched_since: dict[str, float] = {}
        self._prefix: bytes | None = None
        self.create_timer(STRANGER_CHECK_S, self._check_strangers, clock=steady_clock())
        # Default QoS (reliable, volatile, keep-last 10), as ROS's diagnostics tools use.
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 10)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self.publish_diagnostics, clock=steady_clock())

    def _describe_parameters(self, schema: Mapping[str, Param], given: set[str]) -> None:
        """Declare every schema key with its descriptor (read-only) and its checked value.

        The given keys were declared from the overrides without a descriptor:
        they get theirs now, with the checked value (an integer given for a
        number becomes that number). The others are declared with their
        default; an empty list, whose type rclpy cannot infer, is declared by
        its type (its value is then not set).
        """
        for name, param in schema.items():
            desc = descriptor(name, param)
            value = Parameter(name, Parameter.Type(desc.type), self.values[name])
            if name in given:
                self.set_descriptor(name, desc, value.get_parameter_value())
            elif isinstance(self.values[name], list) and not self.values[name]:
                self.declare_parameter(name, Parameter.Type(desc.type), desc)
            else:
                self.declare_parameter(name, value.value, desc, ignore_override=True)

    def publisher(self, name: str) -> Publisher:
        """A publisher of table topic ``name`` with its type and QoS."""
        entry = topics.topic(name)
        return self.create_publisher(MESSAGE_CLASSES[entry.type_name], name, QOS[entry.qos])

    def subscribe(
        self,
        name: str,
        decode: Callable[[Any], T],
        handle: Callable[[T], None],
        *,
        raw: bool = False,
        gate: StreamGate | None = None,
        qos: QoSProfile | None = None,
    ) -> Subscription:
        """Subscribe to table topic ``name``: ``handle(decode(msg))`` for the valid ones.

        ``decode`` raises :class:`SignalError` for a message that must not be
        used (wrong length, names, NaN/inf, stamp); it is then rejected here.
        With a ``gate``, the decoded sample's ``step`` must be one the gate
        takes (it is checked after decoding, so a junk message never moves
        the gate); a ``decode`` that returns None for a message it skips
        leaves the gate alone. ``qos`` replaces the table's profile (a late
        joiner that wants no history).
        """
        entry = topics.topic(name)

        def on_message(msg: Any) -> None:
            try:
                sample = decode(msg)
                if gate is not None and sample is not None:
                    gate.accept(sample.step)  # type: ignore[attr-defined]
            except SignalError as err:
                self.reject(name, f"{name} rejected: {err}")
                return
            handle(sample)

        def on_liveliness(info: Any) -> None:
            self._alive[name] = info.alive_count
            self._lapsed[name] = info.not_alive_count

        self._alive.setdefault(name, 0)
        self._lapsed.setdefault(name, 0)
        if name not in self._watched:
            self._watched.append(name)
        subscription = self.create_subscription(
            MESSAGE_CLASSES[entry.type_name],
            name,
            on_message,
            READER_QOS[entry.qos] if qos is None else qos,
            raw=raw,
            event_callbacks=SubscriptionEventCallbacks(liveliness=on_liveliness),
        )
        self._subscriptions_by_topic[name] = subscription
        return subscription

    def reject(self, topic_name: str, text: str) -> None:
        """Count a dropped message of ``topic_name`` and log it (at most once a second)."""
        self.rejected += 1
        self.health.rejected[topic_name] = self.health.rejected.get(topic_name, 0) + 1
        if self._complain.ready():
            self.get_logger().warning(f"{text} ({self.rejected} rejected so far)")

    # -- peers -------------------------------------------------------------------
    def peer_alive(self, name: str) -> bool:
        """Whether a publisher of subscribed topic ``name`` is alive (liveliness).

        Fast DDS asserts AUTOMATIC liveliness between participants only: a
        publisher of this process (the same participant: a composed run, the
        nodes of a test) counts as alive only for a lease after its last
        message. Such a publisher lives as long as it is in the graph, so it
        counts as alive while it is there.
        """
        if self._alive.get(name, 0) > 0:
            return True
        # A matched publisher whose liveliness has not lapsed is alive: Fast
        # DDS sends a writer's first AUTOMATIC assertion up to a lease after
        # it is created, and a peer must not count as gone before it.
        sub = self._subscriptions_by_topic.get(name)
        if sub is not None and sub.get_publisher_count() > 0 and not self._lapsed.get(name, 0):
            return True
        prefix = self._participant_prefix()
        if prefix is None:
            return False
        infos = self.get_publishers_info_by_topic(self.resolve_topic_name(name))
        return any(bytes(i.endpoint_gid)[: len(prefix)] == prefix for i in infos)

    def _participant_prefix(self) -> bytes | None:
        """The GUID prefix (12 bytes) of this process's DDS participant, from our own endpoints."""
        if self._prefix is None:
            ns, me = self.get_namespace(), self.get_name()
            for topic_name in ("/rosout", "/parameter_events"):
                for info in self.get_publishers_info_by_topic(topic_name):
                    if info.node_name == me and info.node_namespace == ns:
                        self._prefix = bytes(info.endpoint_gid)[:12]
                        return self._prefix
        return self._prefix

    def fallback(self, kind: str, step: int, detail: str) -> None:
        """Record (log, report) that the node went on other than by the protocol."""
        self.health.fallbacks.append(Fallback(kind, step, detail))
        self.get_logger().error(
            f"FALLBACK ({kind}) at step {step}: {detail}; "
            "this run is not the deterministic result of its scenario"
        )
        self.write_report()

    def consumers_matched(self, publisher: Publisher, name: str, count: int) -> bool:
        """Whether the ``count`` subscribers ``publisher`` waits for are matched.

        The graph must show ``count`` subscriptions on the topic from the
        table's consumers or the recorder (in this namespace), and the
        publisher must be matched with at least ``count``. With a stranger
        subscribed as well, the matched count alone cannot tell who is
        matched: then the expected ones must have been in the graph, and the
        count reached, for :data:`MATCH_SETTLE_S` (discovery puts an
        endpoint in the graph and matches it from the same announcement).
        """
        if count <= 0:
            return True
        resolved = self.resolve_topic_name(name)
        entry = topics.topic(name)
        expected = set(entry.consumers) | {"recorder"}
        ns = self.get_namespace()
        infos = self.get_subscriptions_info_by_topic(resolved)
        ours = [i for i in infos if i.node_name in expected and i.node_namespace == ns]
        matched = publisher.get_subscription_count()
        if len(ours) < count or matched < count:
            self._matched_since.pop(name, None)
            return False
        if matched >= len(infos):
            return True
        since = self._matched_since.setdefault(name, time.monotonic())
        return time.monotonic() - since >= MATCH_SETTLE_S

    def after_consumers_matched(
        self, outputs: list[tuple[Publisher, str, int]], then: Callable[[], None]
    ) -> None:
        """Call ``then`` once each ``(publisher, topic, count)`` has its consumers matched.

        A node subscribes to the input it answers (``state``) only then, so
        that nothing it publishes in answer is lost to a reader still being
        discovered: the plant takes step 0 only once all of its ``state``
        subscribers are in. At once if they already are.
        """

        def ready() -> bool:
            return all(self.consumers_matched(pub, name, n) for pub, name, n in outputs)

        if ready():
            then()
            return

        def poll() -> None:
            if ready():
                timer.cancel()
                then()

        timer = self.create_timer(0.01, poll, clock=steady_clock())

    def _check_strangers(self) -> None:
        ns = self.get_namespace()
        new = False
        for name in self._watched:
            entry = topics.topic(name)
            # An endpoint discovered before its participant's node names has
            # node "_NODE_NAME_UNKNOWN_": not judged until the graph names it.
            infos = [
                i
                for i in self.get_publishers_info_by_topic(self.resolve_topic_name(name))
                if i.node_name != UNKNOWN_NODE_NAME
            ]
            is_ours = [i.node_name == entry.producer and i.node_namespace == ns for i in infos]
            ours = [i for i, mine in zip(infos, is_ours, strict=True) if mine]
            others = [i for i, mine in zip(infos, is_ours, strict=True) if not mine]
            # Two endpoints of the producer's own name: a restarted node and
            # the dead one, whose endpoint stays in the graph until its
            # participant's lease (5 s) ends; a duplicate that outlives that
            # is a stranger.
            twins = {bytes(i.endpoint_gid).hex() for i in ours[1:]}
            seen = self._twin_looks.get(name, {})
            self._twin_looks[name] = looks = {g: seen.get(g, 0) + 1 for g in twins}
            lasting = {g for g, n in looks.items() if n * STRANGER_CHECK_S > TWIN_GRACE_S}
            strangers = others + [i for i in ours[1:] if bytes(i.endpoint_gid).hex() in lasting]
            for info in strangers:
                gid = bytes(info.endpoint_gid).hex()
                if gid in self._stranger_gids:
                    continue
                self._stranger_gids.add(gid)
                who = f"{info.node_namespace.rstrip('/')}/{info.node_name} {gid[:16]}"
                self.health.strangers.setdefault(name, []).append(who)
                self.get_logger().warning(
                    f"stranger publishing on {name}: {who} (the run started only "
                    f"{ns.rstrip('/')}/{entry.producer}); its messages are validated like any other"
                )
                new = True
        if new:
            self.write_report()

    # -- report -------------------------------------------------------------------
    def write_report(self) -> None:
        """Write :attr:`health` to ``report_dir`` (if set)."""
        if self._report_dir is None:
            return
        try:
            write_health(self._report_dir, self.health)
        except OSError as err:
            self.get_logger().error(f"cannot write the health report: {err}")

    # -- diagnostics -------------------------------------------------------------
    def diagnostic_values(self) -> list[tuple[str, Any]]:
        """The node's own state on ``/diagnostics`` (a node adds its own: step, mode, ...)."""
        return []

    def diagnostic_error(self) -> str | None:
        """An error the node is in (one line: its status is then ERROR), None if none."""
        return None

    def diagnostic_stamp_ns(self) -> int:
        """The stamp of a status: the node's clock (simulation time with ``use_sim_time``)."""
        return int(self.get_clock().now().nanoseconds)

    def diagnostic_status(self) -> Status:
        """What the node's next ``/diagnostics`` status says."""
        return node_status(self.health, self.diagnostic_values(), self.diagnostic_error())

    def publish_diagnostics(self) -> None:
        """Publish the node's status on ``/diagnostics`` (:mod:`servo_axis.nodes.diagnostics`)."""
        self._diagnostics_pub.publish(
            diagnostic_array(
                self.diagnostic_status(),
                name=self.get_fully_qualified_name(),
                hardware_id=str(self.values["axis"]),
                stamp_ns=self.diagnostic_stamp_ns(),
            )
        )

    def close(self) -> None:
        """Called once when the node's process ends: write the report, a last status."""
        self.write_report()
        if self.context.ok():
            try:
                self.publish_diagnostics()
            except Exception as err:  # the context may be going down
                self.get_logger().warning(f"no last /diagnostics status: {err}")


def _plain(value: Any) -> Any:
    """A parameter value as plain Python (rclpy gives arrays as array.array)."""
    return value.tolist() if hasattr(value, "tolist") else value
