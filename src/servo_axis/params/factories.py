"""Factories: checked (typed) parameter values -> core objects, and the checks of each node's keys.

The nodes, the headless simulation (:mod:`servo_axis.simulate`) and the
reports build the same objects from the same checked values through these
functions. :func:`checked_values` turns a node's given keys into its typed
values (:mod:`servo_axis.params.typed`; the class of each node in
:mod:`servo_axis.params.values`), checking each key against its schema, then
what depends on several keys (:func:`check_consistency`: the node's own
checks here, its model's, law's, method's and terms' ``check`` in their
modules), without building any core object to do it: a check computes only
what the builder computes first (a period in samples, the PID's gains, a
frozen parameter record), and the node builds its object once, from the
same values.

The extension points (plant models, feedforward terms, learning laws,
identification methods) are the installed entry points of
:mod:`servo_axis.params.registry`; each is one module of its own (the
suite's in :mod:`servo_axis.plugins`), and this module only looks them up by
the name a scenario gives (``plant.model``, ``learning.law``,
``identifier.method``; every installed term is asked whether its keys switch
it on).

Nothing here imports rclpy.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np

from servo_axis.core.deformation import DeformationRatio
from servo_axis.core.errors import ParameterFileError
from servo_axis.core.feedback.dob import DisturbanceObserver, OutsideObserver, check_cutoff
from servo_axis.core.feedback.loop import FeedbackLoop, SafetyLimits
from servo_axis.core.feedback.pid import DiscretePid, PidGains, design_pid_pole_placement
from servo_axis.core.feedback.stage_sigmoid import StageSigmoid
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.core.feedforward.sigmoid import SigmoidParams
from servo_axis.core.feedforward.terms import FeedforwardTerm
from servo_axis.core.identification.online.base import OnlineIdentifier
from servo_axis.core.learning.base import LearningLaw
from servo_axis.core.models.base import NominalModel, Plant
from servo_axis.core.reference import Reference, make_reference
from servo_axis.core.timing import SampleGrid
from servo_axis.params import schemas
from servo_axis.params.param import Param, build, check_values
from servo_axis.params.registry import FEEDFORWARD_TERMS as FEEDFORWARD_TERMS
from servo_axis.params.registry import IDENTIFIERS as IDENTIFIERS
from servo_axis.params.registry import LEARNING_LAWS as LEARNING_LAWS
from servo_axis.params.registry import PLANT_MODELS as PLANT_MODELS
from servo_axis.params.registry import FeedforwardTermEntry as FeedforwardTermEntry
from servo_axis.params.registry import IdentifierEntry as IdentifierEntry
from servo_axis.params.registry import LearningLawEntry as LearningLawEntry
from servo_axis.params.registry import PlantModelEntry as PlantModelEntry
from servo_axis.params.registry import feedforward_class, feedforward_terms
from servo_axis.params.topic_checks import (
    check_command_source,
    check_forward_topic,
    check_recorder_topics,
)
from servo_axis.params.typed import Values, from_flat
from servo_axis.params.values import (
    FeedbackValues,
    FeedforwardValues,
    IdentifierValues,
    LearningValues,
    PlantValues,
    RecorderValues,
    ReferenceKeys,
    SharedValues,
)

#: The keys of the ``nominal.*`` values, by the names the core constructors give them.
NOMINAL_KEYS = {
    name: f"nominal.{name}"
    for name in ("torque_constant_Nm_per_A", "inertia_kgm2", "damping_Nms_per_rad")
}
#: The key of the control period where a core constructor calls it ``period_s``.
PERIOD_KEYS = {"period_s": "control_period_s"}
#: Integration steps per control period and per dead time a plant may take
#: (``control_period_s / sim_step_s``, ``dead_time_s / sim_step_s``): more
#: would not run in any useful time, or not fit in memory.
MAX_SIM_STEPS = 100_000
#: Reference instants a learning cycle may hold (its arrays are this long).
MAX_CYCLE_INSTANTS = 1_000_000

# --------------------------------------------------------------------------- common


def grid(values: SharedValues) -> SampleGrid:
    """The sample grid (``T_u``, ``T_r = 2 T_u``) of a node's values."""
    return build("", SampleGrid, control_period_s=values.control_period_s)


