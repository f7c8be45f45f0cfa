"""Factories: parameter values -> core objects, with the registries of the extension points.

The nodes, the headless simulation (:mod:`servo_axis.simulate`) and the
reports build the same objects from the same checked values through these
functions. Extension points, as in ros2_control, are chosen by a parameter
from a registry; adding an implementation is one module plus one
``register_*`` call:

* plant models (``plant.model``): :func:`register_plant_model`;
* feedforward terms (``feedforward`` keys of their own, e.g.
  ``friction_table.*``): :func:`register_feedforward_term`;
* learning laws (``learning.law``): :func:`register_learning_law`;
* online identifiers (``identifier.method``): :func:`register_identifier`.

Nothing here imports rclpy.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.core.deformation import DeformationRatio
from servo_axis.core.errors import ParameterFileError, ServoAxisError
from servo_axis.core.feedback.dob import DisturbanceObserver
from servo_axis.core.feedback.loop import FeedbackLoop, SafetyLimits
from servo_axis.core.feedback.pid import DiscretePid, design_pid_pole_placement
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.core.feedforward.gms import GmsTerm
from servo_axis.core.feedforward.mnc import MncParams, NonlinearityCompensator
from servo_axis.core.feedforward.sigmoid import SigmoidParams, SigmoidTerm
from servo_axis.core.feedforward.terms import FeedforwardTerm, FrictionTableTerm, OutsideObserver
from servo_axis.core.friction.model import FrictionParams
from servo_axis.core.identification.base import OnlineIdentifier
from servo_axis.core.identification.dlpid import Dlpid, DlpidParams
from servo_axis.core.identification.rls import RlsParams
from servo_axis.core.learning.base import LearningLaw
from servo_axis.core.learning.rptc import LearningParams, PeriodicSignalGenerator
from servo_axis.core.models.ball_screw import BallScrewParams, BallScrewPlant, DisturbanceParams
from servo_axis.core.models.base import NominalModel, Plant
from servo_axis.core.models.elastic_ball_screw import (
    ElasticBallScrewParams,
    ElasticBallScrewPlant,
    mode_warning,
)
from servo_axis.core.models.tilting_table import TiltingTableParams, TiltingTablePlant
from servo_axis.core.reference import Reference, make_reference
from servo_axis.core.sensors import SensorParams
from servo_axis.core.timing import SampleGrid
from servo_axis.params import schemas
from servo_axis.params.scenario import node_params, resolve_table
from servo_axis.params.schema import Param, build, check_values, section
from servo_axis.storage import load_friction_table, load_gms_parameters

Values = Mapping[str, Any]

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


@dataclass(frozen=True)
class PlantModelEntry:
    """A registered plant model: its parameter keys and how to build it.

    Attributes
    ----------
    schema : mapping of str to Param
        The model's keys in the ``plant`` section (beside :data:`schemas.PLANT`).
    build : callable
        ``build(values, rng) -> Plant`` from the checked plant values.
    warnings : callable
        ``warnings(values) -> list of str``: what is allowed but unusual.
    """

    schema: Mapping[str, Param]
    build: Callable[[Values, np.random.Generator], Plant]
    warnings: Callable[[Values], list[str]]


PLANT_MODELS: dict[str, PlantModelEntry] = {}


def register_plant_model(
    name: str,
    *,
    schema: Mapping[str, Param],
    build: Callable[[Values, np.random.Generator], Plant],
    warnings: Callable[[Values], list[str]] | None = None,
) -> None:
    """Make a plant model selectable as ``plant.model: <name>``.

    ``warnings(values)`` lists what is allowed but unusual in checked values
    (the plant node logs each at start). The schema must have
    ``torque_constant_Nm_per_A``: the plant, as a drive, turns the motor
    torque reference of ``command`` into its current with it
    (:mod:`servo_axis.core.drive`).
    """
    clash = set(schema) & (set(schemas.PLANT) | set(schemas.SHARED))
    if clash:
        raise ValueError(f"schema: keys {sorted(clash)} are the plant node's own")
    if "torque_constant_Nm_per_A" not in schema:
        raise ValueError(
            "schema: expected a key 'torque_constant_Nm_per_A' (N m/A), with which the "
            "plant turns the torque reference of `command` into its current"
        )
    PLANT_MODELS[name] = PlantModelEntry(
        schema=schema, build=build, warnings=warnings or (lambda values: [])
    )


def plant_model(name: object) -> PlantModelEntry:
    """The registered model ``name`` (ParameterFileError naming ``model`` otherwise)."""
    if not isinstance(name, str) or name not in PLANT_MODELS:
        raise ParameterFileError(
            f"parameter 'model': expected one of {sorted(PLANT_MODELS)}, got {name!r}"
        )
    return PLANT_MODELS[name]


def build_plant(values: Values) -> Plant:
    """The plant model of checked plant values, its sensor noise seeded by ``noise_seed``."""
    entry = plant_model(values["model"])
    return entry.build(values, np.random.default_rng(values["noise_seed"]))


# The modes lists default to [0.0] only so that their type is known; an
# all-zero frequency list means "no modes".
_NO_MODES = [0.0]


def ball_screw_params(values: Values) -> BallScrewParams:
    """:class:`BallScrewParams` from checked plant values."""
    freqs, zetas, gains = (values[f"modes.{k}"] for k in ("frequency_hz", "zeta", "a"))
    if freqs == _NO_MODES and zetas == _NO_MODES and gains == _NO_MODES:
        freqs, zetas, gains = [], [], []
    if not len(freqs) == len(zetas) == len(gains):
        raise ParameterFileError(
            "parameter 'modes': modes.frequency_hz, modes.zeta and modes.a must have the "
            f"same length, got {len(freqs)}, {len(zetas)}, {len(gains)}"
        )
    for key, listed in (("frequency_hz", freqs), ("zeta", zetas)):
        if any(x <= 0.0 for x in listed):
            raise ParameterFileError(
                f"parameter 'modes.{key}': expected every element > 0 when modes are given "
                f"(all three lists [0.0]: no mode), got {listed!r}"
            )
    h = values["sim_step_s"]
    if any(f >= 0.5 / h for f in freqs):
        raise ParameterFileError(
            "parameter 'modes.frequency_hz': expected every element below the Nyquist "
            f"frequency of sim_step_s ({0.5 / h:g} Hz), got {freqs!r}"
        )
    for key in ("control_period_s", "dead_time_s"):
        if values[key] / h > MAX_SIM_STEPS:
            raise ParameterFileError(
                f"parameter '{key}': expected at most {MAX_SIM_STEPS} integration steps "
                f"(sim_step_s = {h!r} s), got {values[key]!r} s"
            )
    return build(
        "",
        BallScrewParams,
        torque_constant_Nm_per_A=values["torque_constant_Nm_per_A"],
        inertia_kgm2=values["inertia_kgm2"],
        damping_Nms_per_rad=values["damping_Nms_per_rad"],
        lead_m_per_rad=values["lead_m_per_rad"],
        modes=tuple(zip(freqs, zetas, gains, strict=True)),
        dead_time_s=values["dead_time_s"],
        control_period_s=values["control_period_s"],
        sim_step_s=values["sim_step_s"],
        current_limit_A=values["current_limit_A"],
        initial_angle_rad=values["initial_angle_rad"],
        initial_velocity_rad_s=values["initial_velocity_rad_s"],
        friction=build("friction.", FrictionParams, **section(values, "friction")),
        disturbance=build("disturbance.", DisturbanceParams, **section(values, "disturbance")),
        encoder=build("encoder.", SensorParams, **section(values, "encoder")),
        scale=build("scale.", SensorParams, **section(values, "scale")),
    )


def tilting_table_params(values: Values) -> TiltingTableParams:
    """:class:`TiltingTableParams` from checked plant values (paper 003)."""
    return build(
        "",
        TiltingTableParams,
        keys={"encoder_resolution_rad": "encoder.resolution"},
        torque_constant_Nm_per_A=values["torque_constant_Nm_per_A"],
        inertia_kgm2=values["inertia_kgm2"],
        damping_Nms_per_rad=values["damping_Nms_per_rad"],
        unbalance_Nm=values["unbalance_Nm"],
        coulomb_Nm=values["coulomb_Nm"],
        control_period_s=values["control_period_s"],
        sim_step_s=values["sim_step_s"],
        current_limit_A=values["current_limit_A"],
        initial_angle_rad=values["initial_angle_rad"],
        initial_velocity_rad_s=values["initial_velocity_rad_s"],
        noise_rad=values["noise_rad"],
        encoder_resolution_rad=values["encoder.resolution"],
    )


register_plant_model(
    "tilting_table",
    schema=schemas.TILTING_TABLE,
    build=lambda values, rng: TiltingTablePlant(tilting_table_params(values), rng=rng),
)


#: Plant keys added after files were fitted (the elastic ball screw's ball-nut
#: friction option, issue 21): in the fingerprint only when set away from their
#: defaults, so that a file fitted before names the same plant.
_ADDED_KEYS = frozenset(
    {
        "nut_friction",
        "nut_preload_N",
        "contact_travel_m",
        "contact_presliding_m",
        "bearing_friction_Nm",
        "bearing_presliding_m",
    }
)


def plant_fingerprint(scenario: dict[str, Any]) -> str:
    """``<model>:<16 hex>``: which plant a file identified on it belongs to.

    The SHA-256 of the checked values of the plant model's own keys (its
    physics, not the node's run settings) and the lead, as sorted JSON with
    floats in ``repr``; a GMS parameter file carries it, and the feedforward
    refuses a file of another plant.
    """
    values = node_values(scenario, "plant")
    schema = plant_model(values["model"]).schema
    own = [k for k in sorted(schema) if k not in _ADDED_KEYS or values[k] != schema[k].default]
    keys = [*own, "lead_m_per_rad"]
    text = json.dumps({k: values[k] for k in keys}, sort_keys=True)
    return f"{values['model']}:{hashlib.sha256(text.encode()).hexdigest()[:16]}"


def elastic_ball_screw_params(values: Values) -> ElasticBallScrewParams:
    """:class:`ElasticBallScrewParams` from checked plant values (paper 004)."""
    own = {k: values[k] for k in schemas.ELASTIC_BALL_SCREW if "." not in k}
    return build(
        "",
        ElasticBallScrewParams,
        **own,
        lead_m_per_rad=values["lead_m_per_rad"],
        control_period_s=values["control_period_s"],
        encoder=build("encoder.", SensorParams, **section(values, "encoder")),
        scale=build("scale.", SensorParams, **section(values, "scale")),
    )


def _elastic_warnings(values: Values) -> list[str]:
    warning = mode_warning(elastic_ball_screw_params(values))
    return [] if warning is None else [warning]


register_plant_model(
    "elastic_ball_screw",
    schema=schemas.ELASTIC_BALL_SCREW,
    build=lambda values, rng: ElasticBallScrewPlant(elastic_ball_screw_params(values), rng=rng),
    warnings=_elastic_warnings,
)

register_plant_model(
    "ball_screw",
    schema=schemas.BALL_SCREW,
    build=lambda values, rng: BallScrewPlant(ball_screw_params(values), rng=rng),
)

# --------------------------------------------------------------------------- feedback


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

#: Feedforward terms, in the order they are summed; each builder returns None
#: when its keys leave it off.
FEEDFORWARD_TERMS: dict[str, TermBuilder] = {}


def register_feedforward_term(name: str, build: TermBuilder) -> None:
    """Add a feedforward term (summed after those registered before it)."""
    FEEDFORWARD_TERMS[name] = build


def _term_file(values: Values, term: str) -> str | None:
    """``<term>.file`` when ``<term>.enabled`` (None when off), not read."""
    if not values[f"{term}.enabled"]:
        return None
    path = str(values[f"{term}.file"])
    if not path:
        raise ParameterFileError(f"parameter '{term}.file': required when {term}.enabled is true")
    return path


def _friction_table_path(values: Values) -> str | None:
    """The friction table file when the term is on (None when off), not read."""
    return _term_file(values, "friction_table")


def _friction_table_term(values: Values) -> FeedforwardTerm | None:
    path = _friction_table_path(values)
    if path is None:
        return None
    try:
        table = load_friction_table(path)
    except (OSError, ServoAxisError) as err:
        raise ParameterFileError(f"parameter 'friction_table.file': {err}") from err
    return build(
        "",
        FrictionTableTerm,
        keys=NOMINAL_KEYS,
        table=table,
        torque_constant_Nm_per_A=values["nominal.torque_constant_Nm_per_A"],
    )


register_feedforward_term("friction_table", _friction_table_term)


def _mnc_term(values: Values) -> FeedforwardTerm | None:
    """The multirate nonlinearity compensator of 003 eqs. (12)-(15) / (17), if on."""
    if not values["mnc.enabled"]:
        return None
    params = build(
        "mnc.",
        MncParams,
        keys={
            "alpha": "mnc.alpha_s_per_rad",
            "torque_constant_Nm_per_A": "nominal.torque_constant_Nm_per_A",
            "lead_m_per_rad": "lead_m_per_rad",
            "ratio": "control_period_s",
            "control_period_s": "control_period_s",
        },
        unbalance_Nm=values["mnc.unbalance_Nm"],
        coulomb_Nm=values["mnc.coulomb_Nm"],
        friction=values["mnc.friction"],
        alpha=values["mnc.alpha_s_per_rad"],
        omega_th_rad_s=values["mnc.omega_th_rad_s"],
        torque_constant_Nm_per_A=values["nominal.torque_constant_Nm_per_A"],
        lead_m_per_rad=values["lead_m_per_rad"],
        ratio=grid(values).ratio,
        control_period_s=values["control_period_s"],
    )
    # A feedforward term (registered like the friction table); its U and C
    # follow the online estimates when adaptive.enabled.
    return NonlinearityCompensator(params, reference=build_reference(values))


register_feedforward_term("mnc", _mnc_term)


def _gms_term(values: Values) -> FeedforwardTerm | None:
    """The GMS-model compensation (004 Sect. II-C), if on: its file read and checked."""
    path = _term_file(values, "gms")
    if path is None:
        return None
    try:
        params, _, fingerprint = load_gms_parameters(path)
    except (OSError, ServoAxisError) as err:
        raise ParameterFileError(f"parameter 'gms.file': {err}") from err
    expected = values["gms.plant"]
    if expected and fingerprint != expected:
        raise ParameterFileError(
            f"parameter 'gms.file': {path} was identified on plant {fingerprint!r}, "
            f"this run's plant is {expected!r}: fit it again on a friction_id run of this plant"
        )
    return build(
        "",
        GmsTerm,
        keys={**NOMINAL_KEYS, **PERIOD_KEYS},
        params=params,
        torque_constant_Nm_per_A=values["nominal.torque_constant_Nm_per_A"],
        control_period_s=values["control_period_s"],
    )


register_feedforward_term("gms", _gms_term)


def _sigmoid_term(values: Values) -> FeedforwardTerm | None:
    """The sigmoid law of 004 eq. (9), if on."""
    if not values["sigmoid.enabled"]:
        return None
    params = build(
        "sigmoid.",
        SigmoidParams,
        sigma_m2_per_rad=values["sigmoid.sigma_m2_per_rad"],
        gamma_m_per_rad=values["sigmoid.gamma_m_per_rad"],
        coulomb_Nm=values["sigmoid.coulomb_Nm"],
    )
    return build(
        "sigmoid.",
        SigmoidTerm,
        keys={**NOMINAL_KEYS, "control_period_s": "control_period_s"},
        params=params,
        reference=build_reference(values),
        control_period_s=values["control_period_s"],
        torque_constant_Nm_per_A=values["nominal.torque_constant_Nm_per_A"],
        search_horizon_s=values["sigmoid.search_horizon_s"],
    )


register_feedforward_term("sigmoid", _sigmoid_term)


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
    """The feedforward terms the values switch on, in registration order.

    With the feedback's DOB on (``dob.*``, copied from the feedback section),
    their sum enters outside the DOB (:class:`OutsideObserver`, 004 Fig. 5).
    """
    terms = [t for b in FEEDFORWARD_TERMS.values() if (t := b(values)) is not None]
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


@dataclass(frozen=True)
class LearningLawEntry:
    """A registered learning law.

    Attributes
    ----------
    schema : mapping of str to Param
        The law's own keys in the ``learning`` section.
    period, side : str
        ``cycle``/``trial`` and ``target``/``input`` (:mod:`servo_axis.core.learning.base`).
    build : callable
        ``build(values) -> LearningLaw`` from checked learning values.
    outputs : tuple of str
        The topics the learning unit publishes with this law.
    """

    schema: Mapping[str, Param]
    period: str
    side: str
    build: Callable[[Values], LearningLaw]
    outputs: tuple[str, ...] = ()


LEARNING_LAWS: dict[str, LearningLawEntry] = {}


def register_learning_law(
    name: str,
    *,
    schema: Mapping[str, Param],
    period: str,
    side: str,
    build: Callable[[Values], LearningLaw],
    identifies: tuple[str, ...] = (),
) -> None:
    """Make a learning law selectable as ``learning.law: <name>``.

    ``identifies`` names what else the law publishes besides its correction
    and the per-period stats: ``"learning/parameters"`` and / or
    ``"learning/friction_table"`` (an :class:`~servo_axis.core.learning.base.IdentifyingLaw`).
    """
    correction = "learning/correction" if side == "target" else "learning/input_correction"
    outputs = (correction, "learning/cycle_stats", *identifies)
    LEARNING_LAWS[name] = LearningLawEntry(
        schema=schema, period=period, side=side, build=build, outputs=outputs
    )


def learning_law(name: object, key: str = "law") -> LearningLawEntry:
    """The registered law ``name`` (ParameterFileError naming ``key`` otherwise)."""
    if not isinstance(name, str) or name not in LEARNING_LAWS:
        raise ParameterFileError(
            f"parameter '{key}': expected one of {sorted(LEARNING_LAWS)}, got {name!r}"
        )
    return LEARNING_LAWS[name]


def _rptc(values: Values) -> LearningLaw:
    g = grid(values)
    nd = build("", g.instants_per, period_s=values["cycle_s"], name="cycle_s", minimum=4)
    nd = cycle_instants("cycle_s", values["cycle_s"], nd)
    params = build(
        "",
        LearningParams,
        keys={**PERIOD_KEYS, "samples_per_cycle": "cycle_s"},
        samples_per_cycle=nd,
        nq=values["nq"],
        n=values["n"],
        period_s=g.reference_period_s,
    )
    return PeriodicSignalGenerator(params)


register_learning_law("rptc", schema={}, period="cycle", side="target", build=_rptc)


def ilc_params(values: Values) -> Any:
    """The :class:`~servo_axis.core.learning.ilc.IlcParams` of checked values of a trial law."""
    from servo_axis.core.learning.ilc import IlcParams

    g = grid(values)
    check_trial_period("cycle_s", values["cycle_s"], values)
    n = build("", g.steps_per, period_s=values["cycle_s"], name="cycle_s")
    nominal = nominal_model(values)
    pid = build(
        "feedback.",
        design_pid_pole_placement,
        keys=NOMINAL_KEYS,
        inertia_kgm2=nominal.inertia_kgm2,
        damping_Nms_per_rad=nominal.damping_Nms_per_rad,
        torque_constant_Nm_per_A=nominal.torque_constant_Nm_per_A,
        bandwidth_hz=values["feedback.bandwidth_hz"],
    )
    return build(
        "",
        IlcParams,
        keys={"samples_per_trial": "cycle_s", "period_s": "control_period_s"},
        samples_per_trial=n,
        nq=values["nq"],
        period_s=g.control_period_s,
        lead_m_per_rad=values["lead_m_per_rad"],
        nominal=nominal,
        pid=pid,
    )


def _silc(values: Values) -> LearningLaw:
    from servo_axis.core.learning.ilc import StandardIlc

    law: LearningLaw = build("", StandardIlc, params=ilc_params(values))
    return law


def _trial_reference(values: Values) -> Callable[[int], tuple[Any, Any, Any]]:
    """``reference_of(trial)``: the reference of 1-based trial ``trial`` at its control samples (m)."""
    reference = build_reference(values)
    g = grid(values)
    n = g.steps_per(values["cycle_s"], name="cycle_s")
    k = np.arange(n)

    def reference_of(trial: int) -> tuple[Any, Any, Any]:
        return reference.sample(((trial - 1) * n + k) * g.control_period_s)

    return reference_of


def _pilc(friction_table: bool) -> Callable[[Values], LearningLaw]:
    def make(values: Values) -> LearningLaw:
        from servo_axis.core.learning.pilc import (
            ProjectionIlc,
            ProjectionParams,
            reversal_displacement,
            weighting,
        )

        projection = build(
            "",
            ProjectionParams,
            x_mu_m=values["x_mu_m"],
            threshold_m=values["threshold_m"],
        )
        reference_of = _trial_reference(values)
        law: LearningLaw = build(
            "",
            ProjectionIlc,
            ilc=ilc_params(values),
            projection=projection,
            reference_of=reference_of,
            friction_table=friction_table,
        )
        if friction_table:
            # W of eq. (27) must have data in every trajectory: refused here,
            # before anything moves, not at the end of a trial.
            reference = build_reference(values)
            firsts = getattr(reference, "first_trials", (1,))
            for trial in firsts:
                pos, vel, _ = reference_of(trial)
                x_r = reversal_displacement(pos, vel)
                try:
                    weighting(x_r, threshold_m=values["threshold_m"], velocity_m_s=vel)
                except ServoAxisError as err:
                    detail = str(err).partition(": ")[2]
                    raise ParameterFileError(
                        f"parameter 'threshold_m': trial {trial} (its reference): {detail}"
                    ) from err
        return law

    return make


register_learning_law("silc", schema=schemas.ILC, period="trial", side="input", build=_silc)
register_learning_law(
    "pilc_bf",
    schema={**schemas.ILC, **schemas.PILC},
    period="trial",
    side="input",
    build=_pilc(False),
    identifies=("learning/parameters",),
)
register_learning_law(
    "pilc_bfft",
    schema={**schemas.ILC, **schemas.PILC},
    period="trial",
    side="input",
    build=_pilc(True),
    identifies=("learning/parameters", "learning/friction_table"),
)


def build_learning_law(values: Values) -> LearningLaw:
    """The learning law of checked learning values."""
    return learning_law(values["law"]).build(values)


# --------------------------------------------------------------------------- identifiers


@dataclass(frozen=True)
class IdentifierEntry:
    """A registered online identification method.

    Attributes
    ----------
    schema : mapping of str to Param
        The method's own keys in the ``identifier`` section (beside :data:`schemas.IDENTIFIER`).
    build : callable
        ``build(values) -> OnlineIdentifier`` from checked identifier values.
    estimates_friction : bool
        Whether its ``C`` is an estimate (the feedforward then compensates
        friction with it, ``mnc.friction``) or always 0.
    """

    schema: Mapping[str, Param]
    build: Callable[[Values], OnlineIdentifier]
    estimates_friction: bool


IDENTIFIERS: dict[str, IdentifierEntry] = {}


def register_identifier(
    name: str,
    *,
    schema: Mapping[str, Param],
    build: Callable[[Values], OnlineIdentifier],
    estimates_friction: bool,
) -> None:
    """Make an online identifier selectable as ``identifier.method: <name>``."""
    IDENTIFIERS[name] = IdentifierEntry(
        schema=schema, build=build, estimates_friction=estimates_friction
    )


def identifier_method(name: object, key: str = "method") -> IdentifierEntry:
    """The registered method ``name`` (ParameterFileError naming ``key`` otherwise)."""
    if not isinstance(name, str) or name not in IDENTIFIERS:
        raise ParameterFileError(
            f"parameter '{key}': expected one of {sorted(IDENTIFIERS)}, got {name!r}"
        )
    return IDENTIFIERS[name]


def _bounds(values: Values, key: str) -> tuple[float, float]:
    pair = values[key]
    if len(pair) != 2 or not pair[0] < pair[1]:
        raise ParameterFileError(
            f"parameter '{key}': expected [min, max] with min < max, got {pair!r}"
        )
    return float(pair[0]), float(pair[1])


def _dlpid(mode: str) -> Callable[[Values], OnlineIdentifier]:
    def make(values: Values) -> OnlineIdentifier:
        estimate_schedule(values, "rls_period_s", "latency_s")
        names = ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm")
        bounds = [_bounds(values, f"bounds.{n}") for n in names]
        forgetting = values["forgetting"]
        if len(forgetting) != 3:
            raise ParameterFileError(
                f"parameter 'forgetting': expected 3 factors (J, D, U), got {forgetting!r}"
            )
        initial = (
            values["nominal.inertia_kgm2"],
            values["nominal.damping_Nms_per_rad"],
            values["initial.unbalance_Nm"],
        )
        for name, key, (lo, hi), v in zip(
            names,
            ("nominal.inertia_kgm2", "nominal.damping_Nms_per_rad", "initial.unbalance_Nm"),
            bounds,
            initial,
            strict=True,
        ):
            if not lo <= v <= hi:
                raise ParameterFileError(
                    f"parameter '{key}': the initial estimate must lie inside bounds.{name} "
                    f"[{lo!r}, {hi!r}], got {v!r}"
                )
        rls = build(
            "",
            RlsParams,
            keys={"initial_covariance": "initial_covariance", "forgetting": "forgetting"},
            initial=initial,
            lower=tuple(b[0] for b in bounds),
            upper=tuple(b[1] for b in bounds),
            forgetting=tuple(forgetting),
            initial_covariance=values["initial_covariance"],
            names=("J", "D", "U"),
        )
        friction: dict[str, Any] = {}
        if mode == "double_layer":
            friction = {
                "friction_cutoff_hz": values["friction.cutoff_hz"],
                "initial_friction_Nm": values["initial.coulomb_Nm"],
                "friction_bounds": _bounds(values, "bounds.coulomb_Nm"),
                "friction_velocity_min_rad_s": values["friction.velocity_min_rad_s"],
            }
        params = build(
            "",
            DlpidParams,
            keys={
                "period_s": "control_period_s",
                "friction_cutoff_hz": "friction.cutoff_hz",
                "initial_friction_Nm": "initial.coulomb_Nm",
                "friction_bounds": "bounds.coulomb_Nm",
                "friction_velocity_min_rad_s": "friction.velocity_min_rad_s",
                "angle_min_rad": "conditions.angle_min_rad",
                "velocity_min_rad_s": "conditions.velocity_min_rad_s",
                "acceleration_min_rad_s2": "conditions.acceleration_min_rad_s2",
            },
            rls=rls,
            period_s=values["control_period_s"],
            rls_period_s=values["rls_period_s"],
            pd_cutoff_hz=values["pd_cutoff_hz"],
            angle_min_rad=values["conditions.angle_min_rad"],
            velocity_min_rad_s=values["conditions.velocity_min_rad_s"],
            acceleration_min_rad_s2=values["conditions.acceleration_min_rad_s2"],
            pe_window=values["pe_window"],
            mode=mode,
            **friction,
        )
        return Dlpid(params)

    return make


register_identifier(
    "dlpid", schema=schemas.DLPID_FRICTION, build=_dlpid("double_layer"), estimates_friction=True
)
register_identifier("marc", schema={}, build=_dlpid("single_layer"), estimates_friction=False)


def build_identifier(values: Values) -> OnlineIdentifier:
    """The online identifier of checked identifier values."""
    return identifier_method(values["method"]).build(values)


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


# --------------------------------------------------------------------------- schemas and values

#: Schema of each node (shared keys included); the plant's adds its model's keys.
NODE_SCHEMAS: dict[str, Mapping[str, Param]] = {
    "plant": {**schemas.SHARED, **schemas.PLANT},
    "feedback": {**schemas.SHARED, **schemas.FEEDBACK},
    "feedforward": {**schemas.SHARED, **schemas.FEEDFORWARD},
    "learning": {**schemas.SHARED, **schemas.LEARNING},
    "recorder": {**schemas.SHARED, **schemas.RECORDER},
    "identifier": {**schemas.SHARED, **schemas.IDENTIFIER},
}


def node_schema(role: str, given: Values) -> dict[str, Param]:
    """The full schema of node ``role`` for the keys ``given`` (the model/law chosen there)."""
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
    return schema


def checked_values(role: str, given: Values) -> dict[str, Any]:
    """Checked values of node ``role``: ``given`` where set, defaults elsewhere.

    Each key against its schema first (:func:`~servo_axis.params.schema.check_values`),
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
    elif role == "feedback":
        build_loop(values)
        build_deformation(values)
    elif role == "feedforward":
        _friction_table_path(values)
        _term_file(values, "gms")
        if values["sigmoid.enabled"]:
            _sigmoid_term(values)
        build_generator(values, terms=[])
    elif role == "learning":
        build_learning_law(values)
        build_reference(values)
    elif role == "recorder":
        check_recorder_topics(values)
    elif role == "identifier":
        build_identifier(values)


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


