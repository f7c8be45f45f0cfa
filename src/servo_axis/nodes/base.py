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
* QoS: a subscription is made once the topic has a publisher in the ROS
  graph (with ``wait_for_producers``, a run's node: once the node the run
  started for the topic's producer role publishes it), with the profile
  that matches it
  (:func:`~servo_axis.nodes.runtime.matching_reader_qos`): the suite's own
  publishers (reliable, transient-local, lease 1 s) get a reader just as
  strong, an outside node with rclpy's or rclcpp's default profile
  (reliable, volatile, no lease) or best effort is matched too.
* Peers: where the publisher offers a liveliness lease the subscription
  follows it (:data:`~servo_axis.nodes.runtime.LIVELINESS_LEASE_S` for the
  suite's own); where it offers none, the ROS graph says when it left (its
  participant's lease ended). :meth:`ServoNode.peer_alive` is what a
  lockstep node asks before it falls back (it never does on a wall-clock
  timeout while its peer lives), and :meth:`ServoNode.fallback` records
  that it did.
* Strangers: twice a second each subscribed topic's publishers are compared,
  through the ROS graph, with the declared one: the node the run started
  for the table's producer role (in this node's namespace) or, for a role
  in ``external_roles``, the first publisher seen on the topic, whatever
  its name; any other is logged and reported.
* Handshake: :meth:`ServoNode.consumers_matched` counts the subscriptions
  on the topic, whatever their node is called; when there are more than
  expected (a stranger subscribed too), the count must hold for
  :data:`MATCH_SETTLE_S` before it is believed;
  :meth:`ServoNode.answerer_listens` tells whether the node that answers a
  topic subscribes to it (a count cannot: another subscriber may stand in).
* Report: :mod:`servo_axis.wire.node_report`, written to ``report_dir`` on each
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
from rclpy.qos import DurabilityPolicy, QoSProfile
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
    matching_reader_qos,
    realtime_scheduling,
    steady_clock,
)
from servo_axis.params.factories import checked_values, external_roles, node_schema
from servo_axis.params.param import BUILTIN, Param
from servo_axis.wire import topics
from servo_axis.wire.node_report import Fallback, NodeHealth, write_health
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
        # key -> (who was matched: the counts, since when by the steady clock)
        self._matched_since: dict[str, tuple[tuple[int, int], float]] = {}
        self._prefix: bytes | None = None
        self.external_roles = external_roles(self.values)
        self._declared: dict[str, str] = {}  # topic -> gid of an external role's publisher
        self._unpublished: list[tuple[str, QoSProfile, Callable[[QoSProfile], None]]] = []
        self._unpublished_timer: Any = None
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
    ) -> None:
        """Subscribe to table topic ``name``: ``handle(decode(msg))`` for the valid ones.

        ``decode`` raises :class:`SignalError` for a message that must not be
        used (wrong length, names, NaN/inf, stamp); it is then rejected here.
        With a ``gate``, the decoded sample's ``step`` must be one the gate
        takes (it is checked after decoding, so a junk message never moves
        the gate); a ``decode`` that returns None for a message it skips
        leaves the gate alone. The subscription is made once the topic has a
        publisher (:meth:`when_published`), with the profile that matches
        it; ``qos`` replaces the table's profile as the strongest one asked
        for (a late joiner that wants no history).
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

        def create(profile: QoSProfile) -> None:
            self._subscriptions_by_topic[name] = self.create_subscription(
                MESSAGE_CLASSES[entry.type_name],
                name,
                on_message,
                profile,
                raw=raw,
                event_callbacks=SubscriptionEventCallbacks(liveliness=on_liveliness),
            )

        self._alive.setdefault(name, 0)
        self._lapsed.setdefault(name, 0)
        if name not in self._watched:
            self._watched.append(name)
        self.when_published(name, READER_QOS[entry.qos] if qos is None else qos, create)

    def when_published(
        self, name: str, wanted: QoSProfile, create: Callable[[QoSProfile], None]
    ) -> None:
        """Call ``create(profile)`` once topic ``name`` has a publisher in the ROS graph.

        ``profile`` is ``wanted`` weakened just as far as the publishers there
        need (:func:`~servo_axis.nodes.runtime.matching_reader_qos`); at once
        if the topic already has one, else from a 10 ms poll of the graph.
        """
        if self._create_if_published(name, wanted, create):
            return
        self._unpublished.append((name, wanted, create))
        if self._unpublished_timer is None:
            self._unpublished_timer = self.create_timer(
                0.01, self._create_pending, clock=steady_clock()
            )

    def _create_if_published(
        self, name: str, wanted: QoSProfile, create: Callable[[QoSProfile], None]
    ) -> bool:
        infos = self.get_publishers_info_by_topic(self.resolve_topic_name(name))
        profile = matching_reader_qos(wanted, [i.qos_profile for i in infos])
        producer = topics.topic(name).producer if name in topics.BY_NAME else None
        outside = producer in self.external_roles
        if profile is None or not (outside or self._producer_publishes(producer, infos)):
            return False
        if outside:
            # An outside role's publisher is the first one seen: the one there now.
            self._declared.setdefault(name, bytes(infos[0].endpoint_gid).hex())
        create(profile)
        return True

    def _producer_publishes(self, producer: str | None, infos: list[Any]) -> bool:
        """Whether a topic of the suite's ``producer`` role (None: not a table topic) may be
        subscribed to, with ``infos`` its publishers now.

        With ``wait_for_producers`` (a run's node), a topic of the table whose
        producer is a role the run started waits for that node's publisher:
        the graph lists it only once this participant has discovered it, so
        a reader made then matches it on its own side at once. A reader made
        on a stranger's publisher that was there first matches the producer
        on its side whenever that discovery message comes: measured, a
        learning unit whose real ``state[0]`` came late took a stranger's
        well-formed ``state[0]`` (stamp 0, sent 20 steps later) first, and
        the corrupted correction tripped the loop.
        """
        if not self.values["wait_for_producers"] or producer is None:
            return True
        ns = self.get_namespace()
        return any(i.node_name == producer and i.node_namespace == ns for i in infos)

    def _create_pending(self) -> None:
        self._unpublished = [p for p in self._unpublished if not self._create_if_published(*p)]
        if not self._unpublished and self._unpublished_timer is not None:
            self._unpublished_timer.cancel()
            self.destroy_timer(self._unpublished_timer)
            self._unpublished_timer = None

    @property
    def inputs(self) -> tuple[str, ...]:
        """The table topics the node subscribes to through :meth:`subscribe` (made or awaited)."""
        return tuple(self._watched)

    def input_matched(self, name: str, subscription: Subscription | None = None) -> bool:
        """Whether the subscription to ``name`` exists and is matched with a publisher.

        A volatile publisher among the topic's (an outside node with the
        default profile) sends a reader nothing from before it matched that
        reader on its own side: then the match must have held for
        :data:`MATCH_SETTLE_S` (as in :meth:`consumers_matched`).
        ``subscription`` is one the node made itself (the recorder's).
        """
        sub = subscription or self._subscriptions_by_topic.get(name)
        key = f"input:{name}"
        matched = 0 if sub is None else sub.get_publisher_count()
        if matched < 1:
            self._matched_since.pop(key, None)
            return False
        infos = self.get_publishers_info_by_topic(self.resolve_topic_name(name))
        if all(i.qos_profile.durability != DurabilityPolicy.VOLATILE for i in infos):
            return True
        return self._settled(key, (len(infos), matched))

    def reject(self, topic_name: str, text: str) -> None:
        """Count a dropped message of ``topic_name`` and log it (at most once a second)."""
        self.rejected += 1
        self.health.rejected[topic_name] = self.health.rejected.get(topic_name, 0) + 1
        if self._complain.ready():
            self.get_logger().warning(f"{text} ({self.rejected} rejected so far)")

    # -- peers -------------------------------------------------------------------
    def realtime_scheduling(self, below: int = 0) -> None:
        """Realtime mode: ask for ``SCHED_FIFO`` at ``thread_priority - below`` (at least 1),
        applied by :meth:`start_realtime` once the run starts.

        Start-up (discovery, matching, loading the compiled kernels) runs at
        the default scheduler: realtime threads that saturate a small host
        while the others are still being set up can starve them (a run on 2
        cores once never started). Nothing in lockstep, where nothing waits
        on the wall clock, or with a ``thread_priority`` of 0.
        """
        self.scheduling: dict[str, object] | None = None
        if self.values["mode"] != "lockstep" and self.values["thread_priority"] > 0:
            self._rt_priority = max(1, self.values["thread_priority"] - below)

    def start_realtime(self) -> None:
        """Apply the scheduling asked for (:func:`~servo_axis.nodes.runtime.realtime_scheduling`
        on every thread of the process; a warning if refused), once; later calls do nothing."""
        priority = getattr(self, "_rt_priority", None)
        if priority is None:
            return
        self._rt_priority = None
        got = realtime_scheduling(priority)
        self.scheduling = got
        if "refused" in got:
            self.get_logger().warning(
                f"thread_priority {priority}: refused ({got['refused']}); the default scheduler"
            )

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
        return self.published_in_process(name)

    def published_in_process(self, name: str) -> bool:
        """Whether a publisher of topic ``name`` is in this process's participant (the graph).

        Its AUTOMATIC liveliness lapses a lease after its last message (see
        :meth:`peer_alive`), which says nothing about whether it lives.
        """
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

        The graph must show at least ``count`` subscriptions on the topic,
        whatever their node is called (an outside node plays a role by its
        topics, not its name), and the publisher must be matched with at
        least ``count``. Two cases cannot be told from the counts alone and
        must hold for :data:`MATCH_SETTLE_S` first: more subscriptions than
        expected (a stranger, such as a ``ros2 topic echo``, may stand in for
        a peer still being discovered), and a volatile reader among them (an
        outside node with the default profile gets nothing of what was sent
        before it matched on its own side; discovery puts an endpoint in the
        graph and matches it from the same announcement, within
        milliseconds on one machine).
        """
        if count <= 0:
            return True
        infos = self.get_subscriptions_info_by_topic(self.resolve_topic_name(name))
        matched = publisher.get_subscription_count()
        if len(infos) < count or matched < count:
            self._matched_since.pop(name, None)
            return False
        volatile = any(i.qos_profile.durability == DurabilityPolicy.VOLATILE for i in infos)
        if len(infos) == count and not volatile:
            return True
        return self._settled(name, (len(infos), matched))

    def _settled(self, key: str, counts: tuple[int, int]) -> bool:
        """Whether ``counts`` (endpoints in the graph, matched) have held for
        :data:`MATCH_SETTLE_S`: an endpoint that joins later (an outside node's
        volatile reader beside a stranger) settles in its turn."""
        now = time.monotonic()
        held = self._matched_since.get(key)
        if held is None or held[0] != counts:
            held = self._matched_since[key] = (counts, now)
        return now - held[1] >= MATCH_SETTLE_S

    def answerer_listens(self, answer: str, question: str) -> bool:
        """Whether a node that publishes ``answer`` subscribes to ``question``.

        The node that answers ``question[k]`` with ``answer[k]`` must listen
        before sample 0 goes out, and counting the subscribers of
        ``question`` does not tell: another one (an outside reference
        generator that answers ``state`` too, a stranger) may stand in for it
        while it still waits for its own inputs. Nodes are told apart by
        namespace and name, whatever the name: an outside node plays a role
        by its topics.
        """

        def nodes(infos: list[Any]) -> set[tuple[str, str]]:
            return {
                (i.node_namespace, i.node_name) for i in infos if i.node_name != UNKNOWN_NODE_NAME
            }

        answering = nodes(self.get_publishers_info_by_topic(self.resolve_topic_name(answer)))
        listening = nodes(self.get_subscriptions_info_by_topic(self.resolve_topic_name(question)))
        return not answering.isdisjoint(listening)

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
            if entry.producer in self.external_roles:
                strangers, declared = self._outside_strangers(name, infos)
            else:
                strangers = self._own_strangers(name, infos, entry.producer)
                declared = f"{ns.rstrip('/')}/{entry.producer}"
            for info in strangers:
                gid = bytes(info.endpoint_gid).hex()
                if gid in self._stranger_gids:
                    continue
                self._stranger_gids.add(gid)
                who = f"{info.node_namespace.rstrip('/')}/{info.node_name} {gid[:16]}"
                self.health.strangers.setdefault(name, []).append(who)
                self.get_logger().warning(
                    f"stranger publishing on {name}: {who} (the run declared only {declared}); "
                    "its messages are validated like any other"
                )
                new = True
        if new:
            self.write_report()

    def _outside_strangers(self, name: str, infos: list[Any]) -> tuple[list[Any], str]:
        """An outside role's topic: the first publisher seen is declared, any other a stranger.

        When the declared one leaves the graph, the first of the others
        takes its place (an outside node restarted by its user).
        """
        gids = [bytes(i.endpoint_gid).hex() for i in infos]
        if self._declared.get(name) not in gids and gids:
            self._declared[name] = gids[0]
        declared = self._declared.get(name, "")
        who = next(
            (
                f"{i.node_namespace.rstrip('/')}/{i.node_name}"
                for i, g in zip(infos, gids, strict=True)
                if g == declared
            ),
            "its outside node",
        )
        return [i for i, g in zip(infos, gids, strict=True) if g != declared], who

    def _own_strangers(self, name: str, infos: list[Any], producer: str) -> list[Any]:
        """A role the run started: its node (by the name the run gave it) is declared."""
        ns = self.get_namespace()
        is_ours = [i.node_name == producer and i.node_namespace == ns for i in infos]
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
        return others + [i for i in ours[1:] if bytes(i.endpoint_gid).hex() in lasting]

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

    def realtime_counts(self) -> dict[str, int]:
        """What the node counted of a realtime run for the summary's ``realtime`` block
        (fields of :class:`~servo_axis.analysis.summary.Realtime`; put in ``health.realtime``
        when it closes); none here."""
        return {}

    def close(self) -> None:
        """Called once when the node's process ends: a last look for strangers, the report, a last status.

        The graph is looked at every :data:`STRANGER_CHECK_S`; a stranger
        that began publishing after the last look of a short run (a lockstep
        run of 0.2 s) would otherwise go unreported.
        """
        if self.context.ok():
            try:
                self._check_strangers()
            except Exception as err:  # the context may be going down
                self.get_logger().warning(f"no last look for strangers: {err}")
        counts = self.realtime_counts()
        if counts and self.values["mode"] != "lockstep":
            self.health.realtime = counts
        self.write_report()
        if self.context.ok():
            try:
                self.publish_diagnostics()
            except Exception as err:  # the context may be going down
                self.get_logger().warning(f"no last /diagnostics status: {err}")


def _plain(value: Any) -> Any:
    """A parameter value as plain Python (rclpy gives arrays as array.array)."""
    return value.tolist() if hasattr(value, "tolist") else value
