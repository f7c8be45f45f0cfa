"""What a node reads from the ROS graph: its peers, its consumers, the strangers.

:class:`GraphWatch` is a node's one view of the graph:

* Handshake: :meth:`~GraphWatch.consumers_matched` counts the
  subscriptions on a topic, whatever their node is called (an outside node
  plays a role by its topics, not its name); when there are more than
  expected (a stranger subscribed too) or a volatile one among them, the
  count must hold for :data:`MATCH_SETTLE_S` before it is believed
  (:class:`Settle`). :meth:`~GraphWatch.answerer_listens` tells whether the
  node that answers a topic subscribes to it (a count cannot: another
  subscriber may stand in).
* Producers: :meth:`~GraphWatch.producer_present` says whether a topic's
  declared producer publishes (with ``wait_for_producers``, a run's node:
  the node the run started for the topic's producer role; for a role in
  ``external_roles``, the first publisher seen, whatever its name).
* Peers in this process: :meth:`~GraphWatch.published_in_process` (their
  liveliness says nothing about whether they live; see
  :meth:`servo_axis.nodes.inputs.Inputs.peer_alive`).
* Strangers: :meth:`~GraphWatch.strangers` compares each topic's publishers
  with the declared one (:class:`Strangers`, which needs no rclpy); the base
  node looks every :data:`STRANGER_CHECK_S` and when it closes.
* Senders: :meth:`~GraphWatch.plays_role` judges the publisher of a message
  by its GID (:mod:`servo_axis.nodes.senders`): a run's node applies only
  the messages of the publisher that plays the topic's role.

An outside role's publisher is the first one seen on its topic that is not
a stranger's elsewhere: a node that also publishes a topic of a role the run
started (a junk publisher on every topic) is never declared for an outside
role (:meth:`GraphWatch.suspect`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from servo_axis.nodes.senders import UNNAMED_GRACE_S
from servo_axis.wire import topics

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.publisher import Publisher

#: The node name the ROS graph gives an endpoint whose node it has not learnt yet.
UNKNOWN_NODE_NAME = "_NODE_NAME_UNKNOWN_"
#: Seconds between two looks at the graph for strangers.
STRANGER_CHECK_S = 0.5
#: Seconds a second endpoint of the producer's own name may stay in the graph
#: before it counts as a stranger: longer than the participant lease (5 s) of
#: a dead node replaced by a restarted one.
TWIN_GRACE_S = 7.0
#: Seconds a match must have held when the counts alone cannot tell (a
#: stranger subscriber beside the expected ones, a volatile endpoint that
#: may not have matched on its own side yet).
MATCH_SETTLE_S = 0.5
#: Seconds between two log lines of a node still waiting for its consumers.
WAIT_REPORT_S = 10.0


@dataclass(frozen=True)
class Endpoint:
    """A publisher or subscription as the graph lists it.

    Attributes
    ----------
    namespace, name : str
        Its node's namespace and name (:data:`UNKNOWN_NODE_NAME` until discovered).
    gid : str
        The endpoint's GUID, hex.
    """

    namespace: str
    name: str
    gid: str

    @classmethod
    def of(cls, info: Any) -> Endpoint:
        """From rclpy's ``TopicEndpointInfo``."""
        return cls(info.node_namespace, info.node_name, bytes(info.endpoint_gid).hex())

    @property
    def who(self) -> str:
        """``<namespace>/<node> <first 16 hex digits of the gid>`` for a person."""
        return f"{self.namespace.rstrip('/')}/{self.name} {self.gid[:16]}"


class Settle:
    """Whether counts have held, unchanged, for :data:`MATCH_SETTLE_S` (one clock per key).

    An endpoint that joins later (an outside node's volatile reader beside a
    stranger) changes the counts and settles in its turn.
    """

    def __init__(self, settle_s: float = MATCH_SETTLE_S) -> None:
        self.settle_s = settle_s
        self._since: dict[str, tuple[tuple[int, int], float]] = {}

    def held(self, key: str, counts: tuple[int, int], now: float | None = None) -> bool:
        """Whether ``counts`` have been those of ``key`` for the settle time (from now on if new)."""
        now = time.monotonic() if now is None else now
        held = self._since.get(key)
        if held is None or held[0] != counts:
            held = self._since[key] = (counts, now)
        return now - held[1] >= self.settle_s

    def forget(self, key: str) -> None:
        """The match of ``key`` was lost: it settles anew."""
        self._since.pop(key, None)


