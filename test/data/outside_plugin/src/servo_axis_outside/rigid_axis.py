"""Plant model ``rigid_viscous_axis``: a rigid axis with viscous friction, stepped exactly.

``J theta'' = K_T i - b theta'`` with the current ``i`` held over each
control period ``T_u`` (zero-order hold), clipped at ``+-current_limit_A``.
With ``a = b / J`` and ``w_inf = K_T i / b`` the exact step from
``(theta_0, w_0)`` is::

    w(T)     = w_inf + (w_0 - w_inf) e^(-a T)
    theta(T) = theta_0 + w_inf T + (w_0 - w_inf) (1 - e^(-a T)) / a

Ideal sensors: the encoder reads ``theta``, the linear scale ``R theta``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from servo_axis.core.models.base import Plant, PlantOutput, clipped_current
from servo_axis.params.param import Param, build
from servo_axis.params.registry import PlantModelEntry
from servo_axis.params.values import PlantValues

SCHEMA: dict[str, Param] = {
    "torque_constant_Nm_per_A": Param(
        0.715, unit="N m/A", above=0.0, meaning="K_T: motor torque per ampere"
    ),
    "inertia_kgm2": Param(0.01, unit="kg m^2", above=0.0, meaning="J: inertia at the motor"),
    "viscous_Nms_per_rad": Param(
        0.2, unit="N m s/rad", above=0.0, meaning="b: viscous friction torque per rad/s"
    ),
    "current_limit_A": Param(20.0, unit="A", above=0.0, meaning="amplifier saturation"),
}


@dataclass
class RigidViscousAxis:
    """``J theta'' = K_T i - b theta'``, exact over each control period.

    Parameters
    ----------
    torque_constant_Nm_per_A, inertia_kgm2, viscous_Nms_per_rad : float
        ``K_T`` (N m/A), ``J`` (kg m^2), ``b`` (N m s/rad), all > 0.
    current_limit_A : float
        Saturation of the held current, A.
    control_period_s : float
        ``T_u``, s.
    lead_m_per_rad : float
        ``R``: the table position is ``R theta``, m.
    """

    torque_constant_Nm_per_A: float
    inertia_kgm2: float
    viscous_Nms_per_rad: float
    current_limit_A: float
    control_period_s: float
    lead_m_per_rad: float
    _k: int = field(default=0, init=False)
    _theta: float = field(default=0.0, init=False)
    _omega: float = field(default=0.0, init=False)
    _torque: float = field(default=0.0, init=False)

    @property
    def step_index(self) -> int:
        """Index of the current control sample."""
        return self._k

    def reset(self) -> None:
        """At rest at angle 0, step 0."""
        self._k, self._theta, self._omega, self._torque = 0, 0.0, 0.0, 0.0

    def output(self) -> PlantOutput:
        """Readings (ideal) and true state at the current control sample."""
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
            friction_force_N=-self.viscous_Nms_per_rad * self._omega / r,
        )

    def step(self, current_A: float) -> PlantOutput:
        """Hold ``current_A`` (A) over one control period; the output at the next sample."""
        current = clipped_current(current_A, self.current_limit_A)
        self._torque = self.torque_constant_Nm_per_A * current
        a = self.viscous_Nms_per_rad / self.inertia_kgm2
        w_inf = self._torque / self.viscous_Nms_per_rad
        decay = math.exp(-a * self.control_period_s)
        self._theta += w_inf * self.control_period_s + (self._omega - w_inf) * (1 - decay) / a
        self._omega = w_inf + (self._omega - w_inf) * decay
        self._k += 1
        return self.output()


def _build(values: PlantValues, rng: np.random.Generator) -> Plant:
    # The model's own keys by name (its class is made from SCHEMA when the
    # suite loads the entry: values.inertia_kgm2 too), the node's as attributes.
    own: dict[str, Any] = {k: values[k] for k in SCHEMA}
    return build(
        "",
        RigidViscousAxis,
        **own,
        control_period_s=values.control_period_s,
        lead_m_per_rad=values.lead_m_per_rad,
    )


#: The entry point ``servo_axis.plant_models: rigid_viscous_axis``.
PLANT_MODEL = PlantModelEntry(
    schema=SCHEMA,
    build=_build,
    rotary=False,
    description="rigid axis with viscous friction, exact ZOH (an outside package)",
)