def run_steps(values: SharedValues) -> int:
    """Control samples of the run (``duration_s / control_period_s``, at least 1)."""
    return build("", grid(values).steps, duration_s=values.duration_s)


def nominal_model(values: SharedValues) -> NominalModel:
    """The nominal model ``P_n`` of eq. (1) (the shared ``nominal.*`` keys)."""
    n = values.nominal
    return build(
        "nominal.",
        NominalModel,
        keys=NOMINAL_KEYS,
        torque_constant_Nm_per_A=n.torque_constant_Nm_per_A,
        inertia_kgm2=n.inertia_kgm2,
        damping_Nms_per_rad=n.damping_Nms_per_rad,
    )


#: Which reference.* keys each kind takes.
REFERENCE_KEYS = {
    "sine": ("amplitude_m", "frequency_hz", "offset_m", "phase_rad", "ramp_s"),
    "one_minus_cos": ("amplitude_m", "frequency_hz"),
    "point_to_point": ("distance_m", "move_time_s", "dwell_s"),
    "trials": (
        "trial_s",
        "amplitudes_m",
        "move_times_s",
        "start_times_s",
        "first_trials",
        "offset_m",
    ),
    "segments": ("segment_distances_m", "segment_durations_s", "segment_delay_s", "offset_m"),
}


def build_reference(values: FeedforwardValues | LearningValues) -> Reference:
    """The table-side reference of the ``reference.*`` keys."""
    ref: ReferenceKeys = values.reference
    kind = ref.kind
    if kind not in REFERENCE_KEYS:
        raise ParameterFileError(
            f"parameter 'reference.kind': expected one of {sorted(REFERENCE_KEYS)}, got {kind!r}"
        )
    # The segments' keys carry a prefix of their own; the reference's fields do not.
    keys = {k.removeprefix("segment_"): ref[k] for k in REFERENCE_KEYS[kind]}
    return build(
        "reference.",
        make_reference,
        keys={f: f"reference.segment_{f}" for f in ("distances_m", "durations_s", "delay_s")},
        kind=kind,
        **keys,
    )


def as_values(role: str, values: Values | Mapping[str, Any]) -> Any:
    """``values`` as the typed values of node ``role``: as they are, or made from a mapping.

    For a caller of the builders with values of its own (a dict of dotted
    keys, which bypassed the schema): made into the node's class without a
    check, so that what a constructor refuses still names the key.
    """
    if isinstance(values, Values):
        return values
    return from_flat(values_class(role, values), values)


# --------------------------------------------------------------------------- plant models


def register_plant_model(
    name: str,
    *,
    schema: Mapping[str, Param],
    build: Callable[[Any, np.random.Generator], Plant],
    warnings: Callable[[Any], list[str]] | None = None,
    rotary: bool = False,
) -> None:
    """Make a plant model selectable as ``plant.model: <name>`` in this process.

    An installed package does it with an entry point of group
    ``servo_axis.plant_models`` (:mod:`servo_axis.params.registry`); this is
    for a test or a script. The schema must have ``torque_constant_Nm_per_A``:
    the plant, as a drive, turns the motor torque reference of ``command``
    into its current with it (:mod:`servo_axis.core.drive`).
    """
    entry: PlantModelEntry[Any] = PlantModelEntry(schema=schema, build=build, rotary=rotary)
    if warnings is not None:
        entry = PlantModelEntry(schema=schema, build=build, warnings=warnings, rotary=rotary)
    PLANT_MODELS.register(name, entry)


def plant_model(name: object, key: str = "model") -> PlantModelEntry[Any]:
    """The installed model ``name`` (ParameterFileError naming ``key`` and the installed ones)."""
    return PLANT_MODELS.lookup(name, key)


