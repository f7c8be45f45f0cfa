"""The resolver: a scenario -> each node's typed values, checked once; the copies between sections.

Some values of a node come from another section of the scenario, one source
each: the feedforward generator takes the learning section's ``law``, the
identifier's schedule and initial ``U``, ``C`` (:func:`adaptive_overrides`),
the feedback's ``dob.*`` and what each installed term takes
(:func:`feedforward_overrides`); the learning unit takes the feedforward's
``reference.*`` and cycle and the feedback's ``sensor`` and, for a trial
law, its bandwidth (:func:`learning_overrides`); the feedback the
feedforward's ``sigmoid.*`` (:func:`feedback_overrides`).

:class:`Resolved` is a single-axis scenario read once: each section's given
keys flattened once (:meth:`Resolved.given`), each node's copies gathered
once (:meth:`Resolved.copied`) and each node's values checked once, when
first asked (:meth:`Resolved.values`, ``resolved.plant``, ...): typed values
(:mod:`servo_axis.params.typed`) that everything after reads as attributes.
The run's plan (:mod:`servo_axis.params.run_plan`) makes one per axis and
hands it to the summary; ``simulate``, the analysis and the identification
make one of the scenario they are given (:meth:`Resolved.of`). Nothing here
imports rclpy.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from servo_axis.params import schemas
from servo_axis.params.factories import (
    checked_values,
    identifier_method,
    learning_law,
    plant_model,
)
from servo_axis.params.registry import feedforward_terms, term_files
from servo_axis.params.scenario import ROLES, flatten, node_params, resolve_table, roles_of
from servo_axis.params.typed import Values
from servo_axis.params.values import (
    FeedbackValues,
    FeedforwardValues,
    IdentifierValues,
    LearningValues,
    PlantValues,
    RecorderValues,
)


class Resolved:
    """A single-axis scenario's sections, read once, and each node's values, checked once.

    Parameters
    ----------
    scenario : dict
        The single-axis scenario (a multi-axis one through
        :func:`~servo_axis.params.scenario.axis_view` first).
    path : Path or None
        Its file: the relative file paths of the feedforward terms
        (``friction_table.file``, ...) are made absolute against its folder
        (None: left as given).
    roles : sequence of str or None
        The nodes that run (default: those with a section,
        :func:`~servo_axis.params.scenario.roles_of`): what the copies take
        from (the feedforward takes the learning section's ``law`` only when
        the learning unit runs).
    known : mapping or None
        Values already resolved, by role (the plan's, handed to the
        summary): not checked again.
    """

    def __init__(
        self,
        scenario: Mapping[str, Any],
        path: Path | None = None,
        *,
        roles: Sequence[str] | None = None,
        known: Mapping[str, Values] | None = None,
    ) -> None:
        self.scenario = scenario
        self.path = Path(path) if path is not None else None
        self.roles: tuple[str, ...] = tuple(roles_of(dict(scenario)) if roles is None else roles)
        self._given: dict[str, dict[str, Any]] = {}
        self._sections: dict[str, dict[str, Any]] = {}
        self._copied: dict[str, dict[str, Any]] = {}
        self._values: dict[str, Values] = dict(known or {})

    @classmethod
    def of(cls, scenario: Resolved | Mapping[str, Any], path: Path | None = None) -> Resolved:
        """``scenario`` if already resolved, else a :class:`Resolved` of it."""
        return scenario if isinstance(scenario, Resolved) else cls(scenario, path)

    def has(self, role: str) -> bool:
        """Whether the scenario has a section for ``role`` (its node runs)."""
        return role in self.scenario

    def given(self, role: str) -> dict[str, Any]:
        """The keys the scenario gives node ``role``: its section on top of the shared block, dotted."""
        if role not in self._given:
            self._given[role] = node_params(dict(self.scenario), role)
        return self._given[role]

    def section(self, role: str) -> dict[str, Any]:
        """The keys of ``role``'s own section alone (without the shared block), dotted."""
        if role not in self._sections:
            own = self.scenario.get(role, {}).get("ros__parameters", {})
            self._sections[role] = flatten(own)
        return self._sections[role]

    def copied(self, role: str) -> dict[str, Any]:
        """What node ``role`` takes from the other sections (flat, dotted keys; :func:`copied`)."""
        if role not in self._copied:
            self._copied[role] = _copies(self, role)
        return self._copied[role]

    def values(self, role: str) -> Any:
        """The checked values of node ``role`` with what it copies (checked the first time asked).

        The feedforward's term files are absolute when :attr:`path` is known.

        Raises
        ------
        ParameterFileError
            Naming the key at fault (the same the node would name).
        """
        if role not in self._values:
            values = checked_values(role, {**self.given(role), **self.copied(role)})
            if role == "feedforward" and self.path is not None:
                folder = self.path.resolve().parent
                values = values.with_keys(
                    {key: resolve_table(values[key], folder) for key in term_files()}
                )
            self._values[role] = values
        return self._values[role]

    @property
    def plant(self) -> PlantValues:
        """The plant's values (its model's class)."""
        values: PlantValues = self.values("plant")
        return values

    @property
    def feedback(self) -> FeedbackValues:
        """The feedback's values."""
        values: FeedbackValues = self.values("feedback")
        return values

    @property
    def feedforward(self) -> FeedforwardValues:
        """The feedforward generator's values (every installed term's keys)."""
        values: FeedforwardValues = self.values("feedforward")
        return values

    @property
    def learning(self) -> LearningValues:
        """The learning unit's values (its law's class)."""
        values: LearningValues = self.values("learning")
        return values

    @property
    def identifier(self) -> IdentifierValues:
        """The identifier's values (its method's class)."""
        values: IdentifierValues = self.values("identifier")
        return values

    @property
    def recorder(self) -> RecorderValues:
        """The recorder's values."""
        values: RecorderValues = self.values("recorder")
        return values

    def known(self) -> dict[str, Values]:
        """The values resolved so far, by role."""
        return dict(self._values)


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
    return Resolved(scenario, roles=roles).copied(role)


