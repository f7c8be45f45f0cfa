"""From a scenario to the parameter file of a run.

What a node copies from the other sections of the scenario is the
resolver's (:func:`servo_axis.params.resolve.copied`, the same copies
``simulate`` and ``analysis`` make); a run adds to it what only a run
knows: whom each publisher waits for before its first message (the start
handshakes, :class:`Handshake`: subscriber counts derived from the table of
topics in :mod:`servo_axis.wire.topics` and the run's topics,
:mod:`servo_axis.params.run_topics`), what the recorder records and where,
the target and the cycle the learning unit must learn against, simulated
time for the nodes that follow the plant's clock, the roles outside nodes
play (:func:`external_roles_of`) and the namespace of a single-axis run
(:func:`single_axis_namespace`). Each function takes the scenario read once
(:class:`~servo_axis.params.resolve.Resolved`; a scenario dict is read into
one) and asks its checked values; :mod:`servo_axis.params.run_plan` gathers
all of it into the run's plan. Nothing here imports rclpy.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servo_axis.core.errors import ConfigError, ParameterFileError, did_you_mean
from servo_axis.params.factories import EXTERNAL_ROLES
from servo_axis.params.registry import term_files
from servo_axis.params.resolve import Resolved
from servo_axis.params.run_topics import (
    REQUIRED_INPUTS,
    Scenario,
    law_outputs,
    presence_topic,
    recorder_topics,
    sim_time_roles,
)
from servo_axis.params.scenario import (
    ROLES,
    SHARED_SECTION,
    dump_params,
    resolve_table,
    shared,
)
from servo_axis.wire.topics import subscriber_count, topic


def scheduled_topics(scenario: Scenario, recorded: list[str]) -> dict[str, list[Any]]:
    """The plant's scheduled topics outside the per-sample streams, and their periods (lockstep).

    ``/clock`` every ``clock_every_steps`` and ``plant/status`` every
    ``status_every_steps`` samples from step 0: the recorder acknowledges a
    step only once those up to it are written (``final_topics``,
    ``final_every_steps``).
    """
    plant = Resolved.of(scenario).plant
    if plant.mode != "lockstep":
        return {}
    every = {"/clock": plant.clock_every_steps, "plant/status": plant.status_every_steps}
    if not plant.publish_clock:
        every.pop("/clock")
    topics = [t for t in every if t in recorded]
    if not topics:
        return {}
    return {"final_topics": topics, "final_every_steps": [every[t] for t in topics]}


@dataclass(frozen=True)
class Handshake:
    """A start handshake: the node of ``role`` publishes ``topic`` once it has ``subscribers`` readers.

    Attributes
    ----------
    role : str
        The publishing node.
    key : str
        Its parameter that holds the count (``wait_for_state_subscribers``).
    topic : str
        The topic (relative to the axis namespace, ``/clock`` absolute).
    subscribers : int
        The readers it waits for, >= 0.
    """

    role: str
    key: str
    topic: str
    subscribers: int


#: Every start handshake: (publisher, its parameter, topic). ``""`` is the
#: learning law's first output (:func:`law_outputs`).
HANDSHAKES: tuple[tuple[str, str, str], ...] = (
    ("identifier", "wait_for_estimate_subscribers", "identifier/estimates"),
    ("learning", "wait_for_correction_subscribers", ""),
    ("learning", "wait_for_stats_subscribers", "learning/cycle_stats"),
    ("plant", "wait_for_state_subscribers", "state"),
    ("plant", "wait_for_clock_subscribers", "/clock"),
    ("plant", "wait_for_status_subscribers", "plant/status"),
    ("feedback", "wait_for_command_subscribers", "command"),
    ("feedforward", "wait_for_reference_subscribers", "reference"),
)


def handshakes(
    scenario: Scenario,
    roles: list[str],
    recorded: list[str],
    external: tuple[str, ...] = (),
) -> list[Handshake]:
    """The start handshakes of a run of ``roles`` whose recorder records ``recorded``.

    Each publisher waits for the consumers of its topic in the table that
    run, the recorder if it records the topic; an outside node is counted
    only on the inputs its role must take (:data:`REQUIRED_INPUTS`). The
    plant's are always there; the others' only when their node runs.
    """
    resolved = Resolved.of(scenario)
    out = []
    for role, key, name in HANDSHAKES:
        if role != "plant" and role not in roles:
            continue
        name = name or law_outputs(resolved)[0]
        counted = [r for r in roles if r not in external or name in REQUIRED_INPUTS[r]]
        out.append(Handshake(role, key, name, subscriber_count(name, counted, recorded)))
    return out


def handshake_overrides(
    scenario: Scenario,
    roles: list[str],
    bag_dir: Path,
    scenario_dir: Path,
    external: tuple[str, ...] = (),
) -> dict[str, dict[str, Any]]:
    """Per-node parameters the runner adds to a scenario (flat, dotted keys).

    Parameters
    ----------
    scenario : Resolved or dict
        A single-axis scenario (a multi-axis one through
        :func:`servo_axis.params.scenario.axis_view` first), read once.
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
    # The copies are those of the nodes that run (``roles``).
    resolved = scenario if isinstance(scenario, Resolved) else Resolved(scenario, roles=roles)
    recorded = recorder_topics(resolved, roles)[0] if "recorder" in roles else []
    waits: dict[str, dict[str, Any]] = {}
    for shake in handshakes(resolved, roles, recorded, external):
        waits.setdefault(shake.role, {})[shake.key] = shake.subscribers
    out: dict[str, dict[str, Any]] = {"plant": {}}
    if "learning" in roles:
        out["learning"] = dict(resolved.copied("learning"))
        if "memory.file" not in resolved.given("learning"):
            out["learning"]["memory.file"] = str(bag_dir.parent / "learning_memory.json")
    if "recorder" in roles:
        out["recorder"] = _recorder_overrides(resolved, roles, bag_dir, external)
        out["plant"]["flow_control"] = True
    if "identifier" in roles:
        out["identifier"] = dict(waits["identifier"])
        if "memory.file" not in resolved.given("identifier"):
            out["identifier"]["memory.file"] = str(bag_dir.parent / "identifier_memory.json")
    if "learning" in roles:
        out["learning"].update(waits["learning"])
    out["plant"].update(waits["plant"])
    if "feedback" in roles:
        out["feedback"] = {**waits["feedback"], **resolved.copied("feedback")}
    if "feedforward" in roles:
        given = resolved.given("feedforward")
        files = {
            key: resolve_table(given[key], scenario_dir)
            for key in term_files()
            if given.get(key, "")
        }
        out["feedforward"] = {
            **waits["feedforward"],
            **files,
            **resolved.copied("feedforward"),
        }
    _for_every_node(out, roles, bag_dir, external)
    if "plant" in external:
        _outside_plant(out, resolved, roles, recorded, external)
    if external and "recorder" in roles and _outside_counted(resolved, recorded, external):
        out["plant"].update(outside_flow_control(resolved))
        out["recorder"]["ack_every_steps"] = min(
            out["plant"]["max_recorder_lag_steps"], resolved.recorder.ack_every_steps
        )
    return out


