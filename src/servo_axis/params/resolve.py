"""The resolver: a scenario -> each node's checked values, the copies between sections written once.

Some values of a node come from another section of the scenario, one source
each: the feedforward generator takes the learning section's ``law``, the
identifier's schedule and initial ``U``, ``C`` (:func:`adaptive_overrides`),
the feedback's ``dob.*`` and what each installed term takes
(:func:`feedforward_overrides`); the learning unit takes the feedforward's
``reference.*`` and cycle and the feedback's ``sensor`` and, for a trial
law, its bandwidth (:func:`learning_overrides`). :func:`copied` gathers them
for a node, :func:`node_values` checks a node's section with them. The
runner (:mod:`servo_axis.params.run_params`) adds only what a run knows (handshakes,
paths in the run directory) on top of :func:`copied`; ``simulate`` and
``analysis`` use :func:`node_values`. Nothing here imports rclpy.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from servo_axis.params import schemas
from servo_axis.params.factories import (
    checked_values,
    identifier_method,
    learning_law,
    plant_model,
)
from servo_axis.params.registry import Values, feedforward_terms, term_files
from servo_axis.params.scenario import flatten, node_params, resolve_table, roles_of


def copied(
    scenario: dict[str, Any], role: str, roles: Sequence[str] | None = None
) -> dict[str, Any]:
    """What node ``role`` takes from the other sections of ``scenario`` (flat, dotted keys).

    The feedforward generator: :func:`feedforward_overrides`, the learning
    section's ``law`` (``learning.law``; it decides target- or input-side
    corrections) when the learning unit runs and its section names one,
    and, when an identifier runs, :func:`adaptive_overrides`. The learning
    unit: :func:`learning_overrides`. The feedback:
    :func:`feedback_overrides`. Other nodes take nothing. ``roles``
    are the nodes that run (default: those with a section,
    :func:`~servo_axis.params.scenario.roles_of`).
    """
    running = roles_of(scenario) if roles is None else roles
    if role == "feedforward":
        out = feedforward_overrides(scenario, node_params(scenario, "feedforward"))
        law = node_params(scenario, "learning").get("law")
        if "learning" in running and law is not None:
            out["learning.law"] = law  # one source: the learning section
        if "identifier" in running:
            out.update(adaptive_overrides(scenario))
        return out
    if role == "learning":
        return learning_overrides(scenario)
    if role == "feedback":
        return feedback_overrides(scenario)
    return {}


def node_values(scenario: dict[str, Any], role: str) -> dict[str, Any]:
    """Checked parameter values of one node of a scenario (no ROS), with what it copies.

    What the node itself checks and builds from the parameter file the runner
    writes (:func:`copied`; the runner's additions are handshakes and paths,
    which change no number).
    """
    return checked_values(role, {**node_params(scenario, role), **copied(scenario, role)})


def feedforward_values(scenario: dict[str, Any], scenario_path: Path) -> dict[str, Any]:
    """Checked feedforward values, the terms' file paths made absolute."""
    values = node_values(scenario, "feedforward")
    for key in term_files():
        values[key] = resolve_table(values[key], Path(scenario_path).resolve().parent)
    return values


def plant_fingerprint(scenario: dict[str, Any]) -> str:
    """``<model>:<16 hex>``: which plant a file identified on it belongs to.

    The SHA-256 of the checked values of the plant model's own keys (its
    physics, not the node's run settings) and the lead, as sorted JSON with
    floats in ``repr``; a GMS parameter file carries it, and the feedforward
    refuses a file of another plant.
    """
    values = node_values(scenario, "plant")
    entry = plant_model(values["model"])
    own = [
        k
        for k in sorted(entry.schema)
        if k not in entry.fingerprint_if_set or values[k] != entry.schema[k].default
    ]
    keys = [*own, "lead_m_per_rad"]
    text = json.dumps({k: values[k] for k in keys}, sort_keys=True)
    return f"{values['model']}:{hashlib.sha256(text.encode()).hexdigest()[:16]}"


