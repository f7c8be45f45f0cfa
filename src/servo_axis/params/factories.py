"""Factories: checked parameter values -> core objects, and the resolver of a scenario's sections.

The nodes, the headless simulation (:mod:`servo_axis.simulate`) and the
reports build the same objects from the same checked values through these
functions. The extension points (plant models, feedforward terms, learning
laws, identification methods) are the installed entry points of
:mod:`servo_axis.params.registry`; each is one module of its own (the
suite's in :mod:`servo_axis.plugins`), and this module only looks them up
by the name a scenario gives (``plant.model``, ``learning.law``,
``identifier.method``; every installed term is asked whether its keys switch
it on).

Nothing here imports rclpy.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from servo_axis.core.deformation import DeformationRatio
from servo_axis.core.errors import ParameterFileError
from servo_axis.core.feedback.dob import DisturbanceObserver
from servo_axis.core.feedback.loop import FeedbackLoop, SafetyLimits
from servo_axis.core.feedback.pid import DiscretePid, design_pid_pole_placement
from servo_axis.core.feedback.stage_sigmoid import StageSigmoid
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.core.feedforward.sigmoid import SigmoidParams
from servo_axis.core.feedforward.terms import FeedforwardTerm, OutsideObserver
from servo_axis.core.identification.base import OnlineIdentifier
from servo_axis.core.learning.base import LearningLaw
from servo_axis.core.models.base import NominalModel, Plant
from servo_axis.core.reference import Reference, make_reference
from servo_axis.core.timing import SampleGrid
from servo_axis.params import schemas
from servo_axis.params.names import namespace_problem
from servo_axis.params.param import Param, build, check_values, section
from servo_axis.params.registry import FEEDFORWARD_TERMS as FEEDFORWARD_TERMS
from servo_axis.params.registry import IDENTIFIERS as IDENTIFIERS
from servo_axis.params.registry import LEARNING_LAWS as LEARNING_LAWS
from servo_axis.params.registry import PLANT_MODELS as PLANT_MODELS
from servo_axis.params.registry import FeedforwardTermEntry as FeedforwardTermEntry
from servo_axis.params.registry import IdentifierEntry as IdentifierEntry
from servo_axis.params.registry import LearningLawEntry as LearningLawEntry
from servo_axis.params.registry import PlantModelEntry as PlantModelEntry
from servo_axis.params.registry import Values, feedforward_terms

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


def grid(values: Values) -> SampleGrid:
    """The sample grid (``T_u``, ``T_r = 2 T_u``) of a node's values."""
    return build("", SampleGrid, control_period_s=values["control_period_s"])


def run_steps(values: Values) -> int:
    """Control samples of the run (``duration_s / control_period_s``, at least 1)."""
    return build("", grid(values).steps, duration_s=values["duration_s"])


def nominal_model(values: Values) -> NominalModel:
    """The nominal model ``P_n`` of eq. (1) (the shared ``nominal.*`` keys)."""
    return build("nominal.", NominalModel, keys=NOMINAL_KEYS, **section(values, "nominal"))


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


def build_reference(values: Values) -> Reference:
    """The table-side reference of the ``reference.*`` keys."""
    ref = section(values, "reference")
    kind = ref.pop("kind")
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


# --------------------------------------------------------------------------- plant models


def register_plant_model(
    name: str,
    *,
    schema: Mapping[str, Param],
    build: Callable[[Values, np.random.Generator], Plant],
    warnings: Callable[[Values], list[str]] | None = None,
    rotary: bool = False,
) -> None:
    """Make a plant model selectable as ``plant.model: <name>`` in this process.

    An installed package does it with an entry point of group
    ``servo_axis.plant_models`` (:mod:`servo_axis.params.registry`); this is
    for a test or a script. The schema must have ``torque_constant_Nm_per_A``:
    the plant, as a drive, turns the motor torque reference of ``command``
    into its current with it (:mod:`servo_axis.core.drive`).
    """
    entry = PlantModelEntry(schema=schema, build=build, rotary=rotary)
    if warnings is not None:
        entry = PlantModelEntry(schema=schema, build=build, warnings=warnings, rotary=rotary)
    PLANT_MODELS.register(name, entry)


