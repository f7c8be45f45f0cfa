"""A node's inputs: one way to take a message in, and whether its publisher lives.

* :meth:`Inputs.subscribe` decodes and validates each message with a pure
  function of :mod:`servo_axis.wire.messages` before the node's handler
  sees it; a message that fails is dropped and handed to ``reject`` (the
  node's :meth:`~servo_axis.nodes.reporting.Reporter.reject`: counted,
  logged): nothing derived from it is published.
* Senders: each message comes with its publisher's GID
  (:class:`~servo_axis.nodes.identified.IdentifiedSubscription`); a run's
  node (``wait_for_producers``) applies only the messages of the publisher
  that plays the topic's role (:meth:`~servo_axis.nodes.graph.GraphWatch.plays_role`:
  the node the run started for it, or an outside role's declared
  publisher), and counts a stranger's per topic, never applied
  (:meth:`~servo_axis.nodes.reporting.Reporter.stranger_message`): a
  stranger's well-formed message with the next stamp never takes the
  producer's place. A publisher the graph cannot name yet has its messages
  held, in order, until it can (:class:`~servo_axis.nodes.senders.Senders`).
* Streams: a per-sample subscription may take a
  :class:`~servo_axis.wire.streams.StreamGate` (made by
  :func:`~servo_axis.nodes.lockstep.stream_gate`); its stamp is checked
  after the payload is validated and before the handler sees it, so a
  message ahead of or behind the stream never displaces it.
* QoS: a subscription is made once the topic has a publisher in the ROS
  graph and its declared producer publishes
  (:meth:`~servo_axis.nodes.graph.GraphWatch.producer_present`), with the
  profile that matches it
  (:func:`~servo_axis.nodes.runtime.matching_reader_qos`): the suite's own
  publishers (reliable, transient-local, lease 1 s) get a reader just as
  strong, an outside node with rclpy's or rclcpp's default profile
  (reliable, volatile, no lease) or best effort is matched too.
* Peers: where the publisher offers a liveliness lease the subscription
  follows it (:data:`~servo_axis.nodes.runtime.LIVELINESS_LEASE_S` for the
  suite's own); where it offers none, the ROS graph says when it left (its
  participant's lease ended). :meth:`Inputs.peer_alive` is what a lockstep
  node asks before it falls back (it never does on a wall-clock timeout
  while its peer lives).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message

from servo_axis.core.errors import SignalError
from servo_axis.nodes.graph import GraphWatch
from servo_axis.nodes.identified import IdentifiedSubscription
from servo_axis.nodes.runtime import MESSAGE_CLASSES, READER_QOS, matching_reader_qos, steady_clock
from servo_axis.nodes.senders import Senders
from servo_axis.wire import topics
from servo_axis.wire.streams import StreamGate

#: ``take(data, from_producer, who)``: a message's payload, whether its
#: publisher plays the topic's role, and who that publisher is (for a person).
Take = Callable[[bytes, bool, str], None]

#: Messages handed on by a :class:`Senders`: ``(data, gid, from_producer)`` each.
Released = list[tuple[bytes, str, bool]]

#: Seconds between two looks at the graph for publishers whose messages are held.
HOLD_POLL_S = 0.01

T = TypeVar("T")


class Inputs:
    """The table topics a node subscribes to, and the liveliness of their publishers.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that subscribes.
    graph : GraphWatch
        Its view of the graph (which producer is declared, who is in this process).
    reject : callable
        ``reject(topic, text)`` for a message that is dropped.
    stranger : callable or None
        ``stranger(topic, who)`` for a message of a publisher that does not
        play the topic's role (not applied); None: not counted.
    """

    def __init__(
        self,
        node: Node,
        graph: GraphWatch,
        *,
        reject: Callable[[str, str], None],
        stranger: Callable[[str, str], None] | None = None,
    ) -> None:
        self._node = node
        self._graph = graph
        self._reject = reject
        self._stranger = stranger
        self._alive: dict[str, int] = {}
        self._lapsed: dict[str, int] = {}
        self._subscriptions: dict[str, IdentifiedSubscription] = {}
        self._made: list[IdentifiedSubscription] = []
        self._topics: list[str] = []
        self._unpublished: list[tuple[str, QoSProfile, Callable[[QoSProfile], None]]] = []
        self._unpublished_timer: Any = None
        self._senders: list[tuple[Senders[bytes], Callable[[Released], None]]] = []
        self._hold_timer: Any = None

    @property
    def topics(self) -> tuple[str, ...]:
        """The table topics subscribed to through :meth:`subscribe` (made or awaited)."""
        return tuple(self._topics)

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
        cls = MESSAGE_CLASSES[entry.type_name]
        reject = self._reject
        stranger = self._stranger

        def on_message(data: bytes, from_producer: bool, who: str) -> None:
            if not from_producer:
                if stranger is not None:
                    stranger(name, who)
                return
            try:
                sample = decode(data if raw else deserialize_message(data, cls))
                if gate is not None and sample is not None:
                    gate.accept(sample.step)  # type: ignore[attr-defined]
            except SignalError as err:
                reject(name, f"{name} rejected: {err}")
                return
            handle(sample)

        def on_liveliness(info: Any) -> None:
            self._alive[name] = info.alive_count
            self._lapsed[name] = info.not_alive_count

        def create(profile: QoSProfile) -> None:
            self._subscriptions[name] = self.identified(
                name,
                cls,
                on_message,
                profile,
                events=SubscriptionEventCallbacks(liveliness=on_liveliness),
            )

        self._alive.setdefault(name, 0)
        self._lapsed.setdefault(name, 0)
        if name not in self._topics:
            self._topics.append(name)
        self.when_published(name, READER_QOS[entry.qos] if qos is None else qos, create)

    def identified(
        self,
        name: str,
        cls: Any,
        take: Take,
        profile: QoSProfile,
        *,
        events: SubscriptionEventCallbacks | None = None,
    ) -> IdentifiedSubscription:
        """A subscription to ``name`` (message class ``cls``) whose messages are sorted by sender.

        ``take(data, from_producer, who)`` gets each message's CDR bytes, in
        the order each publisher sent them, once its publisher is judged
        (:meth:`~servo_axis.nodes.graph.GraphWatch.plays_role`); the
        recorder takes every message so, the others through :meth:`subscribe`.
        """
        graph = self._graph
        if graph.judges_senders:
            senders: Senders[bytes] = Senders(
                lambda gid, final: graph.plays_role(name, gid, final=final)
            )
        else:
            senders = Senders(lambda gid, final: True)
        who_of: dict[str, str] = {}

        def who(gid: str) -> str:
            if gid not in who_of:
                who_of[gid] = graph.who(name, gid)
            return who_of[gid]

        def hand_on(released: Released) -> None:
            for data, gid, verdict in released:
                take(data, verdict, "" if verdict else who(gid))

        def on_message(data: bytes, gid: str) -> None:
            hand_on(senders.offer(gid, data))
            if senders.held and self._hold_timer is None:
                self._hold_timer = self._node.create_timer(
                    HOLD_POLL_S, self._release_held, clock=steady_clock()
                )

        sub = IdentifiedSubscription(
            self._node, cls, name, profile, on_message, event_callbacks=events
        )
        self._senders.append((senders, hand_on))
        self._made.append(sub)
        return sub

    def _release_held(self) -> None:
        """Hand on the held messages whose publisher the graph can judge now."""
        for senders, hand_on in self._senders:
            if senders.held:
                hand_on(senders.retry())
        if not any(s.held for s, _ in self._senders) and self._hold_timer is not None:
            self._hold_timer.cancel()
            self._node.destroy_timer(self._hold_timer)
            self._hold_timer = None

    def release_all(self) -> None:
        """Hand on every held message, its publisher judged as the graph shows it now
        (the node's end: the recorder writes them)."""
        for senders, hand_on in self._senders:
            hand_on(senders.flush())

    def destroy(self) -> None:
        """Destroy the subscriptions made here (before the node is destroyed)."""
        for sub in self._made:
            sub.destroy()
        self._made.clear()
        self._subscriptions.clear()

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
            self._unpublished_timer = self._node.create_timer(
                0.01, self._create_pending, clock=steady_clock()
            )

    def _create_if_published(
        self, name: str, wanted: QoSProfile, create: Callable[[QoSProfile], None]
    ) -> bool:
        infos = self._graph.publishers(name)
        profile = matching_reader_qos(wanted, [i.qos_profile for i in infos])
        if profile is None or not self._graph.producer_present(name, infos):
            return False
        create(profile)
        return True

    def _create_pending(self) -> None:
        self._unpublished = [p for p in self._unpublished if not self._create_if_published(*p)]
        if not self._unpublished and self._unpublished_timer is not None:
            self._unpublished_timer.cancel()
            self._node.destroy_timer(self._unpublished_timer)
            self._unpublished_timer = None

    def matched(self, name: str, subscription: IdentifiedSubscription | None = None) -> bool:
        """Whether the subscription to ``name`` exists and is matched with a publisher.

        A volatile publisher among the topic's (an outside node with the
        default profile) sends a reader nothing from before it matched that
        reader on its own side: then the match must have held for
        :data:`~servo_axis.nodes.graph.MATCH_SETTLE_S`
        (:meth:`~servo_axis.nodes.graph.GraphWatch.matched_settled`).
        ``subscription`` is one the node made itself (the recorder's).
        """
        sub = subscription or self._subscriptions.get(name)
        key = f"input:{name}"
        matched = 0 if sub is None else sub.get_publisher_count()
        if matched < 1:
            self._graph.forget_match(key)
            return False
        return self._graph.matched_settled(key, self._graph.publishers(name), matched)

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
        sub = self._subscriptions.get(name)
        if sub is not None and sub.get_publisher_count() > 0 and not self._lapsed.get(name, 0):
            return True
        return self._graph.published_in_process(name)