def _outside_plant(
    out: dict[str, dict[str, Any]],
    resolved: Resolved,
    roles: list[str],
    recorded: list[str],
    external: tuple[str, ...],
) -> None:
    """What the suite's nodes do for an outside plant, which needs only ``state`` and ``command``.

    Such a plant meets one start rule: it publishes ``state[0]`` once
    ``command`` has a publisher. So the suite's feedback makes its
    ``command`` publisher only once the run's readers of ``state`` are all
    subscribed (``wait_for_state_readers``: the plant's own count, the
    feedforward's reader included). The feedforward tops its preview up on
    the stamps of ``state`` (``progress_from_state``), not on
    ``plant/status``; the recorder's progress counts the steps of the
    streams, not ``/clock`` or ``plant/status`` messages
    (:func:`scheduled_topics` leaves them out). In lockstep with a recorder,
    the feedback answers ``state[k]`` only once the recorder has step
    ``k + 1 - lag`` (``recorder_lag_steps``, :func:`outside_flow_control`):
    a plant that answers ``command[k]`` with ``state[k + 1]`` then never has
    more than ``lag + 1`` states unrecorded, within a keep-last 10 writer.
    """
    readers = out["plant"].get("wait_for_state_subscribers", 0)
    if "feedforward" in roles:
        out["feedforward"]["progress_from_state"] = True
        readers += 1
        # ... and does not read plant/status: a plant that publishes it (the
        # suite's node started by hand) must not wait for the feedforward there.
        status = out["plant"].get("wait_for_status_subscribers", 0)
        out["plant"]["wait_for_status_subscribers"] = max(0, status - 1)
    if "feedback" in roles and "feedback" not in external:
        out["feedback"]["wait_for_state_readers"] = readers
        lockstep = resolved.plant.mode == "lockstep"
        if lockstep and "recorder" in roles:
            lag = outside_flow_control(resolved)["max_recorder_lag_steps"]
            out["feedback"]["recorder_lag_steps"] = lag
            out["recorder"]["ack_every_steps"] = min(lag, resolved.recorder.ack_every_steps)


def drive_setpoints(scenario: Scenario) -> bool:
    """Whether the plant takes ``command`` as a drive's set-point (``command_source``)."""
    return Resolved.of(scenario).plant.command_source == "drive_setpoint"


def _counted(scenario: Scenario, name: str, external: tuple[str, ...]) -> bool:
    """Whether the recorder counts ``name`` in its progress.

    Of an outside node's streams, flow control counts only the one its role
    must publish (an outside feedback need not publish ``deformation``). A
    drive's set-points (``command_source: drive_setpoint``) are of no step:
    recorded, never counted.
    """
    if name == "command" and drive_setpoints(scenario):
        return False
    entry = topic(name)
    if entry.producer in external:
        return entry.counted and name == presence_topic(scenario, entry.producer)
    return entry.counted