def plant_model(name: object, key: str = "model") -> PlantModelEntry:
    """The installed model ``name`` (ParameterFileError naming ``key`` and the installed ones)."""
    return PLANT_MODELS.lookup(name, key)


def build_plant(values: Values) -> Plant:
    """The plant model of checked plant values, its sensor noise seeded by ``noise_seed``."""
    entry = plant_model(values["model"])
    return entry.build(values, np.random.default_rng(values["noise_seed"]))


# --------------------------------------------------------------------------- feedback


def sigmoid_params(values: Values) -> SigmoidParams:
    """The sigmoid law's constants of 004 eq. (9) from the ``sigmoid.*`` keys (the
    feedforward term from the reference and the feedback's from the stage share them)."""
    return build(
        "sigmoid.",
        SigmoidParams,
        sigma_m2_per_rad=values["sigmoid.sigma_m2_per_rad"],
        gamma_m_per_rad=values["sigmoid.gamma_m_per_rad"],
        coulomb_Nm=values["sigmoid.coulomb_Nm"],
    )


def build_loop(values: Values) -> FeedbackLoop:
    """The feedback loop (PID, optional DOB, trips) of checked feedback values."""
    period = values["control_period_s"]
    nominal = nominal_model(values).as_kwargs()
    # The gains follow from bandwidth_hz and the nominal model alone.
    from_bandwidth = {
        name: "bandwidth_hz" for name in ("kp_A_per_rad", "ki_A_per_rad_s", "derivative_tau_s", "a")
    }
    try:
        gains = build(
            "",
            design_pid_pole_placement,
            keys={**NOMINAL_KEYS, **from_bandwidth},
            bandwidth_hz=values["bandwidth_hz"],
            **nominal,
        )
    except OverflowError as err:
        raise ParameterFileError(
            f"parameter 'bandwidth_hz': expected PID gains that are finite numbers, "
            f"got {values['bandwidth_hz']!r}"
        ) from err
    pid = build(
        "", DiscretePid, keys={**PERIOD_KEYS, **from_bandwidth}, gains=gains, period_s=period
    )
    dob = (
        build(
            "dob.",
            DisturbanceObserver,
            keys={**NOMINAL_KEYS, **PERIOD_KEYS},
            cutoff_hz=values["dob.cutoff_hz"],
            period_s=period,
            **nominal,
        )
        if values["dob.enabled"]
        else None
    )
    limits = build("limits.", SafetyLimits, **section(values, "limits"))
    compensation = None
    if values["sigmoid.enabled"] and values["sigmoid.source"] == "stage":
        # 004 eq. (9) with sgn(v) and z of the stage: the loop has the scale.
        compensation = build(
            "sigmoid.",
            StageSigmoid,
            keys=NOMINAL_KEYS,
            params=sigmoid_params(values),
            torque_constant_Nm_per_A=values["nominal.torque_constant_Nm_per_A"],
        )
    return build(
        "",
        FeedbackLoop,
        pid=pid,
        dob=dob,
        lead_m_per_rad=values["lead_m_per_rad"],
        limits=limits,
        use_feedforward=values["use_feedforward"],
        sensor=values["sensor"],
        dob_sensor=values["dob.sensor"],
        compensation=compensation,
    )


def build_deformation(values: Values) -> DeformationRatio | None:
    """The deformation ratio of 004 eqs. (5)-(7) the feedback publishes, if on."""
    if not values["deformation.enabled"]:
        return None
    return build(
        "deformation.",
        DeformationRatio,
        keys={"lead_m_per_rad": "lead_m_per_rad"},
        window_samples=values["deformation.window_samples"],
        lead_m_per_rad=values["lead_m_per_rad"],
        min_rotation_rad=values["deformation.min_rotation_rad"],
    )


# --------------------------------------------------------------------------- feedforward

TermBuilder = Callable[[Values], FeedforwardTerm | None]