def drive_constant(values: PlantValues) -> float:
    """The plant's ``K_T`` (N m/A), with which it turns the torque reference of ``command``
    into its current: every model has the key ``torque_constant_Nm_per_A``."""
    return float(values["torque_constant_Nm_per_A"])


def build_plant(values: PlantValues | Mapping[str, Any]) -> Plant:
    """The plant model of checked plant values, its sensor noise seeded by ``noise_seed``."""
    v: PlantValues = as_values("plant", values)
    return plant_model(v.model).build(v, np.random.default_rng(v.noise_seed))


# --------------------------------------------------------------------------- feedback


class SigmoidConstants(Protocol):
    """The ``sigmoid.*`` constants of 004 eq. (9): the feedback's copies and the term's keys."""

    @property
    def sigma_m2_per_rad(self) -> float: ...

    @property
    def gamma_m_per_rad(self) -> float: ...

    @property
    def coulomb_Nm(self) -> float: ...


def sigmoid_params(keys: SigmoidConstants) -> SigmoidParams:
    """The sigmoid law's constants of 004 eq. (9) from the ``sigmoid.*`` keys (the
    feedforward term from the reference and the feedback's from the stage share them)."""
    return build(
        "sigmoid.",
        SigmoidParams,
        sigma_m2_per_rad=keys.sigma_m2_per_rad,
        gamma_m_per_rad=keys.gamma_m_per_rad,
        coulomb_Nm=keys.coulomb_Nm,
    )


#: What a PID's gains follow from besides the nominal model: the bandwidth.
_FROM_BANDWIDTH = {
    name: "bandwidth_hz" for name in ("kp_A_per_rad", "ki_A_per_rad_s", "derivative_tau_s", "a")
}


def pid_gains(values: FeedbackValues) -> PidGains:
    """The PID's gains by pole placement on ``P_n`` (``bandwidth_hz`` and ``nominal.*``)."""
    nominal = nominal_model(values).as_kwargs()
    try:
        return build(
            "",
            design_pid_pole_placement,
            keys={**NOMINAL_KEYS, **_FROM_BANDWIDTH},
            bandwidth_hz=values.bandwidth_hz,
            **nominal,
        )
    except OverflowError as err:
        raise ParameterFileError(
            f"parameter 'bandwidth_hz': expected PID gains that are finite numbers, "
            f"got {values.bandwidth_hz!r}"
        ) from err


def safety_limits(values: FeedbackValues) -> SafetyLimits:
    """The loop's trips (``limits.*``)."""
    limits = values.limits
    return build(
        "limits.",
        SafetyLimits,
        following_error_m=limits.following_error_m,
        travel_m=limits.travel_m,
        current_A=limits.current_A,
    )


def stage_sigmoid(values: FeedbackValues) -> bool:
    """Whether the loop adds 004 eq. (9) from the measured stage (``sigmoid.source: stage``)."""
    return values.sigmoid.enabled and values.sigmoid.source == "stage"


def check_feedback(values: FeedbackValues) -> None:
    """What :func:`build_loop` refuses, without building the loop; and the forward topic."""
    pid_gains(values)
    if values.dob.enabled:
        build(
            "dob.",
            check_cutoff,
            keys=PERIOD_KEYS,
            cutoff_hz=values.dob.cutoff_hz,
            period_s=values.control_period_s,
        )
    safety_limits(values)
    if stage_sigmoid(values):
        sigmoid_params(values.sigmoid)
    # deformation.*: each key's range is all the DeformationRatio asks.
    check_forward_topic(values)