def _recorder_overrides(
    resolved: Resolved, roles: list[str], bag_dir: Path, external: tuple[str, ...]
) -> dict[str, Any]:
    """The recorder's: its topics unless its section lists them, its bag, the plant's schedule."""
    recorded, types = recorder_topics(resolved, roles)
    rec: dict[str, Any] = {}
    if "topics" not in resolved.given("recorder"):
        rec.update(
            topics=recorded,
            types=types,
            counted_topics=[name for name in recorded if _counted(resolved, name, external)],
        )
    rec["output_dir"] = str(bag_dir)
    if "plant" not in external:  # an outside plant need publish neither
        rec.update(scheduled_topics(resolved, recorded))
    return rec


def _for_every_node(
    out: dict[str, dict[str, Any]], roles: list[str], bag_dir: Path, external: tuple[str, ...]
) -> None:
    """Simulated time for the consumers of ``/clock``; report directory, producers, outside roles."""
    for role in sim_time_roles():
        if role in roles:
            out.setdefault(role, {})["use_sim_time"] = True
    for role in roles:
        out.setdefault(role, {})["report_dir"] = str(bag_dir.parent / "logs")
        out[role]["wait_for_producers"] = True
    for role in roles if external else ():
        out[role]["external_roles"] = list(external)


def _outside_counted(resolved: Resolved, recorded: list[str], external: tuple[str, ...]) -> bool:
    """Whether an outside node other than the plant publishes a stream the recorder counts."""
    return any(
        topic(name).producer in external
        and topic(name).producer != "plant"
        and _counted(resolved, name, external)
        for name in recorded
    )


#: The keep-last depth of a publisher with rclpy's and rclcpp's default
#: profile: it drops a sample that a reliable reader has not taken once 10
#: newer ones are written.
OUTSIDE_PUBLISHER_DEPTH = 10


def outside_flow_control(scenario: Scenario) -> dict[str, int]:
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
    lag = Resolved.of(scenario).plant.max_recorder_lag_steps
    return {"max_recorder_lag_steps": min(lag, OUTSIDE_PUBLISHER_DEPTH - 2)}


def run_params(scenario: Scenario, overrides: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The parameter file the nodes of a run get: the scenario plus the overrides.

    Node sections are keyed ``/**/<node>`` so that they apply under any
    namespace; the file is kept in the run directory as the exact record of
    what ran: each section as the scenario gives it, not its checked values.
    """
    scenario = dict(Resolved.of(scenario).scenario)
    out: dict[str, Any] = {SHARED_SECTION: {"ros__parameters": shared(scenario)}}
    for role in ROLES:
        if role not in scenario and role not in overrides:
            continue
        params = dict(scenario.get(role, {}).get("ros__parameters", {}))
        params.update(overrides.get(role, {}))
        out[f"/**/{role}"] = {"ros__parameters": params}
    return out


def write_run_params(scenario: Scenario, overrides: dict[str, dict[str, Any]], path: Path) -> Path:
    """Write :func:`run_params` to ``path`` (every string quoted, as rcl must read it)."""
    path.write_text(dump_params(run_params(scenario, overrides)))
    return path


def external_roles_of(scenario: Scenario, given: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The roles outside nodes play: ``given`` (``--external``) and the scenario's ``external_roles``.

    Raises
    ------
    ConfigError
        For a role that is not one an outside node can play.
    """
    listed = [r for r in Resolved.of(scenario).plant.external_roles if r]
    roles = tuple(dict.fromkeys([*given, *listed]))
    for role in roles:
        if role not in EXTERNAL_ROLES:
            hint = did_you_mean(role, EXTERNAL_ROLES)
            raise ConfigError(
                f"--external {role}: expected one of {', '.join(EXTERNAL_ROLES)}"
                + (f"; {hint}" if hint else "")
            )
    return roles


def single_axis_namespace(scenario: Scenario, namespace: str = "") -> str:
    """The namespace of a single-axis run: ``namespace`` if given, else ``/<axis>``.

    ``"/"`` is the root (returned as ``""``: the nodes start without a
    namespace remap). The default is the scenario's shared key ``axis``
    (``/x``): the nodes are ``/x/plant``, ``/x/feedback``, ... and the
    topics ``/x/state``, ``/x/command``, ...; ``/clock`` and
    ``/diagnostics`` stay absolute.

    Raises
    ------
    ParameterFileError
        For an ``axis`` that cannot name a ROS namespace.
    """
    if namespace:
        return "" if namespace == "/" else namespace
    axis = Resolved.of(scenario).plant.axis
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", axis):
        raise ParameterFileError(
            f"parameter 'axis': {axis!r} cannot name the run's ROS namespace /<axis> (a "
            "letter, then letters, digits or _); rename it or give --namespace"
        )
    return f"/{axis}"
