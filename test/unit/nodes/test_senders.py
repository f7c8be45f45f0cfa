"""Whose messages a subscription applies (Senders), without ROS: the producer's, in order."""

from __future__ import annotations

from servo_axis.nodes.senders import Senders


class Graph:
    """A judge over a graph the test changes: GID -> True/False, missing: not known yet."""

    def __init__(self) -> None:
        self.known: dict[str, bool] = {}
        self.asked: list[tuple[str, bool]] = []

    def judge(self, gid: str, final: bool) -> bool | None:
        self.asked.append((gid, final))
        return self.known.get(gid, False if final else None)


def test_a_judged_publisher_goes_on_at_once_and_a_strangers_is_marked() -> None:
    graph = Graph()
    graph.known = {"plant": True, "junk": False}
    senders: Senders[int] = Senders(graph.judge)
    assert senders.offer("plant", 0) == [(0, "plant", True)]
    assert senders.offer("junk", 0) == [(0, "junk", False)]
    assert senders.offer("plant", 1) == [(1, "plant", True)]
    # Each publisher is judged once (a GID is never reused).
    assert graph.asked == [("plant", False), ("junk", False)]
    assert senders.verdicts == {"plant": True, "junk": False} and senders.held == 0


def test_an_unnamed_publisher_is_held_in_order_until_the_graph_names_it() -> None:
    graph = Graph()
    graph.known = {"plant": True}
    now = [0.0]
    senders: Senders[int] = Senders(graph.judge, grace_s=2.0, clock=lambda: now[0])
    assert senders.offer("restarted", 10) == []
    assert senders.offer("plant", 5) == [(5, "plant", True)]  # the others go on meanwhile
    assert senders.offer("restarted", 11) == []
    assert senders.held == 2 and senders.retry() == []
    graph.known["restarted"] = True  # its node's name came
    now[0] = 0.5
    assert senders.retry() == [(10, "restarted", True), (11, "restarted", True)]
    assert senders.held == 0
    assert senders.offer("restarted", 12) == [(12, "restarted", True)]


def test_a_publisher_never_named_is_judged_after_the_grace() -> None:
    graph = Graph()
    now = [0.0]
    senders: Senders[int] = Senders(graph.judge, grace_s=2.0, clock=lambda: now[0])
    senders.offer("dds_only", 1)
    now[0] = 1.9
    assert senders.retry() == []
    now[0] = 2.0
    assert senders.retry() == [(1, "dds_only", False)]
    assert graph.asked[-1] == ("dds_only", True)


def test_holding_is_bounded_and_the_end_judges_what_is_held() -> None:
    graph = Graph()
    senders: Senders[int] = Senders(graph.judge, hold_limit=3)
    assert [senders.offer("a", i) for i in range(3)] == [[], [], []]
    assert senders.offer("b", 0) == [(0, "a", False), (1, "a", False), (2, "a", False)]
    assert senders.held == 1
    graph.known["b"] = True
    assert senders.flush() == [(0, "b", True)] and senders.held == 0