def build_loop(values: FeedbackValues | Mapping[str, Any]) -> FeedbackLoop:
    """The feedback loop (PID, optional DOB, trips) of checked feedback values."""
    v: FeedbackValues = as_values("feedback", values)
    period = v.control_period_s
    nominal = nominal_model(v).as_kwargs()
    gains = pid_gains(v)
    pid = build(
        "", DiscretePid, keys={**PERIOD_KEYS, **_FROM_BANDWIDTH}, gains=gains, period_s=period
    )
    dob = (
        build(
            "dob.",
            DisturbanceObserver,
            keys={**NOMINAL_KEYS, **PERIOD_KEYS},
            cutoff_hz=v.dob.cutoff_hz,
            period_s=period,
            **nominal,
        )
        if v.dob.enabled
        else None
    )
    limits = safety_limits(v)
    compensation = None
    if stage_sigmoid(v):
        # 004 eq. (9) with sgn(v) and z of the stage: the loop has the scale.
        compensation = build(
            "sigmoid.",
            StageSigmoid,
            keys=NOMINAL_KEYS,
            params=sigmoid_params(v.sigmoid),
            torque_constant_Nm_per_A=v.nominal.torque_constant_Nm_per_A,
        )
    return build(
        "",
        FeedbackLoop,
        pid=pid,
        dob=dob,
        lead_m_per_rad=v.lead_m_per_rad,
        limits=limits,
        use_feedforward=v.use_feedforward,
        sensor=v.sensor,
        dob_sensor=v.dob.sensor,
        compensation=compensation,
    )


def build_deformation(values: FeedbackValues) -> DeformationRatio | None:
    """The deformation ratio of 004 eqs. (5)-(7) the feedback publishes, if on."""
    d = values.deformation
    if not d.enabled:
        return None
    return build(
        "deformation.",
        DeformationRatio,
        keys={"lead_m_per_rad": "lead_m_per_rad"},
        window_samples=d.window_samples,
        lead_m_per_rad=values.lead_m_per_rad,
        min_rotation_rad=d.min_rotation_rad,
    )


# --------------------------------------------------------------------------- feedforward


def term_file(enabled: bool, file: str, term: str) -> str | None:
    """A term's ``<term>.file`` when ``<term>.enabled`` (None when off), not read.

    Raises
    ------
    ParameterFileError
        Naming ``<term>.file`` when the term is on and names no file.
    """
    if not enabled:
        return None
    if not file:
        raise ParameterFileError(f"parameter '{term}.file': required when {term}.enabled is true")
    return file


def term_on(values: FeedforwardValues, term: str) -> bool:
    """Whether the installed feedforward term ``term`` is on (``<term>.enabled``; a term
    without that key is on whenever it is installed, a term not installed never is)."""
    key = f"{term}.enabled"
    if key in values:
        return bool(values[key])
    return term in FEEDFORWARD_TERMS


def estimate_schedule(values: Any, period_key: str, latency_key: str) -> tuple[int, int]:
    """``(period, latency)`` in control samples of the estimates of ``values[period_key]``, ``values[latency_key]``.

    For a caller with the dotted keys of the two periods; the suite's own
    ask :func:`identifier_schedule` or :func:`estimate_steps`.
    """
    return _schedule(values, (period_key, values[period_key]), (latency_key, values[latency_key]))


def _schedule(
    values: SharedValues, period: tuple[str, float], latency: tuple[str, float]
) -> tuple[int, int]:
    """``(period, latency)`` in control samples of an online estimate (003, docs/design.md section 4).

    ``period``, ``latency``: each period's key and its value, s. Both are
    whole numbers of reference periods and the latency is at least one
    period: an estimate computed from the samples up to ``k`` applies from
    ``k + 1 + latency``, and the feedforward's preview never runs ahead of
    the estimates it depends on.
    """
    g = grid(values)
    steps = [
        build("", g.instants_per, keys={key: key}, period_s=seconds, name=key) * g.ratio
        for key, seconds in (period, latency)
    ]
    if steps[1] < steps[0]:
        raise ParameterFileError(
            f"parameter '{latency[0]}': expected at least one estimate period "
            f"({period[1]!r} s), got {latency[1]!r}"
        )
    return steps[0], steps[1]


def identifier_schedule(values: IdentifierValues) -> tuple[int, int]:
    """``(period, latency)`` of the identifier's estimates in control samples (``rls_period_s``,
    ``latency_s``)."""
    return _schedule(values, ("rls_period_s", values.rls_period_s), ("latency_s", values.latency_s))