def register_feedforward_term(
    name: str,
    build: TermBuilder,
    *,
    schema: Mapping[str, Param] | None = None,
    order: float = 100.0,
) -> None:
    """Add a feedforward term in this process (an installed one is an entry point).

    Terms are summed in increasing ``order`` (:func:`~servo_axis.params.registry.feedforward_terms`).
    """
    FEEDFORWARD_TERMS.register(
        name, FeedforwardTermEntry(schema=schema or {}, build=build, order=order)
    )


def term_file(values: Values, term: str) -> str | None:
    """``<term>.file`` when ``<term>.enabled`` (None when off), not read."""
    if not values[f"{term}.enabled"]:
        return None
    path = str(values[f"{term}.file"])
    if not path:
        raise ParameterFileError(f"parameter '{term}.file': required when {term}.enabled is true")
    return path


def estimate_schedule(values: Values, period_key: str, latency_key: str) -> tuple[int, int]:
    """``(period, latency)`` in control samples of an online estimate (003, docs/design.md section 4).

    Both are whole numbers of reference periods and the latency is at least
    one period: an estimate computed from the samples up to ``k`` applies
    from ``k + 1 + latency``, and the feedforward's preview never runs
    ahead of the estimates it depends on.
    """
    g = grid(values)
    period, latency = (
        build("", g.instants_per, keys={key: key}, period_s=values[key], name=key) * g.ratio
        for key in (period_key, latency_key)
    )
    if latency < period:
        raise ParameterFileError(
            f"parameter '{latency_key}': expected at least one estimate period "
            f"({values[period_key]!r} s), got {values[latency_key]!r}"
        )
    return period, latency


def build_terms(values: Values) -> list[FeedforwardTerm]:
    """The feedforward terms the values switch on, in their order (``FeedforwardTermEntry.order``).

    With the feedback's DOB on (``dob.*``, copied from the feedback section),
    their sum enters outside the DOB (:class:`OutsideObserver`, 004 Fig. 5).
    """
    terms = [t for _, e in feedforward_terms() if (t := e.build(values)) is not None]
    if terms and values["dob.enabled"]:
        outside: FeedforwardTerm = build(
            "dob.",
            OutsideObserver,
            keys=PERIOD_KEYS,
            terms=terms,
            cutoff_hz=values["dob.cutoff_hz"],
            period_s=values["control_period_s"],
        )
        return [outside]
    return terms


def learning_period_steps(values: Values) -> int | None:
    """Control samples per learning period of checked feedforward values (None: no learning).

    The cycle is a whole number (>= 4) of reference periods ``T_r``, as the
    learning unit needs it (:func:`build_learning_law`).
    """
    if not values["learning.enabled"]:
        return None
    check_trial_period("learning.cycle_s", values["learning.cycle_s"], values)
    g = grid(values)
    instants = build(
        "learning.", g.instants_per, period_s=values["learning.cycle_s"], name="cycle_s", minimum=4
    )
    return cycle_instants("learning.cycle_s", values["learning.cycle_s"], instants) * g.ratio


def check_trial_period(key: str, period_s: float, values: Values) -> None:
    """A learning period over a ``trials`` reference is one trial (``reference.trial_s``)."""
    if values["reference.kind"] == "trials" and period_s != values["reference.trial_s"]:
        raise ParameterFileError(
            f"parameter '{key}': expected one trial, reference.trial_s = "
            f"{values['reference.trial_s']!r} s, got {period_s!r} s"
        )


def cycle_instants(key: str, cycle_s: float, instants: int) -> int:
    """``instants``, if a learning cycle of that many reference instants is not too long."""
    if instants > MAX_CYCLE_INSTANTS:
        raise ParameterFileError(
            f"parameter '{key}': expected at most {MAX_CYCLE_INSTANTS} reference periods "
            f"per learning cycle, got {cycle_s!r} s ({instants})"
        )
    return instants


