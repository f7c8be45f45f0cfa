"""A test-only plant model: how adding a model is one module plus its registration.

A frictionless rigid body ``J theta'' = K_T i`` (no damping, ideal sensors),
discretised exactly (zero-order hold) at the control period. Importing this
module registers it as ``plant.model: toy_rigid_body``; nothing else of the
project is edited for it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from servo_axis.core.models.base import PlantOutput
from servo_axis.params.factories import PLANT_MODELS, register_plant_model
from servo_axis.params.param import Param

NAME = "toy_rigid_body"

SCHEMA = {
    "inertia_kgm2": Param(0.01, unit="kg m^2", above=0.0, meaning="J of J theta'' = K_T i"),
    "torque_constant_Nm_per_A": Param(0.715, unit="N m/A", above=0.0, meaning="K_T"),
}


@dataclass
class ToyRigidBody:
    """``J theta'' = K_T i`` stepped exactly with the current held over ``T_u``."""

    inertia_kgm2: float
    torque_constant_Nm_per_A: float
    control_period_s: float
    lead_m_per_rad: float

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self._k = 0
        self._theta = 0.0
        self._omega = 0.0
        self._torque = 0.0

    @property
    def step_index(self) -> int:
        return self._k

    def output(self) -> PlantOutput:
        r = self.lead_m_per_rad
        return PlantOutput(
            step=self._k,
            encoder_rad=self._theta,
            scale_m=self._theta * r,
            angle_rad=self._theta,
            velocity_rad_s=self._omega,
            position_m=self._theta * r,
            velocity_m_s=self._omega * r,
            motor_torque_Nm=self._torque,
            friction_force_N=0.0,
        )

    def step(self, current_A: float) -> PlantOutput:
        t = self.control_period_s
        self._torque = self.torque_constant_Nm_per_A * current_A
        accel = self._torque / self.inertia_kgm2
        self._theta += self._omega * t + 0.5 * accel * t * t
        self._omega += accel * t
        self._k += 1
        return self.output()


def build(values: Any, rng: np.random.Generator) -> ToyRigidBody:
    return ToyRigidBody(
        inertia_kgm2=values["inertia_kgm2"],
        torque_constant_Nm_per_A=values["torque_constant_Nm_per_A"],
        control_period_s=values["control_period_s"],
        lead_m_per_rad=values["lead_m_per_rad"],
    )


if NAME not in PLANT_MODELS:
    register_plant_model(NAME, schema=SCHEMA, build=build)