def build_terms(values: FeedforwardValues) -> list[FeedforwardTerm]:
    """The feedforward terms the values switch on, in their order (``FeedforwardTermEntry.order``).

    With the feedback's DOB on (``dob.*``, copied from the feedback section),
    their sum enters outside the DOB (:class:`OutsideObserver`, 004 Fig. 5).
    """
    terms = [t for _, e in feedforward_terms() if (t := e.build(values)) is not None]
    if terms and values.dob.enabled:
        outside: FeedforwardTerm = build(
            "dob.",
            OutsideObserver,
            keys=PERIOD_KEYS,
            terms=terms,
            cutoff_hz=values.dob.cutoff_hz,
            period_s=values.control_period_s,
        )
        return [outside]
    return terms


def learning_period_steps(values: FeedforwardValues) -> int | None:
    """Control samples per learning period of checked feedforward values (None: no learning).

    The cycle is a whole number (>= 4) of reference periods ``T_r``, as the
    learning unit needs it (:func:`build_learning_law`).
    """
    learning = values.learning
    if not learning.enabled:
        return None
    check_trial_period("learning.cycle_s", learning.cycle_s, values)
    g = grid(values)
    instants = build(
        "learning.", g.instants_per, period_s=learning.cycle_s, name="cycle_s", minimum=4
    )
    return cycle_instants("learning.cycle_s", learning.cycle_s, instants) * g.ratio


def check_trial_period(
    key: str, period_s: float, values: FeedforwardValues | LearningValues
) -> None:
    """A learning period over a ``trials`` reference is one trial (``reference.trial_s``)."""
    ref = values.reference
    if ref.kind == "trials" and period_s != ref.trial_s:
        raise ParameterFileError(
            f"parameter '{key}': expected one trial, reference.trial_s = "
            f"{ref.trial_s!r} s, got {period_s!r} s"
        )


def cycle_instants(key: str, cycle_s: float, instants: int) -> int:
    """``instants``, if a learning cycle of that many reference instants is not too long."""
    if instants > MAX_CYCLE_INSTANTS:
        raise ParameterFileError(
            f"parameter '{key}': expected at most {MAX_CYCLE_INSTANTS} reference periods "
            f"per learning cycle, got {cycle_s!r} s ({instants})"
        )
    return instants


def learning_side(values: FeedforwardValues, period_steps: int | None) -> str:
    """``target`` or ``input``: where the learning law's corrections go (``target``: none).

    Raises
    ------
    ParameterFileError
        Naming ``learning.law`` for a law that is not installed, ``ptc.enabled``
        for a target-side law without PTC.
    """
    if period_steps is None:
        return "target"
    side = learning_law(values.learning.law, "learning.law").side
    if side == "target" and not values.ptc.enabled:
        raise ParameterFileError(
            f"parameter 'ptc.enabled': learning law {values.learning.law!r} corrects the "
            "target, which needs PTC, got false"
        )
    return side


def estimate_steps(values: FeedforwardValues) -> tuple[int | None, int]:
    """``(period, latency)`` of the online estimates in control samples, ``(None, 0)``: none."""
    adaptive = values.adaptive
    if not adaptive.enabled:
        return None, 0
    return _schedule(
        values,
        ("adaptive.rls_period_s", adaptive.rls_period_s),
        ("adaptive.latency_s", adaptive.latency_s),
    )


def check_feedforward(values: FeedforwardValues) -> None:
    """What :func:`build_generator` refuses, without building the generator; each term's check."""
    for _, term in feedforward_terms():
        term.check(values)
    learning_side(values, learning_period_steps(values))
    estimate_steps(values)
    build_reference(values)
    grid(values)
    nominal_model(values)