def build_generator(
    values: Values, *, terms: list[FeedforwardTerm] | None = None
) -> FeedforwardGenerator:
    """The feedforward generator of checked feedforward values.

    ``terms`` replaces the terms the values switch on (:func:`build_terms`,
    which reads their files); :func:`check_consistency` builds it with none.
    """
    period_steps = learning_period_steps(values)
    side = (
        learning_law(values["learning.law"], "learning.law").side
        if period_steps is not None
        else "target"
    )
    if period_steps is not None and side == "target" and not values["ptc.enabled"]:
        raise ParameterFileError(
            f"parameter 'ptc.enabled': learning law {values['learning.law']!r} corrects the "
            "target, which needs PTC, got false"
        )
    period, latency = (
        estimate_schedule(values, "adaptive.rls_period_s", "adaptive.latency_s")
        if values["adaptive.enabled"]
        else (None, 0)
    )
    return build(
        "",
        FeedforwardGenerator,
        keys={
            **NOMINAL_KEYS,
            "learning_period_steps": "learning.cycle_s",
            "estimate_period_steps": "adaptive.rls_period_s",
            "estimate_latency_steps": "adaptive.latency_s",
        },
        reference=build_reference(values),
        grid=grid(values),
        lead_m_per_rad=values["lead_m_per_rad"],
        nominal=nominal_model(values),
        ptc_enabled=values["ptc.enabled"],
        terms=build_terms(values) if terms is None else terms,
        learning_period_steps=period_steps,
        learning_side=side,
        estimate_period_steps=period,
        estimate_latency_steps=latency,
    )


# --------------------------------------------------------------------------- learning laws


def register_learning_law(
    name: str,
    *,
    schema: Mapping[str, Param],
    period: str,
    side: str,
    build: Callable[[Values], LearningLaw],
    identifies: tuple[str, ...] = (),
) -> None:
    """Make a learning law selectable as ``learning.law: <name>`` in this process.

    An installed package does it with an entry point of group
    ``servo_axis.learning_laws``. ``identifies`` names what else the law
    publishes besides its correction and the per-period stats:
    ``"learning/parameters"`` and / or ``"learning/friction_table"``.
    """
    LEARNING_LAWS.register(
        name,
        LearningLawEntry(
            schema=schema, period=period, side=side, build=build, identifies=identifies
        ),
    )


def learning_law(name: object, key: str = "law") -> LearningLawEntry:
    """The installed law ``name`` (ParameterFileError naming ``key`` and the installed ones)."""
    return LEARNING_LAWS.lookup(name, key)


def build_learning_law(values: Values) -> LearningLaw:
    """The learning law of checked learning values."""
    return learning_law(values["law"]).build(values)


# --------------------------------------------------------------------------- identifiers


def register_identifier(
    name: str,
    *,
    schema: Mapping[str, Param],
    build: Callable[[Values], OnlineIdentifier],
    estimates_friction: bool,
) -> None:
    """Make an online identifier selectable as ``identifier.method: <name>`` in this process.

    An installed package does it with an entry point of group
    ``servo_axis.identification_methods``.
    """
    IDENTIFIERS.register(
        name,
        IdentifierEntry(schema=schema, build=build, estimates_friction=estimates_friction),
    )


def identifier_method(name: object, key: str = "method") -> IdentifierEntry:
    """The installed method ``name`` (ParameterFileError naming ``key`` and the installed ones)."""
    return IDENTIFIERS.lookup(name, key)


def build_identifier(values: Values) -> OnlineIdentifier:
    """The online identifier of checked identifier values."""
    return identifier_method(values["method"]).build(values)


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


def node_schema(role: str, given: Values) -> dict[str, Param]:
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


def checked_values(role: str, given: Values) -> dict[str, Any]:
    """Checked values of node ``role``: ``given`` where set, defaults elsewhere.

    Each key against its schema first (:func:`~servo_axis.params.param.check_values`),
    then what depends on several keys (:func:`check_consistency`), so that
    whoever checks a section (the node, the runner before it starts any
    process) refuses what the node would.

    Raises
    ------
    ParameterFileError
        Naming the full key (or keys) at fault.
    """
    values = check_values(node_schema(role, given), given, role)
    check_consistency(role, values)
    return values


