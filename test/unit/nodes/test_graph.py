"""What a node judges from the ROS graph, without ROS: settled matches, strangers."""

from __future__ import annotations

import math

from servo_axis.nodes.graph import (
    MATCH_SETTLE_S,
    STRANGER_CHECK_S,
    TWIN_GRACE_S,
    UNKNOWN_NODE_NAME,
    Endpoint,
    Settle,
    Strangers,
)


def gid(n: int) -> str:
    return f"{n:032x}"


def test_a_match_is_believed_once_its_counts_held_for_the_settle_time() -> None:
    settle = Settle()
    assert not settle.held("state", (2, 2), now=10.0)
    assert not settle.held("state", (2, 2), now=10.0 + MATCH_SETTLE_S / 2)
    assert settle.held("state", (2, 2), now=10.0 + MATCH_SETTLE_S)
    # A new endpoint (counts changed) settles in its turn; other keys are apart.
    assert not settle.held("state", (3, 3), now=11.0)
    assert not settle.held("input:command", (1, 1), now=11.0)
    assert settle.held("state", (3, 3), now=11.0 + MATCH_SETTLE_S)
    settle.forget("state")  # the match was lost
    assert not settle.held("state", (3, 3), now=12.0)


def test_endpoint_names_whom_a_person_reads() -> None:
    e = Endpoint("/x/", "junk", gid(0xABC))
    assert e.who == f"/x/junk {gid(0xABC)[:16]}"


def test_the_run_declares_its_own_producer_by_name_and_namespace() -> None:
    strangers = Strangers(namespace="/x", external_roles=[])
    plant = Endpoint("/x", "plant", gid(1))
    other_axis = Endpoint("/y", "plant", gid(2))
    junk = Endpoint("/", "junk", gid(3))
    unnamed = Endpoint("/", UNKNOWN_NODE_NAME, gid(4))
    whos, declared = strangers.look("state", "plant", [plant, other_axis, junk, unnamed])
    assert declared == "/x/plant"
    # Not judged while the graph has not named its node.
    assert whos == [other_axis.who, junk.who]
    # Reported once, whatever the looks after.
    assert strangers.look("state", "plant", [plant, other_axis, junk]) == ([], "/x/plant")
    named = Endpoint("/", "late_name", gid(4))
    assert strangers.look("state", "plant", [plant, named])[0] == [named.who]


def test_a_restarted_producer_beside_its_dead_twin_is_no_stranger_for_a_while() -> None:
    strangers = Strangers(namespace="/x", external_roles=[])
    dead, restarted = Endpoint("/x", "learning", gid(1)), Endpoint("/x", "learning", gid(2))
    looks_within_grace = math.floor(TWIN_GRACE_S / STRANGER_CHECK_S)
    for _ in range(looks_within_grace):
        assert strangers.look("learning/correction", "learning", [dead, restarted])[0] == []
    # The dead one's participant lease ended long ago: a twin that stays is a stranger.
    whos, _ = strangers.look("learning/correction", "learning", [dead, restarted])
    assert whos == [restarted.who]


def test_an_outside_role_declares_the_first_publisher_seen_and_its_successor() -> None:
    strangers = Strangers(namespace="/", external_roles=["feedback"])
    mine = Endpoint("/", "my_controller", gid(1))
    echo = Endpoint("/", "someone", gid(2))
    whos, declared = strangers.look("command", "feedback", [mine, echo])
    assert declared == "/my_controller" and whos == [echo.who]
    # The user restarted the controller: the first publisher there now takes its place.
    again = Endpoint("/", "my_controller", gid(3))
    whos, declared = strangers.look("command", "feedback", [again])
    assert declared == "/my_controller" and whos == []


def test_a_publisher_declared_when_subscribed_stays_declared_whatever_comes_first() -> None:
    strangers = Strangers(namespace="/", external_roles=["plant"])
    junk = Endpoint("/", "junk", gid(1))
    driver = Endpoint("/", "my_axis_driver", gid(2))
    strangers.declare("state", driver.gid)  # the one the subscription was made on
    strangers.declare("state", junk.gid)  # a later declaration does not replace it
    whos, declared = strangers.look("state", "plant", [junk, driver])
    assert declared == "/my_axis_driver" and whos == [junk.who]
    assert strangers.look("state", "plant", []) == ([], "its outside node")


def test_a_message_is_the_producers_only_if_its_publisher_plays_the_role() -> None:
    """By the GID of its publisher: the role's node in this namespace (any of its
    publishers: a restarted one too); any other a stranger; unnamed or unlisted not known
    yet, unless the judgment is final."""
    strangers = Strangers(namespace="/x", external_roles=[])
    plant, restarted = Endpoint("/x", "plant", gid(1)), Endpoint("/x", "plant", gid(5))
    other_axis, junk = Endpoint("/y", "plant", gid(2)), Endpoint("/x", "junk", gid(3))
    unnamed = Endpoint("/x", UNKNOWN_NODE_NAME, gid(4))
    listed = [plant, restarted, other_axis, junk, unnamed]
    judged = {e.gid: strangers.plays_role("state", "plant", listed, e.gid) for e in listed}
    assert judged == {gid(1): True, gid(5): True, gid(2): False, gid(3): False, gid(4): None}
    assert strangers.plays_role("state", "plant", listed, gid(4), final=True) is False
    assert strangers.plays_role("state", "plant", listed, gid(9)) is None  # not listed yet


def test_an_outside_role_is_never_declared_for_a_node_that_is_a_stranger_elsewhere() -> None:
    """A junk publisher on every topic, there before the outside plant, is a stranger on
    the topics of the roles the run started: it is not the outside plant, whatever it
    publishes first."""
    strangers = Strangers(namespace="/x", external_roles=["plant"])
    junk = Endpoint("/x", "junk", gid(1))
    sim = Endpoint("/x", "my_axis_sim", gid(2))

    def suspect(e: Endpoint) -> bool:
        return e.name == "junk"  # it also publishes `command`, the suite feedback's

    assert strangers.declared_outside("state", [junk], suspect) is None
    assert strangers.plays_role("state", "plant", [junk], junk.gid, suspect=suspect) is False
    assert strangers.declared_outside("state", [junk, sim], suspect) == sim.gid
    assert strangers.plays_role("state", "plant", [junk, sim], sim.gid, suspect=suspect)
    whos, declared = strangers.look("state", "plant", [junk, sim], suspect)
    assert declared == "/x/my_axis_sim" and whos == [junk.who]


def test_an_outside_publisher_the_graph_never_names_is_declared_after_the_grace() -> None:
    """A DDS application has no ROS node name: after the grace it may play the role."""
    now = [0.0]
    strangers = Strangers(
        namespace="/", external_roles=["plant"], unnamed_grace_s=2.0, clock=lambda: now[0]
    )
    app = Endpoint("/", UNKNOWN_NODE_NAME, gid(7))
    assert strangers.plays_role("state", "plant", [app], app.gid) is None
    now[0] = 2.0
    assert strangers.plays_role("state", "plant", [app], app.gid) is True