def build_generator(
    values: FeedforwardValues | Mapping[str, Any], *, terms: list[FeedforwardTerm] | None = None
) -> FeedforwardGenerator:
    """The feedforward generator of checked feedforward values.

    ``terms`` replaces the terms the values switch on (:func:`build_terms`,
    which reads their files).
    """
    v: FeedforwardValues = as_values("feedforward", values)
    period_steps = learning_period_steps(v)
    side = learning_side(v, period_steps)
    period, latency = estimate_steps(v)
    return build(
        "",
        FeedforwardGenerator,
        keys={
            **NOMINAL_KEYS,
            "learning_period_steps": "learning.cycle_s",
            "estimate_period_steps": "adaptive.rls_period_s",
            "estimate_latency_steps": "adaptive.latency_s",
        },
        reference=build_reference(v),
        grid=grid(v),
        lead_m_per_rad=v.lead_m_per_rad,
        nominal=nominal_model(v),
        ptc_enabled=v.ptc.enabled,
        terms=build_terms(v) if terms is None else terms,
        learning_period_steps=period_steps,
        learning_side=side,
        estimate_period_steps=period,
        estimate_latency_steps=latency,
    )


# --------------------------------------------------------------------------- learning laws


def learning_law(name: object, key: str = "law") -> LearningLawEntry[Any]:
    """The installed law ``name`` (ParameterFileError naming ``key`` and the installed ones)."""
    return LEARNING_LAWS.lookup(name, key)


def build_learning_law(values: LearningValues | Mapping[str, Any]) -> LearningLaw:
    """The learning law of checked learning values."""
    v: LearningValues = as_values("learning", values)
    return learning_law(v.law).build(v)


# --------------------------------------------------------------------------- identifiers


def identifier_method(name: object, key: str = "method") -> IdentifierEntry[Any]:
    """The installed method ``name`` (ParameterFileError naming ``key`` and the installed ones)."""
    return IDENTIFIERS.lookup(name, key)


def build_identifier(values: IdentifierValues | Mapping[str, Any]) -> OnlineIdentifier:
    """The online identifier of checked identifier values."""
    v: IdentifierValues = as_values("identifier", values)
    return identifier_method(v.method).build(v)


# --------------------------------------------------------------------------- schemas and values

#: Schema of each node (shared keys included), before its extensions' keys
#: (:func:`node_schema` adds the chosen model's, law's or method's and every
#: installed feedforward term's).
NODE_SCHEMAS: dict[str, Mapping[str, Param]] = {
    "plant": {**schemas.SHARED, **schemas.PLANT},
    "feedback": {**schemas.SHARED, **schemas.FEEDBACK},
    "feedforward": {**schemas.SHARED, **schemas.FEEDFORWARD},
    "learning": {**schemas.SHARED, **schemas.LEARNING},
    "recorder": {**schemas.SHARED, **schemas.RECORDER},
    "identifier": {**schemas.SHARED, **schemas.IDENTIFIER},
}

#: The class of each node's values without extensions (:mod:`servo_axis.params.values`).
NODE_CLASSES: dict[str, type[Values]] = {
    "plant": PlantValues,
    "feedback": FeedbackValues,
    "feedforward": FeedforwardValues,
    "learning": LearningValues,
    "recorder": RecorderValues,
    "identifier": IdentifierValues,
}


def node_schema(role: str, given: Mapping[str, Any]) -> dict[str, Param]:
    """The full schema of node ``role`` for the keys ``given`` (the model/law chosen there).

    Raises
    ------
    BrokenPluginError
        When ``given`` selects an installed extension that cannot be loaded
        (its model, law or method, a key of a feedforward term).
    """
    schema = dict(NODE_SCHEMAS[role])
    if role == "plant":
        model = given.get("model", schema["model"].default)
        schema.update(plant_model(model).schema)
    elif role == "learning":
        law = given.get("law", schema["law"].default)
        schema.update(learning_law(law).schema)
    elif role == "identifier":
        method = given.get("method", schema["method"].default)
        schema.update(identifier_method(method).schema)
    elif role == "feedforward":
        for _, term in feedforward_terms():
            schema.update(term.schema)
        # A key of a term that is installed but cannot be loaded uses that term.
        FEEDFORWARD_TERMS.refuse_broken_keys(k for k in given if k not in schema)
    return schema