def check_consistency(role: str, values: Values) -> None:
    """Build (and drop) what node ``role`` builds of its values; no file is read.

    The run length (``duration_s`` against ``control_period_s``), the plant
    model (``sim_step_s`` divides ``control_period_s``, the modes, ...), the
    feedback loop (the DOB cut-off below Nyquist, ...), the feedforward
    generator (``learning.cycle_s`` whole, PTC for target-side learning), the
    learning law (``n Nq + 2 < Nd``) and the recorder's topic lists. What
    needs a file (a friction table, a learning memory) or the node's
    transport (the learning cycle against the stream depth) is the node's.

    Raises
    ------
    ParameterFileError
        Naming the key (or keys) at fault.
    """
    run_steps(values)
    external_roles(values)
    if role == "plant":
        build_plant(values)
        check_command_source(values)
    elif role == "feedback":
        build_loop(values)
        build_deformation(values)
        check_forward_topic(values)
    elif role == "feedforward":
        for _, term in feedforward_terms():
            term.check(values)
        build_generator(values, terms=[])
    elif role == "learning":
        build_learning_law(values)
        build_reference(values)
    elif role == "recorder":
        check_recorder_topics(values)
    elif role == "identifier":
        build_identifier(values)


def check_command_source(values: Values) -> None:
    """``command_source: drive_setpoint`` only in realtime (a set-point has no step to wait for).

    Raises
    ------
    ParameterFileError
        Naming ``command_source`` and ``mode``.
    """
    if values.get("command_source") == "drive_setpoint" and values["mode"] == "lockstep":
        raise ParameterFileError(
            "parameter 'command_source': drive_setpoint needs mode: realtime (a drive's "
            "set-point carries no step of the k T_u grid, which lockstep waits for; "
            "got mode: lockstep)"
        )


def check_forward_topic(values: Values) -> None:
    """``forward_commands_topic``: empty, or a ROS topic name (absolute or relative).

    Raises
    ------
    ParameterFileError
        Naming ``forward_commands_topic`` and what rcl would refuse.
    """
    topic = values.get("forward_commands_topic", "")
    if not topic:
        return
    problem = namespace_problem(topic if topic.startswith("/") else f"/{topic}")
    if problem is not None or topic in ("/", "~"):
        raise ParameterFileError(
            f"parameter 'forward_commands_topic': {topic!r} is not a ROS topic name: "
            f"{problem or 'no name'}"
        )


#: The roles a node from outside the suite may play (``external_roles``).
EXTERNAL_ROLES = ("plant", "feedback", "feedforward", "learning", "identifier")


def external_roles(values: Values) -> tuple[str, ...]:
    """The roles of ``external_roles`` (the empty placeholder dropped), checked.

    Raises
    ------
    ParameterFileError
        Naming ``external_roles`` for a role that is not one of :data:`EXTERNAL_ROLES`.
    """
    roles = tuple(r for r in values.get("external_roles", [""]) if r)
    for role in roles:
        if role not in EXTERNAL_ROLES:
            raise ParameterFileError(
                f"parameter 'external_roles': expected roles among {list(EXTERNAL_ROLES)}, "
                f"got {role!r}"
            )
    return roles


def check_recorder_topics(values: Values) -> None:
    """One type per topic; the latched and counted topics among them; a period per final topic."""
    topics, types = values["topics"], values["types"]
    if len(topics) != len(types) or not topics:
        raise ParameterFileError(
            f"parameter 'types': expected one type per topic ({len(topics)} topics), "
            f"got {len(types)}"
        )
    for key in ("latched_topics", "counted_topics"):
        extra = set(values[key]) - set(topics)
        if extra:
            raise ParameterFileError(f"parameter '{key}': {sorted(extra)} not in 'topics'")
    finals, every = values["final_topics"], values["final_every_steps"]
    if len(finals) != len(every):
        raise ParameterFileError(
            f"parameter 'final_every_steps': expected one period per final topic "
            f"({len(finals)} topics), got {len(every)}"
        )
