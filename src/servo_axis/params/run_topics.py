"""The topics of a run: what is recorded, what is on, what each role publishes and must serve.

From the table of topics (:mod:`servo_axis.wire.topics`) and a scenario:
which topics its switches turn on (:func:`switched_on`) and its learning law
publishes (:func:`law_outputs`), what the recorder records by default
(:func:`recorder_topics`), which nodes run on the plant's clock
(:func:`sim_time_roles`), and what a node playing each role publishes and
takes (:func:`role_topics`), of which it must publish the topic that shows
it is there (:func:`presence_topic`) and take :data:`REQUIRED_INPUTS`; the
rest is optional. Each takes the scenario read once
(:class:`~servo_axis.params.resolve.Resolved`; a scenario dict is read
into one) and asks its checked values; :mod:`servo_axis.params.run_plan`
asks these once per axis. Nothing here imports rclpy.
"""

from __future__ import annotations

from typing import Any

from servo_axis.params import schemas
from servo_axis.params.factories import NODE_SCHEMAS, learning_law
from servo_axis.params.resolve import Resolved
from servo_axis.wire.topics import TOPICS, Topic, recorded_topics, topic

#: A scenario as these functions take it: read once, or a dict to read.
Scenario = Resolved | dict[str, Any]


def sim_time_roles() -> tuple[str, ...]:
    """The nodes that run on the plant's simulated time: the consumers of ``/clock``.

    The recorder records ``/clock`` but does not run on it as a ROS clock
    (it logs each message at the simulation time of its stamp,
    :mod:`servo_axis.recording.timeline`), so that its subscriptions are
    exactly the ones counted in the plant's ``wait_for_clock_subscribers``.
    """
    return topic("/clock").consumers


def recorder_topics(scenario: Scenario, roles: list[str]) -> tuple[list[str], list[str]]:
    """The topics (and their types) the recorder of a run of ``roles`` subscribes to.

    The recorder section's own ``topics`` (and ``types``) if it sets them,
    else every topic recorded by default whose producer runs, in the order
    of the table of topics.
    """
    resolved = Resolved.of(scenario)
    given = resolved.given("recorder")
    if "topics" in given:
        return list(given["topics"]), list(given.get("types", []))
    outputs = set(law_outputs(resolved)) if "learning" in roles else set()
    default = [
        t
        for t in recorded_topics(roles, switched_on(resolved))
        if t.producer != "learning" or t.name in outputs
    ]
    return [t.name for t in default], [t.type_name for t in default]


def switched_on(scenario: Scenario) -> list[str]:
    """The topics with an ``enabled_by`` switch that the scenario turns on.

    The switch's checked value where its producer runs, else its default.
    """
    resolved = Resolved.of(scenario)
    return [
        t.name
        for t in TOPICS
        if t.enabled_by
        and (
            resolved.values(t.producer)[t.enabled_by]
            if t.producer in resolved.roles
            else NODE_SCHEMAS[t.producer][t.enabled_by].default
        )
    ]


def law_outputs(scenario: Scenario) -> tuple[str, ...]:
    """The topics the learning unit of ``scenario`` publishes (its law's)."""
    resolved = Resolved.of(scenario)
    law = resolved.learning.law if resolved.has("learning") else schemas.LEARNING["law"].default
    return learning_law(law, "learning.law").outputs


#: What a node playing each role must subscribe to (their publishers wait for
#: it there): the samples it answers or learns from. Its other inputs are its
#: choice, and no publisher waits for them: ``/clock``, ``plant/status``, and
#: for a feedback ``reference`` (a regulator with its own set-point reads
#: ``state`` only; one that does subscribe to ``reference`` is waited for
#: there once its ``command`` is in the graph, as the reference is published
#: ahead and a volatile reader that matched late would miss the first samples:
#: :meth:`servo_axis.nodes.feedforward.FeedforwardNode._outside_feedback_reads`).
REQUIRED_INPUTS: dict[str, tuple[str, ...]] = {
    "plant": ("command",),
    "feedback": ("state",),
    "feedforward": (),
    "learning": ("state",),
    "identifier": ("state", "command"),
}

#: The topic whose publisher shows that a node playing the role is there.
PRESENCE_TOPICS = {
    "plant": "state",
    "feedback": "command",
    "feedforward": "reference",
    "identifier": "identifier/estimates",
}


def presence_topic(scenario: Scenario, role: str) -> str:
    """The output topic of ``role`` whose publisher shows that its node is there."""
    if role == "learning":
        return law_outputs(scenario)[0]
    return PRESENCE_TOPICS[role]


def role_topics(scenario: Scenario, roles: list[str], role: str) -> tuple[list[Topic], list[Topic]]:
    """What a node playing ``role`` in a run of ``roles`` publishes and subscribes to.

    The table's rows whose producer (consumer) is ``role``, less the topics
    the scenario leaves off (a switch such as ``deformation.enabled``, the
    outputs of learning laws other than the scenario's) and the inputs whose
    producer does not run. ``recorder/progress`` (the plant's flow control)
    is left to the suite's own plant.
    """
    resolved = Resolved.of(scenario)
    on = set(switched_on(resolved))
    laws = set(law_outputs(resolved)) if "learning" in roles else set()

    def live(t: Topic) -> bool:
        if t.enabled_by and t.name not in on:
            return False
        return t.producer != "learning" or t.name in laws

    publishes = [t for t in TOPICS if t.producer == role and live(t)]
    subscribes = [
        t
        for t in TOPICS
        if role in t.consumers and t.producer in roles and live(t) and t.name != "recorder/progress"
    ]
    return publishes, subscribes