def values_class(role: str, given: Mapping[str, Any]) -> type[Values]:
    """The class of node ``role``'s values for the keys ``given``: with the chosen model's,
    law's or method's keys, or every installed term's (:mod:`servo_axis.plugins.values`)."""
    default = NODE_SCHEMAS[role]
    if role == "plant":
        return PLANT_MODELS.values_class(given.get("model", default["model"].default))
    if role == "learning":
        return LEARNING_LAWS.values_class(given.get("law", default["law"].default))
    if role == "identifier":
        return IDENTIFIERS.values_class(given.get("method", default["method"].default))
    if role == "feedforward":
        return feedforward_class()
    return NODE_CLASSES[role]


def checked_values(role: str, given: Mapping[str, Any]) -> Any:
    """The typed values of node ``role``: ``given`` where set, defaults elsewhere, checked.

    Each key against its schema first (:func:`~servo_axis.params.param.check_values`),
    then what depends on several keys (:func:`check_consistency`), so that
    whoever checks a section (the node, the runner before it starts any
    process) refuses what the node would. The result is an instance of the
    node's class (:func:`values_class`: ``PlantValues`` with the model's
    keys, ...), also a read-only mapping of the dotted keys.

    Raises
    ------
    ParameterFileError
        Naming the full key (or keys) at fault.
    """
    flat = check_values(node_schema(role, given), given, role)
    values = from_flat(values_class(role, flat), flat)
    check_consistency(role, values)
    return values


def check_consistency(role: str, values: Any) -> None:
    """What depends on several keys of node ``role``'s values; no file is read, nothing built.

    The run length (``duration_s`` against ``control_period_s``), the plant
    model (its entry's ``check``: ``sim_step_s`` divides ``control_period_s``,
    the modes, ...), the feedback loop (the DOB cut-off below Nyquist, the
    PID's gains, ...), the feedforward generator (``learning.cycle_s``
    whole, PTC for target-side learning) and its terms' checks, the learning
    law (``n Nq + 2 < Nd``) and the recorder's topic lists. What needs a
    file (a friction table, a learning memory) or the node's transport (the
    learning cycle against the stream depth) is the node's. An extension
    from outside the suite that declares no ``check`` is built once here and
    dropped (what its builder refuses is refused before any process starts).

    Raises
    ------
    ParameterFileError
        Naming the key (or keys) at fault.
    """
    run_steps(values)
    external_roles(values)
    if role == "plant":
        entry = plant_model(values.model)
        if entry.check is not None:
            entry.check(values)
        else:
            build_plant(values)
        check_command_source(values)
    elif role == "feedback":
        check_feedback(values)
    elif role == "feedforward":
        check_feedforward(values)
    elif role == "learning":
        law = learning_law(values.law)
        if law.check is not None:
            law.check(values)
        else:
            law.build(values)
        build_reference(values)
    elif role == "recorder":
        check_recorder_topics(values)
    elif role == "identifier":
        method = identifier_method(values.method)
        if method.check is not None:
            method.check(values)
        else:
            method.build(values)


#: The roles a node from outside the suite may play (``external_roles``).
EXTERNAL_ROLES = ("plant", "feedback", "feedforward", "learning", "identifier")


def external_roles(values: SharedValues) -> tuple[str, ...]:
    """The roles of ``external_roles`` (the empty placeholder dropped), checked.

    Raises
    ------
    ParameterFileError
        Naming ``external_roles`` for a role that is not one of :data:`EXTERNAL_ROLES`.
    """
    roles = tuple(r for r in values.external_roles if r)
    for role in roles:
        if role not in EXTERNAL_ROLES:
            raise ParameterFileError(
                f"parameter 'external_roles': expected roles among {list(EXTERNAL_ROLES)}, "
                f"got {role!r}"
            )
    return roles