def _copies(resolved: Resolved, role: str) -> dict[str, Any]:
    if role == "feedforward":
        out = feedforward_overrides(resolved, resolved.given("feedforward"))
        law = resolved.given("learning").get("law")
        if "learning" in resolved.roles and law is not None:
            out["learning.law"] = law  # one source: the learning section
        if "identifier" in resolved.roles:
            out.update(adaptive_overrides(resolved))
        return out
    if role == "learning":
        return learning_overrides(resolved)
    if role == "feedback":
        return feedback_overrides(resolved)
    if role not in ROLES:
        raise KeyError(role)
    return {}


def node_values(scenario: dict[str, Any] | Resolved, role: str) -> Any:
    """Checked parameter values of one node of a scenario (no ROS), with what it copies.

    What the node itself checks and builds from the parameter file the runner
    writes (:func:`copied`; the runner's additions are handshakes and paths,
    which change no number). A scenario asked several questions is better
    read once: :class:`Resolved`.
    """
    return Resolved.of(scenario).values(role)


def feedforward_values(scenario: dict[str, Any], scenario_path: Path) -> Any:
    """Checked feedforward values, the terms' file paths made absolute."""
    return Resolved(scenario, scenario_path).feedforward


def plant_fingerprint(scenario: dict[str, Any] | Resolved) -> str:
    """``<model>:<16 hex>``: which plant a file identified on it belongs to.

    The SHA-256 of the checked values of the plant model's own keys (its
    physics, not the node's run settings) and the lead, as sorted JSON with
    floats in ``repr``; a GMS parameter file carries it, and the feedforward
    refuses a file of another plant.
    """
    values = Resolved.of(scenario).plant
    entry = plant_model(values.model)
    own = [
        k
        for k in sorted(entry.schema)
        if k not in entry.fingerprint_if_set or values[k] != entry.schema[k].default
    ]
    keys = [*own, "lead_m_per_rad"]
    text = json.dumps({k: values[k] for k in keys}, sort_keys=True)
    return f"{values.model}:{hashlib.sha256(text.encode()).hexdigest()[:16]}"


def adaptive_overrides(scenario: dict[str, Any] | Resolved) -> dict[str, Any]:
    """What the feedforward generator copies from the identifier section (one source each).

    The estimates' schedule (``adaptive.rls_period_s``, ``adaptive.latency_s``),
    the initial ``U``, ``C`` of the MNC until the first estimate applies, and
    whether it compensates friction (``mnc.friction``: the method estimates
    ``C``, DLPID, or not, the previous MARC, eq. (17)).
    """
    ident = Resolved.of(scenario).given("identifier")
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


def feedforward_overrides(
    scenario: dict[str, Any] | Resolved, given: Mapping[str, Any]
) -> dict[str, Any]:
    """What the feedforward copies from the other sections: one source for each value.

    ``dob.enabled`` and ``dob.cutoff_hz`` of the feedback, which the
    compensation terms bypass (:func:`~servo_axis.params.factories.build_terms`),
    and what each installed term takes from other sections
    (``FeedforwardTermEntry.overrides(resolved, given)``: ``gms.plant``, the
    plant a GMS file must come from, when the GMS term is on).
    """
    resolved = Resolved.of(scenario)
    feedback = resolved.given("feedback")
    out = {
        key: feedback.get(key, schemas.FEEDBACK[key].default)
        for key in ("dob.enabled", "dob.cutoff_hz")
    }
    for _, term in feedforward_terms():
        out.update(term.overrides(resolved, given))
    return out


def feedback_overrides(scenario: dict[str, Any] | Resolved) -> dict[str, Any]:
    """What the feedback copies from the other sections: the feedforward's ``sigmoid.*``.

    With ``sigmoid.source: stage`` the law of 004 eq. (9) takes its sign and
    distance from the measured stage: the loop computes it
    (:func:`~servo_axis.params.factories.build_loop`), from the values the
    feedforward section sets (one source) or its term's defaults.
    """
    ff = Resolved.of(scenario).given("feedforward")
    return {key: ff.get(key, param.default) for key, param in schemas.FEEDBACK_SIGMOID.items()}


def learning_overrides(scenario: dict[str, Any] | Resolved) -> dict[str, Any]:
    """What the learning unit copies from the other sections: one source for each value.

    It learns against the feedforward generator's original target
    (``reference.*``) over its cycle (``learning.cycle_s``), and against
    the controlled output of the feedback loop (``sensor``, when the
    feedback section sets it); a trial law's learning filter inverts the
    loop's own ``S_n P_n`` (``feedback.bandwidth_hz``).
    """
    resolved = Resolved.of(scenario)
    ff = resolved.given("feedforward")
    out = {k: v for k, v in ff.items() if k.startswith("reference.")}
    out["cycle_s"] = ff.get("learning.cycle_s", schemas.FEEDFORWARD["learning.cycle_s"].default)
    feedback = resolved.section("feedback")
    if "sensor" in feedback:
        out["sensor"] = feedback["sensor"]
    law = resolved.given("learning").get("law", schemas.LEARNING["law"].default)
    if learning_law(law, "learning.law").period == "trial":
        out["feedback.bandwidth_hz"] = feedback.get(
            "bandwidth_hz", schemas.FEEDBACK["bandwidth_hz"].default
        )
    return out
