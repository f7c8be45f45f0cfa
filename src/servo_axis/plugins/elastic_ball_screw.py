"""Plant model ``elastic_ball_screw``: the two-inertia ball-screw axis of paper 004.

Motor and table coupled by the screw's axial and torsional stiffness, with
nonlinear ball contacts, nut and guide friction and a current loop
(:class:`servo_axis.core.models.elastic_ball_screw.ElasticBallScrewPlant`);
an axial mode outside 100-200 Hz is logged as a warning at start.
"""

from __future__ import annotations

import numpy as np

from servo_axis.core.models.base import Plant
from servo_axis.core.models.elastic_ball_screw import (
    NUT_FRICTION_MODELS,
    ElasticBallScrewParams,
    ElasticBallScrewPlant,
    mode_warning,
)
from servo_axis.params.param import Param, build, dataclass_defaults
from servo_axis.params.registry import PlantModelEntry
from servo_axis.plugins.sensors import ENCODER_AND_SCALE, encoder_and_scale
from servo_axis.plugins.values import ElasticBallScrewValues

_ELASTIC = dataclass_defaults(ElasticBallScrewParams)

#: Keys of the plant model ``elastic_ball_screw`` (paper 004; defaults and the
#: choices behind them: :mod:`servo_axis.core.models.elastic_ball_screw`).
ELASTIC_BALL_SCREW: dict[str, Param] = {
    "torque_constant_Nm_per_A": Param(
        _ELASTIC["torque_constant_Nm_per_A"], unit="N m/A", above=0.0, meaning="K_T (004 Table I)"
    ),
    "motor_inertia_kgm2": Param(
        _ELASTIC["motor_inertia_kgm2"],
        unit="kg m^2",
        above=0.0,
        meaning="J_m: motor and screw rotation (J_n - M_t R^2 = 1.604e-3, so that the rigid "
        "body is J_n = 2.6e-3 of 004 eq. (1))",
    ),
    "motor_damping_Nms_per_rad": Param(
        _ELASTIC["motor_damping_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="B_m (B_n - C_t R^2 = 0.0335, so that the rigid body has B_n = 0.070)",
    ),
    "table_mass_kg": Param(
        _ELASTIC["table_mass_kg"],
        unit="kg",
        above=0.0,
        meaning="M: nut and table (004 Table I: 273)",
    ),
    "table_damping_Ns_per_m": Param(
        _ELASTIC["table_damping_Ns_per_m"],
        unit="N s/m",
        minimum=0.0,
        meaning="C_t: viscosity of the linear guide (004 Table I: 1e4)",
    ),
    "axial_stiffness_N_per_m": Param(
        _ELASTIC["axial_stiffness_N_per_m"],
        unit="N/m",
        above=0.0,
        meaning="k_a: screw axial, nut and bearings in series (1.55e8: first axial mode 150 Hz); "
        "a mode outside 100-200 Hz is logged as a warning",
    ),
    "torsional_stiffness_Nm_per_rad": Param(
        _ELASTIC["torsional_stiffness_Nm_per_rad"],
        unit="N m/rad",
        above=0.0,
        meaning="k_t: screw torsion between motor and nut, in series with k_a as R^2 / k_t",
    ),
    "screw_damping_Ns_per_m": Param(
        _ELASTIC["screw_damping_Ns_per_m"],
        unit="N s/m",
        minimum=0.0,
        meaning="c_s: structural damping of the deformation (1.6e4: about 5 % on the axial mode)",
    ),
    "contact_zone_m": Param(
        _ELASTIC["contact_zone_m"],
        unit="m",
        minimum=0.0,
        meaning="g: soft zone of the ball contacts around zero load (004 Fig. 7: nonlinear "
        "springs); 0 = linear spring",
    ),
    "contact_stiffness_ratio": Param(
        _ELASTIC["contact_stiffness_ratio"],
        above=0.0,
        maximum=1.0,
        meaning="k_0 / k_h: stiffness at zero load over the loaded stiffness",
    ),
    "nut_friction_Nm": Param(
        _ELASTIC["nut_friction_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="rolling friction of nut and screw bearings at the motor once rolling",
    ),
    "nut_presliding_m": Param(
        _ELASTIC["nut_presliding_m"],
        unit="m",
        above=0.0,
        meaning="its pre-sliding width at the table (004 Fig. 4b: about 15 um)",
    ),
    "guide_friction_N": Param(
        _ELASTIC["guide_friction_N"],
        unit="N",
        minimum=0.0,
        meaning="rolling friction of the linear guide once rolling (pattern I/II at the stop "
        "switches at a deceleration of guide_friction_N / table_mass_kg)",
    ),
    "guide_presliding_m": Param(
        _ELASTIC["guide_presliding_m"], unit="m", above=0.0, meaning="its pre-sliding width"
    ),
    "friction_elements": Param(
        _ELASTIC["friction_elements"],
        minimum=1,
        maximum=200,
        meaning="Maxwell-slip elements per friction set",
    ),
    "nut_friction": Param(
        _ELASTIC["nut_friction"],
        choices=NUT_FRICTION_MODELS,
        meaning="what drives the ball nut's friction: displacement (the motor angle, nut and "
        "bearings in one set) or contact (the balls' contact deformation, so that it reverses "
        "with the load's flank, 004 Sect. III-B; the bearings apart)",
    ),
    "contact_travel_m": Param(
        _ELASTIC["contact_travel_m"],
        unit="m",
        minimum=0.0,
        meaning="contact: D, the balls' contact deformation is D tanh(F / F_p) in series with "
        "the linear k_h (contact_zone_m must be 0)",
    ),
    "nut_preload_N": Param(
        _ELASTIC["nut_preload_N"],
        unit="N",
        above=0.0,
        meaning="contact: F_p, the preload: the load over which the balls change flank",
    ),
    "contact_presliding_m": Param(
        _ELASTIC["contact_presliding_m"],
        unit="m",
        above=0.0,
        meaning="contact: the nut's pre-sliding width on the contact deformation; below "
        "contact_travel_m",
    ),
    "bearing_friction_Nm": Param(
        _ELASTIC["bearing_friction_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="contact: rolling friction of the screw bearings at the motor (0 with "
        "displacement: nut_friction_Nm holds both)",
    ),
    "bearing_presliding_m": Param(
        _ELASTIC["bearing_presliding_m"],
        unit="m",
        above=0.0,
        meaning="contact: the bearings' pre-sliding width at the table",
    ),
    "current_bandwidth_hz": Param(
        _ELASTIC["current_bandwidth_hz"],
        unit="Hz",
        minimum=0.0,
        meaning="first-order current loop (004: 1 kHz); 0 = ideal",
    ),
    "sim_step_s": Param(
        _ELASTIC["sim_step_s"],
        unit="s",
        above=0.0,
        meaning="RK4 sub-step; divides control_period_s",
    ),
    "current_limit_A": Param(
        _ELASTIC["current_limit_A"], unit="A", above=0.0, meaning="amplifier saturation"
    ),
    "initial_position_m": Param(
        _ELASTIC["initial_position_m"],
        unit="m",
        meaning="table position at step 0 (motor at x / R, at rest, relaxed)",
    ),
    **ENCODER_AND_SCALE,
}


def elastic_ball_screw_params(values: ElasticBallScrewValues) -> ElasticBallScrewParams:
    """:class:`ElasticBallScrewParams` from checked plant values (paper 004; also the model's check)."""
    encoder, scale = encoder_and_scale(values.encoder, values.scale)
    return build(
        "",
        ElasticBallScrewParams,
        torque_constant_Nm_per_A=values.torque_constant_Nm_per_A,
        motor_inertia_kgm2=values.motor_inertia_kgm2,
        motor_damping_Nms_per_rad=values.motor_damping_Nms_per_rad,
        table_mass_kg=values.table_mass_kg,
        table_damping_Ns_per_m=values.table_damping_Ns_per_m,
        axial_stiffness_N_per_m=values.axial_stiffness_N_per_m,
        torsional_stiffness_Nm_per_rad=values.torsional_stiffness_Nm_per_rad,
        screw_damping_Ns_per_m=values.screw_damping_Ns_per_m,
        contact_zone_m=values.contact_zone_m,
        contact_stiffness_ratio=values.contact_stiffness_ratio,
        nut_friction_Nm=values.nut_friction_Nm,
        nut_presliding_m=values.nut_presliding_m,
        guide_friction_N=values.guide_friction_N,
        guide_presliding_m=values.guide_presliding_m,
        friction_elements=values.friction_elements,
        nut_friction=values.nut_friction,
        contact_travel_m=values.contact_travel_m,
        nut_preload_N=values.nut_preload_N,
        contact_presliding_m=values.contact_presliding_m,
        bearing_friction_Nm=values.bearing_friction_Nm,
        bearing_presliding_m=values.bearing_presliding_m,
        current_bandwidth_hz=values.current_bandwidth_hz,
        sim_step_s=values.sim_step_s,
        current_limit_A=values.current_limit_A,
        initial_position_m=values.initial_position_m,
        lead_m_per_rad=values.lead_m_per_rad,
        control_period_s=values.control_period_s,
        encoder=encoder,
        scale=scale,
    )


def _elastic_warnings(values: ElasticBallScrewValues) -> list[str]:
    warning = mode_warning(elastic_ball_screw_params(values))
    return [] if warning is None else [warning]


def _build(values: ElasticBallScrewValues, rng: np.random.Generator) -> Plant:
    return ElasticBallScrewPlant(elastic_ball_screw_params(values), rng=rng)


#: The entry point ``servo_axis.plant_models: elastic_ball_screw``.
PLANT_MODEL = PlantModelEntry(
    schema=ELASTIC_BALL_SCREW,
    build=_build,
    check=elastic_ball_screw_params,
    values=ElasticBallScrewValues,
    warnings=_elastic_warnings,
    rotary=False,
    description="two-inertia ball-screw axis with elastic screw and nonlinear ball contacts (004)",
    # The ball-nut friction option (issue 21) came after GMS files were fitted.
    fingerprint_if_set=frozenset(
        {
            "nut_friction",
            "nut_preload_N",
            "contact_travel_m",
            "contact_presliding_m",
            "bearing_friction_Nm",
            "bearing_presliding_m",
        }
    ),
)
