"""Whose messages a subscription applies: its producer's, as the ROS graph tells them apart.

Each message comes with its publisher's GID
(:class:`~servo_axis.nodes.identified.IdentifiedSubscription`); a
:class:`Senders` sorts them by a judge: ``judge(gid, final)`` is True for
the publisher that plays the topic's role, False for a stranger, and None
while the graph cannot tell yet (the publisher is not listed, or its node
not named: a node's name comes with its participant's discovery
information, which can trail its endpoints). A publisher's messages are
held, in order, until it is judged, for at most :data:`UNNAMED_GRACE_S`
(then ``final`` asks the judge for an answer) and :data:`HOLD_LIMIT`
messages; a verdict is kept for the publisher's life (a GID is never
reused). The producer's messages go on in the order they came; a
stranger's are handed back marked as such, never applied.

Nothing here imports rclpy.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")

#: Seconds a publisher the graph does not name may have its messages held
#: before it is judged as it is (the suite's nodes are named within
#: milliseconds of their first endpoint).
UNNAMED_GRACE_S = 2.0
#: Messages held at most per topic (a reader's history, the stream's depth
#: twice); past it the oldest is judged at once.
HOLD_LIMIT = 4000

#: ``judge(gid, final)``: True (the producer), False (a stranger), None (not known yet;
#: never when ``final``).
Judge = Callable[[str, bool], "bool | None"]


class Senders(Generic[T]):
    """The messages of one topic, sorted by publisher (see the module docstring).

    Parameters
    ----------
    judge : callable
        ``judge(gid, final) -> bool | None``.
    grace_s : float
        :data:`UNNAMED_GRACE_S`.
    hold_limit : int
        :data:`HOLD_LIMIT`.
    clock : callable
        Seconds, monotonic (``time.monotonic``).
    """

    def __init__(
        self,
        judge: Judge,
        *,
        grace_s: float = UNNAMED_GRACE_S,
        hold_limit: int = HOLD_LIMIT,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._judge = judge
        self._grace_s = grace_s
        self._hold_limit = hold_limit
        self._clock = clock
        #: The verdict on each publisher judged (GID -> plays the role).
        self.verdicts: dict[str, bool] = {}
        self._held: dict[str, deque[T]] = {}
        self._since: dict[str, float] = {}
        self._count = 0

    @property
    def held(self) -> int:
        """Messages held, all publishers together."""
        return self._count

    def offer(self, gid: str, item: T) -> list[tuple[T, str, bool]]:
        """A message of ``gid``: what can be handed on now, in order, ``(item, gid, from_producer)``.

        A message of a publisher already judged goes on at once; one of a
        publisher not judged yet is held, unless the judge can tell now.
        """
        verdict = self.verdicts.get(gid)
        if verdict is not None:
            return [(item, gid, verdict)]
        queue = self._held.get(gid)
        if queue is None:
            verdict = self._judge(gid, False)
            if verdict is not None:
                self.verdicts[gid] = verdict
                return [(item, gid, verdict)]
            queue = self._held[gid] = deque()
            self._since[gid] = self._clock()
        queue.append(item)
        self._count += 1
        out: list[tuple[T, str, bool]] = []
        while self._count > self._hold_limit:
            out += self._release(next(iter(self._held)), final=True)
        return out

    def retry(self) -> list[tuple[T, str, bool]]:
        """The held messages whose publisher can be judged now (past the grace: judged as it is)."""
        out: list[tuple[T, str, bool]] = []
        now = self._clock()
        for gid in list(self._held):
            out += self._release(gid, final=now - self._since[gid] >= self._grace_s)
        return out

    def flush(self) -> list[tuple[T, str, bool]]:
        """Everything held, each publisher judged as it is now (the end of the node)."""
        out: list[tuple[T, str, bool]] = []
        for gid in list(self._held):
            out += self._release(gid, final=True)
        return out

    def _release(self, gid: str, *, final: bool) -> list[tuple[T, str, bool]]:
        verdict = self._judge(gid, final)
        if verdict is None:
            if not final:
                return []
            verdict = False  # a judge that cannot tell at the end: not the producer
        self.verdicts[gid] = verdict
        queue = self._held.pop(gid)
        del self._since[gid]
        self._count -= len(queue)
        return [(item, gid, verdict) for item in queue]