def adaptive_overrides(scenario: dict[str, Any]) -> dict[str, Any]:
    """What the feedforward generator copies from the identifier section (one source each).

    The estimates' schedule (``adaptive.rls_period_s``, ``adaptive.latency_s``),
    the initial ``U``, ``C`` of the MNC until the first estimate applies, and
    whether it compensates friction (``mnc.friction``: the method estimates
    ``C``, DLPID, or not, the previous MARC, eq. (17)).
    """
    ident = node_params(scenario, "identifier")
    schema = schemas.IDENTIFIER
    method = ident.get("method", schema["method"].default)
    entry = identifier_method(method, "identifier.method")

    def value(key: str) -> Any:
        return ident.get(key, {**schema, **entry.schema}[key].default)

    out: dict[str, Any] = {
        "adaptive.enabled": True,
        "adaptive.rls_period_s": value("rls_period_s"),
        "adaptive.latency_s": value("latency_s"),
        "mnc.unbalance_Nm": value("initial.unbalance_Nm"),
        "mnc.friction": entry.estimates_friction,
    }
    if entry.estimates_friction:
        out["mnc.coulomb_Nm"] = value("initial.coulomb_Nm")
    return out


def feedforward_overrides(scenario: dict[str, Any], given: Values) -> dict[str, Any]:
    """What the feedforward copies from the other sections: one source for each value.

    ``dob.enabled`` and ``dob.cutoff_hz`` of the feedback, which the
    compensation terms bypass (:func:`~servo_axis.params.factories.build_terms`),
    and what each installed term takes from other sections
    (``FeedforwardTermEntry.overrides``: ``gms.plant``, the plant a GMS file
    must come from, when the GMS term is on).
    """
    feedback = node_params(scenario, "feedback")
    out = {
        key: feedback.get(key, schemas.FEEDBACK[key].default)
        for key in ("dob.enabled", "dob.cutoff_hz")
    }
    for _, term in feedforward_terms():
        out.update(term.overrides(scenario, given))
    return out


def feedback_overrides(scenario: dict[str, Any]) -> dict[str, Any]:
    """What the feedback copies from the other sections: the feedforward's ``sigmoid.*``.

    With ``sigmoid.source: stage`` the law of 004 eq. (9) takes its sign and
    distance from the measured stage: the loop computes it
    (:func:`~servo_axis.params.factories.build_loop`), from the values the
    feedforward section sets (one source) or its term's defaults.
    """
    ff = node_params(scenario, "feedforward")
    return {key: ff.get(key, param.default) for key, param in schemas.FEEDBACK_SIGMOID.items()}


def learning_overrides(scenario: dict[str, Any]) -> dict[str, Any]:
    """What the learning unit copies from the other sections: one source for each value.

    It learns against the feedforward generator's original target
    (``reference.*``) over its cycle (``learning.cycle_s``), and against
    the controlled output of the feedback loop (``sensor``, when the
    feedback section sets it); a trial law's learning filter inverts the
    loop's own ``S_n P_n`` (``feedback.bandwidth_hz``).
    """
    ff = node_params(scenario, "feedforward")
    out = {k: v for k, v in ff.items() if k.startswith("reference.")}
    out["cycle_s"] = ff.get("learning.cycle_s", schemas.FEEDFORWARD["learning.cycle_s"].default)
    feedback = flatten(scenario.get("feedback", {}).get("ros__parameters", {}))
    if "sensor" in feedback:
        out["sensor"] = feedback["sensor"]
    law = node_params(scenario, "learning").get("law", schemas.LEARNING["law"].default)
    if learning_law(law, "learning.law").period == "trial":
        out["feedback.bandwidth_hz"] = feedback.get(
            "bandwidth_hz", schemas.FEEDBACK["bandwidth_hz"].default
        )
    return out
