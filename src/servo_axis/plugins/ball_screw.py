"""Plant model ``ball_screw``: the rigid ball-screw axis of paper 000 eq. (30).

Rigid body with resonance modes, dead time, rolling (Maxwell-slip) and
Coulomb friction, an input disturbance and quantised sensors
(:class:`servo_axis.core.models.ball_screw.BallScrewPlant`); defaults are the
X axis of docs/design.md section 7. Selected by ``plant.model: ball_screw``
(the default).
"""

from __future__ import annotations

import numpy as np

from servo_axis.core.errors import ParameterFileError
from servo_axis.core.friction.model import FrictionParams
from servo_axis.core.models.ball_screw import BallScrewParams, BallScrewPlant, DisturbanceParams
from servo_axis.core.models.base import Plant
from servo_axis.params.factories import MAX_SIM_STEPS
from servo_axis.params.param import Param, build, dataclass_defaults
from servo_axis.params.registry import PlantModelEntry
from servo_axis.plugins.sensors import ENCODER_AND_SCALE, encoder_and_scale
from servo_axis.plugins.values import BallScrewValues

_BALL_SCREW = dataclass_defaults(BallScrewParams)
_FRICTION = dataclass_defaults(FrictionParams)
_DISTURBANCE = dataclass_defaults(DisturbanceParams)