def node_values(scenario: dict[str, Any], role: str) -> dict[str, Any]:
    """Checked parameter values of one node of a scenario (no ROS).

    The feedforward generator's ``learning.law`` is the learning section's
    ``law`` and, with an identifier, its ``adaptive.*`` and initial
    ``mnc.*`` come from the identifier section (:func:`adaptive_overrides`;
    one source, the runner passes them on the same way).
    """
    given = node_params(scenario, role)
    if role == "feedforward" and "learning.law" not in given:
        law = node_params(scenario, "learning").get("law")
        if law is not None:
            given = {**given, "learning.law": law}
    if role == "feedforward" and "identifier" in scenario:
        given = {**given, **adaptive_overrides(scenario)}
    if role == "feedforward":
        given = {**given, **feedforward_overrides(scenario, given)}
    return checked_values(role, given)


def feedforward_overrides(scenario: dict[str, Any], given: Values) -> dict[str, Any]:
    """What the feedforward copies from the other sections: one source for each value.

    ``gms.plant``, the plant a GMS file must come from, when the GMS term is
    on; ``dob.enabled`` and ``dob.cutoff_hz`` of the feedback, which the
    compensation terms bypass (:func:`build_terms`).
    """
    feedback = node_params(scenario, "feedback")
    out = {
        key: feedback.get(key, schemas.FEEDBACK[key].default)
        for key in ("dob.enabled", "dob.cutoff_hz")
    }
    if given.get("gms.enabled", False) and "gms.plant" not in given:
        out["gms.plant"] = plant_fingerprint(scenario)
    return out


def feedforward_values(scenario: dict[str, Any], scenario_path: Path) -> dict[str, Any]:
    """Checked feedforward values, the friction-table path made absolute."""
    values = node_values(scenario, "feedforward")
    for key in ("friction_table.file", "gms.file"):
        values[key] = resolve_table(values[key], Path(scenario_path).resolve().parent)
    return values
