"""What every plant model offers: the Plant protocol, its outputs and the nominal model.

A plant model is advanced one control period at a time with the current
held over it (``step(current_A)``) and shows at each control sample what the
sensors read and what the true motion is (:class:`PlantOutput`). The
nominal model of paper 000 eq. (1), ``P_n = K_T / (J s^2 + D s)``, is what
the controllers are designed on (PID, DOB, PTC); it is not the plant.

A new model is a class that satisfies :class:`Plant` (a module in this
folder, or in an outside package) plus its entry (parameter schema, builder,
``rotary``) registered as an entry point of group ``servo_axis.plant_models``
(:mod:`servo_axis.params.registry`; the suite's in ``servo_axis.plugins``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, require_nonnegative, require_positive


@dataclass(frozen=True)
class PlantOutput:
    """What the plant shows at a control sample.

    Attributes
    ----------
    step : int
        Control sample index ``k`` (time ``k T_u``).
    encoder_rad : float
        Rotary encoder reading: motor angle, rad.
    scale_m : float
        Linear scale reading: table position, m.
    angle_rad, velocity_rad_s : float
        True motor angle (rad) and velocity (rad/s).
    position_m, velocity_m_s : float
        True table position (m) and velocity (m/s): ``R`` times the motor's
        on a rigid screw, a state of its own on an elastic one.
    motor_torque_Nm : float
        Motor torque applied over the last period (``K_T`` times the current
        after the dead time and saturation), N m.
    friction_force_N : float
        Friction at the table, N (a motor-side friction torque divided by
        the lead ``R``).
    """

    step: int
    encoder_rad: float
    scale_m: float
    angle_rad: float
    velocity_rad_s: float
    position_m: float
    velocity_m_s: float
    motor_torque_Nm: float
    friction_force_N: float


def plant_output(
    step: int,
    encoder_rad: float,
    scale_m: float,
    angle_rad: float,
    velocity_rad_s: float,
    position_m: float,
    velocity_m_s: float,
    motor_torque_Nm: float,
    friction_force_N: float,
) -> PlantOutput:
    """``PlantOutput(...)`` of these values, made without its generated ``__init__``.

    :class:`PlantOutput` is frozen, so its ``__init__`` sets each of its nine
    fields through ``object.__setattr__``: about 0.9 us per sample, a tenth
    of the plain-call loop of the contact scenarios. The instance's
    ``__dict__`` is filled here directly (0.3 us): an equal object, the same
    fields in the same order (``test_elastic_ball_screw`` and
    ``test_tilting_table`` compare it with the constructor's). Used by the
    plants on their per-sample path.
    """
    out: PlantOutput = object.__new__(PlantOutput)
    out.__dict__.update(
        step=step,
        encoder_rad=encoder_rad,
        scale_m=scale_m,
        angle_rad=angle_rad,
        velocity_rad_s=velocity_rad_s,
        position_m=position_m,
        velocity_m_s=velocity_m_s,
        motor_torque_Nm=motor_torque_Nm,
        friction_force_N=friction_force_N,
    )
    return out


class Plant(Protocol):
    """A plant model advanced one control period per call."""

    @property
    def step_index(self) -> int:
        """Index of the current control sample."""
        ...

    def reset(self) -> None:
        """Return to the initial state at step 0."""
        ...

    def output(self) -> PlantOutput:
        """Readings and true state at the current control sample."""
        ...

    def step(self, current_A: float) -> PlantOutput:
        """Hold ``current_A`` (A) over one control period; the output at the next sample."""
        ...


@dataclass(frozen=True, kw_only=True)
class NominalModel:
    """The nominal rigid-body model of paper 000 eq. (1): ``P_n = K_T / (J s^2 + D s)``.

    Parameters
    ----------
    inertia_kgm2 : float
        ``J_n``, kg m^2, > 0.
    damping_Nms_per_rad : float
        ``D_n``, N m s/rad, >= 0.
    torque_constant_Nm_per_A : float
        ``K_T``, N m/A, > 0.
    """

    inertia_kgm2: float
    damping_Nms_per_rad: float
    torque_constant_Nm_per_A: float

    def __post_init__(self) -> None:
        require_positive("inertia_kgm2", self.inertia_kgm2)
        require_nonnegative("damping_Nms_per_rad", self.damping_Nms_per_rad)
        require_positive("torque_constant_Nm_per_A", self.torque_constant_Nm_per_A)

    def as_kwargs(self) -> dict[str, float]:
        """``inertia_kgm2``, ``damping_Nms_per_rad``, ``torque_constant_Nm_per_A``."""
        return {
            "inertia_kgm2": self.inertia_kgm2,
            "damping_Nms_per_rad": self.damping_Nms_per_rad,
            "torque_constant_Nm_per_A": self.torque_constant_Nm_per_A,
        }

    def response(self, freq_hz: ArrayLike) -> NDArray[np.complex128]:
        """``P_n(j 2 pi f)``, rad/A."""
        s = 2j * np.pi * np.asarray(freq_hz, dtype=float)
        result: NDArray[np.complex128] = self.torque_constant_Nm_per_A / (
            self.inertia_kgm2 * s**2 + self.damping_Nms_per_rad * s
        )
        return result


def clipped_current(current_A: float, limit_A: float) -> float:
    """``current_A`` saturated at ``+-limit_A`` (the amplifier), or SignalError if not finite."""
    if not math.isfinite(current_A):
        raise SignalError(f"current_A: expected a finite current, got {current_A!r}")
    return min(max(float(current_A), -limit_A), limit_A)


def whole_ratio(name: str, value: float, unit: float, unit_name: str) -> int:
    """``value / unit`` as an int, or :class:`ConfigError` naming ``name`` if not whole."""
    ratio = value / unit
    n = round(ratio)
    if abs(ratio - n) > 1e-6 * max(1.0, abs(ratio)):
        raise ConfigError(
            f"{name}: expected a whole multiple of {unit_name} = {unit!r} s, got {value!r} s"
        )
    return int(n)


def sim_steps(control_period_s: float, sim_step_s: float) -> int:
    """Integration sub-steps per control period; ConfigError naming the argument at fault.

    Both periods > 0, ``sim_step_s <= control_period_s`` and a whole divisor of it.
    """
    require_positive("control_period_s", control_period_s)
    require_positive("sim_step_s", sim_step_s)
    if sim_step_s > control_period_s:
        raise ConfigError(
            f"sim_step_s: expected <= control_period_s = {control_period_s!r}, got {sim_step_s!r}"
        )
    return whole_ratio("control_period_s", control_period_s, sim_step_s, "sim_step_s")


def zoh(a: np.ndarray, b: np.ndarray, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation ``(e^{A h}, int_0^h e^{A t} dt B)``."""
    n = a.shape[0]
    m = np.zeros((n + 1, n + 1))
    m[:n, :n] = a * step_s
    m[:n, n] = b * step_s
    import scipy.linalg  # here: it costs every node that imports this ~0.3 s at start-up

    e = scipy.linalg.expm(m)
    return e[:n, :n], e[:n, n].copy()