#: Keys of the plant with ``model: ball_screw``: eq. (30) of 000 with docs/design.md section 7 defaults.
BALL_SCREW: dict[str, Param] = {
    "torque_constant_Nm_per_A": Param(
        _BALL_SCREW["torque_constant_Nm_per_A"],
        unit="N m/A",
        above=0.0,
        meaning="K_T of eq. (30) of 000: motor torque per ampere of current (0.715)",
    ),
    "inertia_kgm2": Param(
        _BALL_SCREW["inertia_kgm2"],
        unit="kg m^2",
        above=0.0,
        meaning="J of eq. (30): rigid-body inertia at the motor (0.01)",
    ),
    "damping_Nms_per_rad": Param(
        _BALL_SCREW["damping_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="D of eq. (30): viscous damping at the motor (0.1)",
    ),
    "modes.frequency_hz": Param(
        [0.0],
        unit="Hz",
        minimum=0.0,
        meaning="resonance frequencies f_i of eq. (30), one per mode (> 0); "
        "all three modes.* lists [0.0] = no mode",
    ),
    "modes.zeta": Param(
        [0.0],
        minimum=0.0,
        meaning="damping ratios zeta_i of the modes of eq. (30) (> 0 for a mode)",
    ),
    "modes.a": Param(
        [0.0],
        meaning="relative gains a_i of the modes of eq. (30): K_i = a_i K_T / J (docs/design.md section 7)",
    ),
    "dead_time_s": Param(
        _BALL_SCREW["dead_time_s"],
        unit="s",
        minimum=0.0,
        meaning="dead time T_d of eq. (30) (000: 70 us), a whole number of sim_step_s",
    ),
    "sim_step_s": Param(
        _BALL_SCREW["sim_step_s"],
        unit="s",
        above=0.0,
        meaning="integration step h of the plant (exact ZOH); divides control_period_s",
    ),
    "current_limit_A": Param(
        _BALL_SCREW["current_limit_A"],
        unit="A",
        above=0.0,
        meaning="amplifier saturation: the current command is clipped to +-current_limit_A",
    ),
    "initial_angle_rad": Param(0.0, unit="rad", meaning="motor angle at step 0"),
    "initial_velocity_rad_s": Param(0.0, unit="rad/s", meaning="motor velocity at step 0"),
    "friction.rolling_coulomb_Nm": Param(
        _FRICTION["rolling_coulomb_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="rolling (Maxwell-slip) friction level T_c at the motor once the balls roll "
        "(region B, 000 Fig. 4; 001: 3.2 N m); 0 = off",
    ),
    "friction.presliding_width_m": Param(
        _FRICTION["presliding_width_m"],
        unit="m",
        above=0.0,
        meaning="pre-sliding width at the table: displacement from a reversal at which rolling "
        "friction reaches T_c (region A; about 10 um)",
    ),
    "friction.elements": Param(
        _FRICTION["elements"],
        minimum=1,
        maximum=200,
        meaning="number of Maxwell-slip elements (knots of the piecewise-linear virgin curve)",
    ),
    "friction.coulomb_Nm": Param(
        _FRICTION["coulomb_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="plain Coulomb friction level at the motor, T_c tanh(w / w_s); 0 = off",
    ),
    "friction.coulomb_smoothing_rad_s": Param(
        _FRICTION["coulomb_smoothing_rad_s"],
        unit="rad/s",
        above=0.0,
        meaning="velocity w_s of the tanh regularisation of the Coulomb term",
    ),
    "friction.viscous_Nms_per_rad": Param(
        _FRICTION["viscous_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="viscous friction at the motor, in addition to the damping D",
    ),
    "disturbance.amplitude_Nm": Param(
        _DISTURBANCE["amplitude_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="amplitude A of the input disturbance torque A sin(2 pi f t + phi) at the motor "
        "(000 Fig. 13); 0 = none",
    ),
    "disturbance.frequency_hz": Param(
        _DISTURBANCE["frequency_hz"],
        unit="Hz",
        above=0.0,
        meaning="frequency f of the input disturbance torque",
    ),
    "disturbance.phase_rad": Param(
        _DISTURBANCE["phase_rad"],
        unit="rad",
        meaning="phase phi of the input disturbance torque at t = 0",
    ),
    **ENCODER_AND_SCALE,
}

# The modes lists default to [0.0] only so that their type is known; an
# all-zero frequency list means "no modes".
_NO_MODES = [0.0]


def ball_screw_params(values: BallScrewValues) -> BallScrewParams:
    """:class:`BallScrewParams` from checked plant values (also the model's check: what
    depends on several keys, without building the plant)."""
    modes = values.modes
    freqs, zetas, gains = list(modes.frequency_hz), list(modes.zeta), list(modes.a)
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
    h = values.sim_step_s
    if any(f >= 0.5 / h for f in freqs):
        raise ParameterFileError(
            "parameter 'modes.frequency_hz': expected every element below the Nyquist "
            f"frequency of sim_step_s ({0.5 / h:g} Hz), got {freqs!r}"
        )
    for key, seconds in (
        ("control_period_s", values.control_period_s),
        ("dead_time_s", values.dead_time_s),
    ):
        if seconds / h > MAX_SIM_STEPS:
            raise ParameterFileError(
                f"parameter '{key}': expected at most {MAX_SIM_STEPS} integration steps "
                f"(sim_step_s = {h!r} s), got {seconds!r} s"
            )
    encoder, scale = encoder_and_scale(values.encoder, values.scale)
    friction, disturbance = values.friction, values.disturbance
    return build(
        "",
        BallScrewParams,
        torque_constant_Nm_per_A=values.torque_constant_Nm_per_A,
        inertia_kgm2=values.inertia_kgm2,
        damping_Nms_per_rad=values.damping_Nms_per_rad,
        lead_m_per_rad=values.lead_m_per_rad,
        modes=tuple(zip(freqs, zetas, gains, strict=True)),
        dead_time_s=values.dead_time_s,
        control_period_s=values.control_period_s,
        sim_step_s=values.sim_step_s,
        current_limit_A=values.current_limit_A,
        initial_angle_rad=values.initial_angle_rad,
        initial_velocity_rad_s=values.initial_velocity_rad_s,
        friction=build(
            "friction.",
            FrictionParams,
            rolling_coulomb_Nm=friction.rolling_coulomb_Nm,
            presliding_width_m=friction.presliding_width_m,
            elements=friction.elements,
            coulomb_Nm=friction.coulomb_Nm,
            coulomb_smoothing_rad_s=friction.coulomb_smoothing_rad_s,
            viscous_Nms_per_rad=friction.viscous_Nms_per_rad,
        ),
        disturbance=build(
            "disturbance.",
            DisturbanceParams,
            amplitude_Nm=disturbance.amplitude_Nm,
            frequency_hz=disturbance.frequency_hz,
            phase_rad=disturbance.phase_rad,
        ),
        encoder=encoder,
        scale=scale,
    )


def _build(values: BallScrewValues, rng: np.random.Generator) -> Plant:
    return BallScrewPlant(ball_screw_params(values), rng=rng)


#: The entry point ``servo_axis.plant_models: ball_screw``.
PLANT_MODEL = PlantModelEntry(
    schema=BALL_SCREW,
    build=_build,
    check=ball_screw_params,
    values=BallScrewValues,
    rotary=False,
    description="rigid ball-screw axis with resonance modes, dead time and friction, "
    "eq. (30) of 000",
)
