"""Plant model ``tilting_table``: the tilting table of paper 003 eq. (2).

A rotary table with unbalance ``U sin(theta)``, viscous damping and
Coulomb friction that sticks at zero velocity, integrated with RK4
(:class:`servo_axis.core.models.tilting_table.TiltingTablePlant`); defaults
are 003's Table I. Its table turns: its position is the table angle, and a
run's tracking error is in rad (``rotary``).
"""

from __future__ import annotations

import numpy as np

from servo_axis.core.models.base import Plant
from servo_axis.core.models.tilting_table import TiltingTableParams, TiltingTablePlant
from servo_axis.params.param import Param, build, dataclass_defaults
from servo_axis.params.registry import PlantModelEntry
from servo_axis.plugins.values import TiltingTableValues

#: Keys of the plant model ``tilting_table`` (paper 003 eq. (2); defaults: its Table I).
_TILT = dataclass_defaults(TiltingTableParams)
TILTING_TABLE: dict[str, Param] = {
    "torque_constant_Nm_per_A": Param(
        _TILT["torque_constant_Nm_per_A"],
        unit="N m/A",
        above=0.0,
        meaning="K_T: the wire carries a current i, the motor torque is T_m = K_T i",
    ),
    "inertia_kgm2": Param(
        _TILT["inertia_kgm2"], unit="kg m^2", above=0.0, meaning="J of 003 eq. (2) (50e-4)"
    ),
    "damping_Nms_per_rad": Param(
        _TILT["damping_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="D of 003 eq. (2) (130e-4)",
    ),
    "unbalance_Nm": Param(
        _TILT["unbalance_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="U = F R of 003 eq. (1)-(2), the largest unbalance torque (0.3)",
    ),
    "coulomb_Nm": Param(
        _TILT["coulomb_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="C of 003 eq. (2): Coulomb friction that sticks at zero velocity (0.02)",
    ),
    "sim_step_s": Param(
        _TILT["sim_step_s"],
        unit="s",
        above=0.0,
        meaning="RK4 sub-step of the integration; divides control_period_s",
    ),
    "current_limit_A": Param(
        _TILT["current_limit_A"],
        unit="A",
        above=0.0,
        meaning="amplifier saturation (15.27: the test bench's peak torque at K_T = 1)",
    ),
    "initial_angle_rad": Param(0.0, unit="rad", meaning="table angle at step 0"),
    "initial_velocity_rad_s": Param(0.0, unit="rad/s", meaning="table velocity at step 0"),
    "noise_rad": Param(
        _TILT["noise_rad"],
        unit="rad",
        minimum=0.0,
        meaning="half-width of the uniform encoder noise, seeded by noise_seed (003: 1e-5)",
    ),
    "encoder.resolution": Param(
        _TILT["encoder_resolution_rad"],
        unit="rad",
        minimum=0.0,
        meaning="encoder count applied after the noise; 0 = ideal",
    ),
}


def tilting_table_params(values: TiltingTableValues) -> TiltingTableParams:
    """:class:`TiltingTableParams` from checked plant values (paper 003; also the model's check)."""
    return build(
        "",
        TiltingTableParams,
        keys={"encoder_resolution_rad": "encoder.resolution"},
        torque_constant_Nm_per_A=values.torque_constant_Nm_per_A,
        inertia_kgm2=values.inertia_kgm2,
        damping_Nms_per_rad=values.damping_Nms_per_rad,
        unbalance_Nm=values.unbalance_Nm,
        coulomb_Nm=values.coulomb_Nm,
        control_period_s=values.control_period_s,
        sim_step_s=values.sim_step_s,
        current_limit_A=values.current_limit_A,
        initial_angle_rad=values.initial_angle_rad,
        initial_velocity_rad_s=values.initial_velocity_rad_s,
        noise_rad=values.noise_rad,
        encoder_resolution_rad=values.encoder.resolution,
    )


def _build(values: TiltingTableValues, rng: np.random.Generator) -> Plant:
    return TiltingTablePlant(tilting_table_params(values), rng=rng)


#: The entry point ``servo_axis.plant_models: tilting_table``.
PLANT_MODEL = PlantModelEntry(
    schema=TILTING_TABLE,
    build=_build,
    check=tilting_table_params,
    values=TiltingTableValues,
    rotary=True,
    description="tilting table with unbalance and Coulomb friction, eq. (2) of 003 (rotary)",
)