class Strangers:
    """Which publishers of a topic the run did not declare (no rclpy).

    Parameters
    ----------
    namespace : str
        The node's namespace (a role the run started publishes there).
    external_roles : iterable of str
        Roles played by nodes from outside the suite: on their topics the
        first publisher seen is declared (:meth:`declare`), whatever its name.
    """

    def __init__(
        self,
        *,
        namespace: str,
        external_roles: Iterable[str],
        unnamed_grace_s: float = UNNAMED_GRACE_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.namespace = namespace
        self.external_roles = frozenset(external_roles)
        self._declared: dict[str, str] = {}  # topic -> gid of an outside role's publisher
        self._reported: set[str] = set()
        self._twin_looks: dict[str, dict[str, int]] = {}
        self._listed: dict[str, float] = {}  # gid -> when first listed unnamed
        self._unnamed_grace_s = unnamed_grace_s
        self._clock = clock

    def declare(self, topic: str, gid: str) -> None:
        """``gid`` publishes ``topic`` for an outside role, unless one was declared already."""
        self._declared.setdefault(topic, gid)

    def declared_outside(
        self,
        topic: str,
        publishers: Sequence[Endpoint],
        suspect: Callable[[Endpoint], bool] = lambda e: False,
    ) -> str | None:
        """The GID of an outside role's publisher of ``topic``, or None while there is none.

        The declared one while it is listed; else the first publisher listed
        that is named and not ``suspect`` (a node that is a stranger on
        another topic), which is then declared: when the declared one leaves
        the graph, the first of the others takes its place (an outside node
        restarted by its user). A publisher the graph has not named after
        :data:`UNNAMED_GRACE_S` (a DDS application) may be declared too.
        """
        declared = self._declared.get(topic)
        if declared is not None and any(p.gid == declared for p in publishers):
            return declared
        now = self._clock()
        for p in publishers:
            if p.name == UNKNOWN_NODE_NAME:
                first = self._listed.setdefault(p.gid, now)
                if now - first < self._unnamed_grace_s:
                    continue
            elif suspect(p):
                continue
            self._declared[topic] = p.gid
            return p.gid
        return None

    def plays_role(
        self,
        topic: str,
        producer: str,
        publishers: Sequence[Endpoint],
        gid: str,
        *,
        final: bool = False,
        suspect: Callable[[Endpoint], bool] = lambda e: False,
    ) -> bool | None:
        """Whether publisher ``gid`` of ``topic`` plays its ``producer`` role (None: not known yet).

        A role the run started: a publisher of the node of the role's name in
        this namespace (a restarted one too). An outside role's: the declared
        one (:meth:`declared_outside`). A publisher the graph does not list,
        or whose node it has not named, is not known yet, unless ``final``:
        then it is a stranger.
        """
        endpoint = next((p for p in publishers if p.gid == gid), None)
        if producer in self.external_roles:
            declared = self.declared_outside(topic, publishers, suspect)
            if declared == gid:
                return True
            if (
                declared is None
                and not final
                and (endpoint is None or endpoint.name == UNKNOWN_NODE_NAME)
            ):
                return None
            return False
        if endpoint is None or endpoint.name == UNKNOWN_NODE_NAME:
            return False if final else None
        return endpoint.name == producer and endpoint.namespace == self.namespace

    def look(
        self,
        topic: str,
        producer: str,
        publishers: Sequence[Endpoint],
        suspect: Callable[[Endpoint], bool] = lambda e: False,
    ) -> tuple[list[str], str]:
        """One look at ``topic``'s publishers: the strangers not reported before, and who is declared.

        An endpoint whose node the graph has not named yet is not judged
        until it has. The strangers are given as :attr:`Endpoint.who`.
        """
        named = [p for p in publishers if p.name != UNKNOWN_NODE_NAME]
        if producer in self.external_roles:
            strangers, declared = self._outside(topic, publishers, named, suspect)
        else:
            strangers = self._own(topic, named, producer)
            declared = f"{self.namespace.rstrip('/')}/{producer}"
        new = [s for s in strangers if s.gid not in self._reported]
        self._reported.update(s.gid for s in new)
        return [s.who for s in new], declared

    def _outside(
        self,
        topic: str,
        publishers: Sequence[Endpoint],
        named: list[Endpoint],
        suspect: Callable[[Endpoint], bool],
    ) -> tuple[list[Endpoint], str]:
        """An outside role's topic: the declared publisher (:meth:`declared_outside`), and
        every other named one a stranger."""
        declared = self.declared_outside(topic, publishers, suspect) or ""
        who = next(
            (f"{p.namespace.rstrip('/')}/{p.name}" for p in named if p.gid == declared),
            "its outside node",
        )
        return [p for p in named if p.gid != declared], who

    def _own(self, topic: str, publishers: list[Endpoint], producer: str) -> list[Endpoint]:
        """A role the run started: its node (by the name the run gave it) is declared."""
        ours = [p for p in publishers if p.name == producer and p.namespace == self.namespace]
        others = [
            p for p in publishers if not (p.name == producer and p.namespace == self.namespace)
        ]
        # Two endpoints of the producer's own name: a restarted node and
        # the dead one, whose endpoint stays in the graph until its
        # participant's lease (5 s) ends; a duplicate that outlives that
        # is a stranger.
        seen = self._twin_looks.get(topic, {})
        self._twin_looks[topic] = looks = {p.gid: seen.get(p.gid, 0) + 1 for p in ours[1:]}
        lasting = {g for g, n in looks.items() if n * STRANGER_CHECK_S > TWIN_GRACE_S}
        return others + [p for p in ours[1:] if p.gid in lasting]


def _volatile(infos: Iterable[Any]) -> bool:
    """Whether any of the endpoints ``infos`` (rclpy's) is volatile."""
    # Imported here: the rest of the module (Settle, Strangers) is plain Python.
    from rclpy.qos import DurabilityPolicy

    return any(i.qos_profile.durability == DurabilityPolicy.VOLATILE for i in infos)


class GraphWatch:
    """A node's view of the ROS graph (see the module docstring).

    Parameters
    ----------
    node : rclpy.node.Node
        The node whose graph it is (its namespace, its timers).
    external_roles : iterable of str
        Roles played by nodes from outside the suite (``external_roles``).
    wait_for_producers : bool
        A run's node: a topic of a role the run started is subscribed to
        only once that node publishes it (:meth:`producer_present`).
    """

    def __init__(
        self, node: Node, *, external_roles: Iterable[str], wait_for_producers: bool
    ) -> None:
        self._node = node
        self.external_roles = frozenset(external_roles)
        self._wait_for_producers = wait_for_producers
        self._settle = Settle()
        self._prefix: bytes | None = None
        self._strangers = Strangers(
            namespace=node.get_namespace(), external_roles=self.external_roles
        )

    def publishers(self, name: str) -> list[Any]:
        """The publishers of topic ``name`` (relative names resolved), rclpy's endpoint infos."""
        return self._node.get_publishers_info_by_topic(self._node.resolve_topic_name(name))

    def subscriptions(self, name: str) -> list[Any]:
        """The subscriptions of topic ``name``, rclpy's endpoint infos."""
        return self._node.get_subscriptions_info_by_topic(self._node.resolve_topic_name(name))

    def is_outside(self, role: str | None) -> bool:
        """Whether ``role`` is played by a node from outside the suite."""
        return role in self.external_roles

    # -- producers ------------------------------------------------------------------
    def producer_present(self, name: str, infos: Sequence[Any]) -> bool:
        """Whether topic ``name`` may be subscribed to, with ``infos`` its publishers now.

        An outside role's topic: whoever publishes (the first one seen is
        declared). With ``wait_for_producers``, a topic of the table whose
        producer is a role the run started waits for that node's publisher:
        the graph lists it only once this participant has discovered it, so
        a reader made then matches it on its own side at once. A reader made
        on a stranger's publisher that was there first matches the producer
        on its side whenever that discovery message comes: measured, a
        learning unit whose real ``state[0]`` came late took a stranger's
        well-formed ``state[0]`` (stamp 0, sent 20 steps later) first, and
        the corrupted correction tripped the loop.
        """
        producer = topics.topic(name).producer if name in topics.BY_NAME else None
        if producer in self.external_roles:
            endpoints = [Endpoint.of(i) for i in infos]
            return self._strangers.declared_outside(name, endpoints, self.suspect) is not None
        if not self._wait_for_producers or producer is None:
            return True
        ns = self._node.get_namespace()
        return any(i.node_name == producer and i.node_namespace == ns for i in infos)

    @property
    def judges_senders(self) -> bool:
        """Whether the node applies only its producers' messages (a run's node:
        ``wait_for_producers``; a node started by hand takes every publisher's)."""
        return self._wait_for_producers

    def plays_role(self, name: str, gid: str, *, final: bool = False) -> bool | None:
        """Whether publisher ``gid`` of topic ``name`` plays the topic's producer role.

        True for every publisher of a node started by hand (not
        :attr:`judges_senders`) and of a topic outside the table; else as
        :meth:`Strangers.plays_role` judges it from the graph now (None: not
        known yet, never when ``final``).
        """
        producer = topics.topic(name).producer if name in topics.BY_NAME else None
        if not self._wait_for_producers or producer is None:
            return True
        endpoints = [Endpoint.of(i) for i in self.publishers(name)]
        return self._strangers.plays_role(
            name, producer, endpoints, gid, final=final, suspect=self.suspect
        )

    def who(self, name: str, gid: str) -> str:
        """Publisher ``gid`` of topic ``name`` for a person (:attr:`Endpoint.who`, the whole GID)."""
        for info in self.publishers(name):
            endpoint = Endpoint.of(info)
            if endpoint.gid == gid:
                return f"{endpoint.namespace.rstrip('/')}/{endpoint.name} {gid}"
        return f"{UNKNOWN_NODE_NAME} {gid}"

    def suspect(self, endpoint: Endpoint) -> bool:
        """Whether ``endpoint``'s node also publishes a topic of a role the run started here.

        Such a node is a stranger there, so it is not the outside node of
        any role: a junk publisher on every topic, there before the outside
        node, is not declared in its place. Only a run's node asks
        (``wait_for_producers``); a node that has left the graph is not one.
        """
        if not self._wait_for_producers or endpoint.name == UNKNOWN_NODE_NAME:
            return False
        try:
            published = self._node.get_publisher_names_and_types_by_node(
                endpoint.name, endpoint.namespace
            )
        except Exception:  # NodeNameNonExistentError: it left
            return False
        ns = self._node.get_namespace().rstrip("/")
        for topic_name, _ in published:
            for entry in topics.TOPICS:
                full = entry.name if entry.name.startswith("/") else f"{ns}/{entry.name}"
                if topic_name == full and entry.producer not in self.external_roles:
                    return True
        return False

    def matched_settled(self, key: str, infos: Sequence[Any], matched: int) -> bool:
        """Whether a match with ``infos`` (``matched`` of them matched) can be believed.

        At once unless one of them is volatile: an outside node with the
        default profile gets nothing of what was sent before it matched on
        its own side; discovery puts an endpoint in the graph and matches it
        from the same announcement, within milliseconds on one machine, so
        then the counts must have held for :data:`MATCH_SETTLE_S`.
        """
        if not _volatile(infos):
            return True
        return self._settle.held(key, (len(infos), matched))

    def forget_match(self, key: str) -> None:
        """The match of ``key`` was lost (see :meth:`matched_settled`)."""
        self._settle.forget(key)

    # -- consumers --------------------------------------------------------------------
    def consumers_matched(self, publisher: Publisher, name: str, count: int) -> bool:
        """Whether the ``count`` subscribers ``publisher`` waits for are matched.

        The graph must show at least ``count`` subscriptions on the topic,
        whatever their node is called, and the publisher must be matched
        with at least ``count``. Two cases cannot be told from the counts
        alone and must hold for :data:`MATCH_SETTLE_S` first: more
        subscriptions than expected (a stranger, such as a ``ros2 topic
        echo``, may stand in for a peer still being discovered), and a
        volatile reader among them (:meth:`matched_settled`).
        """
        if count <= 0:
            return True
        infos = self.subscriptions(name)
        matched = publisher.get_subscription_count()
        if len(infos) < count or matched < count:
            self._settle.forget(name)
            return False
        if len(infos) == count and not _volatile(infos):
            return True
        return self._settle.held(name, (len(infos), matched))

    def consumers_missing(self, publisher: Publisher, name: str, count: int) -> str | None:
        """What :meth:`consumers_matched` still waits for, for a person, or None if nothing."""
        if self.consumers_matched(publisher, name, count):
            return None
        listed, matched = len(self.subscriptions(name)), publisher.get_subscription_count()
        return f"{count} subscribers of {name} (the graph lists {listed}, {matched} matched)"

    def readers_settled(self, name: str, count: int) -> bool:
        """Whether topic ``name`` has a publisher and ``count`` subscriptions, held a while.

        For a publisher of another process that starts on a sign (an
        outside plant: ``state[0]`` once ``command`` has a publisher): its
        readers must all be in, and the counts must have held for
        :data:`MATCH_SETTLE_S`, so that its volatile writer has matched them
        on its side too.
        """
        key = f"readers:{name}"
        infos, publishers = self.subscriptions(name), self.publishers(name)
        if not publishers or len(infos) < count:
            self._settle.forget(key)
            return False
        return self._settle.held(key, (len(infos), len(publishers)))

    def after_consumers_matched(
        self, outputs: Sequence[tuple[Publisher, str, int]], then: Callable[[], None]
    ) -> None:
        """Call ``then`` once each ``(publisher, topic, count)`` has its consumers matched.

        A node subscribes to the input it answers (``state``) only then, so
        that nothing it publishes in answer is lost to a reader still being
        discovered: the plant takes step 0 only once all of its ``state``
        subscribers are in. At once if they already are, else from a 10 ms
        poll, which says every :data:`WAIT_REPORT_S` what is still missing
        (a start that never comes is otherwise silent).
        """

        def missing() -> list[str]:
            said = (self.consumers_missing(pub, name, n) for pub, name, n in outputs)
            return [s for s in said if s is not None]

        if not missing():
            then()
            return
        since = time.monotonic()
        told = since

        def poll() -> None:
            nonlocal told
            left = missing()
            if not left:
                timer.cancel()
                then()
            elif time.monotonic() - told >= WAIT_REPORT_S:
                told = time.monotonic()
                self._node.get_logger().warning(
                    f"waiting {told - since:.0f} s for " + "; ".join(left)
                )

        from servo_axis.nodes.runtime import steady_clock  # rclpy: not at the module's top

        timer = self._node.create_timer(0.01, poll, clock=steady_clock())

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

        return not nodes(self.publishers(answer)).isdisjoint(nodes(self.subscriptions(question)))

    # -- this process -----------------------------------------------------------------
    def published_in_process(self, name: str) -> bool:
        """Whether a publisher of topic ``name`` is in this process's participant.

        Fast DDS asserts AUTOMATIC liveliness between participants only: such
        a publisher (a composed run, the nodes of a test) lapses a lease
        after its last message, which says nothing about whether it lives.
        """
        prefix = self._participant_prefix()
        if prefix is None:
            return False
        return any(bytes(i.endpoint_gid)[: len(prefix)] == prefix for i in self.publishers(name))

    def _participant_prefix(self) -> bytes | None:
        """The GUID prefix (12 bytes) of this process's DDS participant, from our own endpoints."""
        if self._prefix is None:
            ns, me = self._node.get_namespace(), self._node.get_name()
            for topic_name in ("/rosout", "/parameter_events"):
                for info in self._node.get_publishers_info_by_topic(topic_name):
                    if info.node_name == me and info.node_namespace == ns:
                        self._prefix = bytes(info.endpoint_gid)[:12]
                        return self._prefix
        return self._prefix

    # -- strangers --------------------------------------------------------------------
    def strangers(self, names: Iterable[str]) -> list[tuple[str, str, str]]:
        """The new strangers on table topics ``names``: ``(topic, who, declared)`` each."""
        found = []
        for name in names:
            endpoints = [Endpoint.of(i) for i in self.publishers(name)]
            whos, declared = self._strangers.look(
                name, topics.topic(name).producer, endpoints, self.suspect
            )
            found += [(name, who, declared) for who in whos]
        return found
