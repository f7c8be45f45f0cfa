"""From a scenario to the parameter file of a run.

What a node copies from the other sections of the scenario is the
resolver's (:func:`servo_axis.params.resolve.copied`, the same copies
``simulate`` and ``analysis`` make); the runner adds to it what only it
knows: whom each publisher
waits for before its first message (the subscriber counts, derived from the
table of topics in :mod:`servo_axis.wire.topics`), what the recorder
records and where, the target and the cycle the learning unit must learn
against, and simulated time for the nodes that follow the plant's clock.
Nothing here imports rclpy.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from servo_axis.params import schemas
from servo_axis.params.factories import NODE_SCHEMAS, checked_values, learning_law
from servo_axis.params.registry import term_files
from servo_axis.params.resolve import copied
from servo_axis.params.scenario import (
    ROLES,
    SHARED_SECTION,
    dump_params,
    node_params,
    resolve_table,
    shared,
)
from servo_axis.wire.topics import TOPICS, Topic, recorded_topics, subscriber_count, topic


def sim_time_roles() -> tuple[str, ...]:
    """The nodes that run on the plant's simulated time: the consumers of ``/clock``.

    The recorder records ``/clock`` but does not run on it as a ROS clock
    (it logs each message at the simulation time of its stamp,
    :mod:`servo_axis.recording.timeline`), so that its subscriptions are
    exactly the ones counted in the plant's ``wait_for_clock_subscribers``.
    """
    return topic("/clock").consumers


def recorder_topics(scenario: dict[str, Any], roles: list[str]) -> tuple[list[str], list[str]]:
    """The topics (and their types) the recorder of a run of ``roles`` subscribes to.

    The recorder section's own ``topics`` (and ``types``) if it sets them,
    else every topic recorded by default whose producer runs, in the order
    of the table of topics.
    """
    rec = node_params(scenario, "recorder")
    if "topics" in rec:
        return list(rec["topics"]), list(rec.get("types", []))
    outputs = set(law_outputs(scenario)) if "learning" in roles else set()
    default = [
        t
        for t in recorded_topics(roles, switched_on(scenario))
        if t.producer != "learning" or t.name in outputs
    ]
    return [t.name for t in default], [t.type_name for t in default]


def scheduled_topics(scenario: dict[str, Any], recorded: list[str]) -> dict[str, list[Any]]:
    """The plant's scheduled topics outside the per-sample streams, and their periods (lockstep).

    ``/clock`` every ``clock_every_steps`` and ``plant/status`` every
    ``status_every_steps`` samples from step 0: the recorder acknowledges a
    step only once those up to it are written (``final_topics``,
    ``final_every_steps``).
    """
    plant = checked_values("plant", node_params(scenario, "plant"))
    if plant["mode"] != "lockstep":
        return {}
    every = {"/clock": plant["clock_every_steps"], "plant/status": plant["status_every_steps"]}
    if not plant["publish_clock"]:
        every.pop("/clock")
    topics = [t for t in every if t in recorded]
    if not topics:
        return {}
    return {"final_topics": topics, "final_every_steps": [every[t] for t in topics]}


def switched_on(scenario: dict[str, Any]) -> list[str]:
    """The topics with an ``enabled_by`` switch that the scenario turns on."""
    return [
        t.name
        for t in TOPICS
        if t.enabled_by
        and node_params(scenario, t.producer).get(
            t.enabled_by, NODE_SCHEMAS[t.producer][t.enabled_by].default
        )
    ]


def law_outputs(scenario: dict[str, Any]) -> tuple[str, ...]:
    """The topics the learning unit of ``scenario`` publishes (its law's)."""
    law = node_params(scenario, "learning").get("law", schemas.LEARNING["law"].default)
    return learning_law(law, "learning.law").outputs


def handshake_overrides(
    scenario: dict[str, Any],
    roles: list[str],
    bag_dir: Path,
    scenario_dir: Path,
    external: tuple[str, ...] = (),
) -> dict[str, dict[str, Any]]:
    """Per-node parameters the runner adds to a scenario (flat, dotted keys).

    Parameters
    ----------
    scenario : dict
        A single-axis scenario (a multi-axis one through
        :func:`servo_axis.params.scenario.axis_view` first).
    roles : list of str
        The nodes that run (:func:`servo_axis.params.scenario.roles_of`).
    bag_dir : Path
        The bag directory the recorder creates; the learning unit's memory
        file goes next to it (``<run>/learning_memory.json``) unless the
        scenario names one.
    scenario_dir : Path
        The scenario file's folder: relative friction-table paths are
        relative to it.
    external : tuple of str
        The roles among ``roles`` that nodes from outside the suite play:
        counted like the others in the handshakes, given to every node as
        ``external_roles``.

    Returns
    -------
    dict
        ``{role: {key: value}}``: the plant waits for the subscribers of
        ``state``, ``/clock`` and ``plant/status`` (and, with a recorder, for
        its acknowledgements: ``flow_control``); the feedforward generator
        for those of ``reference``; the recorder gets ``output_dir`` and,
        unless its section lists them, the topics recorded by default; the
        learning unit gets ``reference.*`` and ``cycle_s`` of the
        feedforward section and ``sensor`` of the feedback section, the
        feedforward generator the learning section's ``law`` and, with an
        identifier, its schedule and initial ``U``, ``C`` (what the resolver
        copies, :func:`~servo_axis.params.resolve.copied`) and the terms'
        files made absolute; the
        identifier waits for the subscribers of ``identifier/estimates``
        and keeps its memory in ``<run>/identifier_memory.json``;
        feedback, feedforward and learning get ``use_sim_time: true``;
        every node gets ``report_dir`` (``<run>/logs``, where it writes its
        health report) and ``wait_for_producers`` (it subscribes to a topic
        only once the node the run started for its producer publishes it).
    """
    recorded: list[str] = []
    out: dict[str, dict[str, Any]] = {"plant": {}}

    def counted(name: str) -> bool:
        # Of an outside node's streams, flow control counts only the one its
        # role must publish (an outside feedback need not publish `deformation`).
        entry = topic(name)
        if entry.producer in external:
            return entry.counted and name == presence_topic(scenario, entry.producer)
        return entry.counted

    def count(name: str, roles: list[str], recorded: list[str]) -> int:
        # An outside node is waited for only on the inputs its role must take.
        counted = [r for r in roles if r not in external or name in REQUIRED_INPUTS[r]]
        return subscriber_count(name, counted, recorded)

    if "learning" in roles:
        out["learning"] = copied(scenario, "learning", roles)
        if "memory.file" not in node_params(scenario, "learning"):
            out["learning"]["memory.file"] = str(bag_dir.parent / "learning_memory.json")
    if "recorder" in roles:
        recorded, types = recorder_topics(scenario, roles)
        rec: dict[str, Any] = {}
        if "topics" not in node_params(scenario, "recorder"):
            rec.update(
                topics=recorded,
                types=types,
                counted_topics=[name for name in recorded if counted(name)],
            )
        rec["output_dir"] = str(bag_dir)
        rec.update(scheduled_topics(scenario, recorded))
        out["recorder"] = rec
        out["plant"]["flow_control"] = True
    if "identifier" in roles:
        ident = node_params(scenario, "identifier")
        out["identifier"] = {
            "wait_for_estimate_subscribers": count("identifier/estimates", roles, recorded)
        }
        if "memory.file" not in ident:
            out["identifier"]["memory.file"] = str(bag_dir.parent / "identifier_memory.json")
    if "learning" in roles:
        out["learning"].update(
            wait_for_correction_subscribers=count(law_outputs(scenario)[0], roles, recorded),
            wait_for_stats_subscribers=count("learning/cycle_stats", roles, recorded),
        )
    out["plant"].update(
        wait_for_state_subscribers=count("state", roles, recorded),
        wait_for_clock_subscribers=count("/clock", roles, recorded),
        wait_for_status_subscribers=count("plant/status", roles, recorded),
    )
    if "feedback" in roles:
        out.setdefault("feedback", {})["wait_for_command_subscribers"] = count(
            "command", roles, recorded
        )
    if "feedforward" in roles:
        ff: dict[str, Any] = {"wait_for_reference_subscribers": count("reference", roles, recorded)}
        given = node_params(scenario, "feedforward")
        for key in term_files():
            if given.get(key, ""):
                ff[key] = resolve_table(given[key], scenario_dir)
        ff.update(copied(scenario, "feedforward", roles))
        out["feedforward"] = ff
    for role in sim_time_roles():
        if role in roles:
            out.setdefault(role, {})["use_sim_time"] = True
    for role in roles:
        out.setdefault(role, {})["report_dir"] = str(bag_dir.parent / "logs")
        out[role]["wait_for_producers"] = True
    if external:
        for role in roles:
            out[role]["external_roles"] = list(external)
        if "recorder" in roles and any(
            topic(name).producer in external and topic(name).producer != "plant" and counted(name)
            for name in recorded
        ):
            out["plant"].update(outside_flow_control(scenario))
            out["recorder"]["ack_every_steps"] = min(
                out["plant"]["max_recorder_lag_steps"],
                node_params(scenario, "recorder").get(
                    "ack_every_steps", schemas.RECORDER["ack_every_steps"].default
                ),
            )
    return out


#: The keep-last depth of a publisher with rclpy's and rclcpp's default
#: profile: it drops a sample that a reliable reader has not taken once 10
#: newer ones are written.
OUTSIDE_PUBLISHER_DEPTH = 10


def outside_flow_control(scenario: dict[str, Any]) -> dict[str, int]:
    """The plant's lead over the recorder when an outside node publishes a counted stream.

    An outside feedback (or feedforward) that publishes ``command`` with the
    default keep-last 10 holds only its last 10 samples: a recorder more than
    10 steps behind lost the older ones for good (seen: commands 280-300 of
    an example controller's run, which then made no progress for 60 s).
    The plant publishes ``state[k]`` only once the recorder has step
    ``k - lag``, and such a node answers ``state[k]``, so at most ``lag + 1``
    of its samples wait for the recorder: ``lag`` is capped at
    ``OUTSIDE_PUBLISHER_DEPTH - 2``, whatever the scenario asks.
    """
    given = node_params(scenario, "plant").get(
        "max_recorder_lag_steps", schemas.PLANT["max_recorder_lag_steps"].default
    )
    return {"max_recorder_lag_steps": min(int(given), OUTSIDE_PUBLISHER_DEPTH - 2)}


def write_run_params(
    scenario: dict[str, Any], overrides: dict[str, dict[str, Any]], path: Path
) -> Path:
    """The parameter file the nodes of a run get: the scenario plus the overrides.

    Node sections are keyed ``/**/<node>`` so that they apply under any
    namespace; the file is kept in the run directory as the exact record of
    what ran.
    """
    out: dict[str, Any] = {SHARED_SECTION: {"ros__parameters": shared(scenario)}}
    for role in ROLES:
        if role not in scenario and role not in overrides:
            continue
        params = dict(scenario.get(role, {}).get("ros__parameters", {}))
        params.update(overrides.get(role, {}))
        out[f"/**/{role}"] = {"ros__parameters": params}
    path.write_text(dump_params(out))
    return path


#: What a node playing each role must subscribe to (their publishers wait for
#: it there): the samples it answers or learns from, and the reference a
#: feedback node follows (published ahead: a volatile reader that matched
#: late would never get the first samples). Its other inputs (``/clock`` for
#: a node without ``use_sim_time``) are its choice, and no publisher waits
#: for them.
REQUIRED_INPUTS: dict[str, tuple[str, ...]] = {
    "plant": ("command",),
    "feedback": ("state", "reference"),
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


def presence_topic(scenario: dict[str, Any], role: str) -> str:
    """The output topic of ``role`` whose publisher shows that its node is there."""
    if role == "learning":
        return law_outputs(scenario)[0]
    return PRESENCE_TOPICS[role]


def role_topics(
    scenario: dict[str, Any], roles: list[str], role: str
) -> tuple[list[Topic], list[Topic]]:
    """What a node playing ``role`` in a run of ``roles`` publishes and subscribes to.

    The table's rows whose producer (consumer) is ``role``, less the topics
    the scenario leaves off (a switch such as ``deformation.enabled``, the
    outputs of learning laws other than the scenario's) and the inputs whose
    producer does not run. ``recorder/progress`` (the plant's flow control)
    is left to the suite's own plant.
    """
    on = set(switched_on(scenario))
    laws = set(law_outputs(scenario)) if "learning" in roles else set()

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
