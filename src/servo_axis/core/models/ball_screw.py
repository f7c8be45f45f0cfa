"""Ball-screw servo axis: rigid body, resonance modes, dead time, friction.

The plant from current reference ``i`` (A) to motor angle ``theta`` (rad) is
eq. (30) of paper 000::

    P(s) = [ K_T / (J s^2 + D s) + sum_i K_i / (s^2 + 2 zeta_i w_i s + w_i^2) ] e^{-T_d s}

with ``K_i = a_i K_T / J`` (docs/design.md section 7). The table position is ``x = R theta``
(rigid screw; the elastic two-inertia axis of paper 004 is a separate model).
Friction and an injectable disturbance act as input torques at the motor and
so pass through the whole of ``P(s)``, as the paper injects rolling friction
("nonlinear rolling friction is injected as the input disturbance").

Integration: the linear part is discretised exactly (zero-order hold, matrix
exponential) at the simulation step ``h`` (a divisor of the control period).
The dead time is a delay line of whole simulation steps, not a Pade
approximation. Friction and disturbance are evaluated at the start of each
simulation step and held over it. Friction depends on the rigid-body motion
``theta_r`` (the modes are structural vibration on top of it), so only the
two rigid-body states are stepped one simulation step at a time; the modes
and, without friction, the whole state are advanced per control period by
precomputed exact matrices (the same result as stepping, to rounding).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import (
    ConfigError,
    require_finite,
    require_nonnegative,
    require_positive,
)
from servo_axis.core.friction.model import FrictionModel, FrictionParams
from servo_axis.core.models.base import PlantOutput, clipped_current, sim_steps, whole_ratio, zoh
from servo_axis.core.sensors import PositionSensor, SensorParams

#: Resonance modes of docs/design.md section 7 (paper 000 Table I did not survive; our choice):
#: (frequency Hz, damping ratio, relative gain a_i).
BALL_SCREW_MODES: tuple[tuple[float, float, float], ...] = (
    (180.0, 0.05, 0.3),
    (520.0, 0.03, -0.2),
    (1100.0, 0.02, 0.1),
)


@dataclass(frozen=True, kw_only=True)
class DisturbanceParams:
    """Sinusoidal input disturbance torque ``A sin(2 pi f t + phi)`` at the motor.

    Parameters
    ----------
    amplitude_Nm : float
        Amplitude, N m, >= 0 (0: no disturbance).
    frequency_hz : float
        Frequency, Hz, > 0.
    phase_rad : float
        Phase at t = 0, rad.
    """

    amplitude_Nm: float = 0.0
    frequency_hz: float = 4.0
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        require_nonnegative("amplitude_Nm", self.amplitude_Nm)
        require_positive("frequency_hz", self.frequency_hz)
        require_finite("phase_rad", self.phase_rad)

    def torque_Nm(self, time_s: float) -> float:
        """Disturbance torque at ``time_s``, N m."""
        return self.amplitude_Nm * math.sin(
            2.0 * math.pi * self.frequency_hz * time_s + self.phase_rad
        )


@dataclass(frozen=True, kw_only=True)
class BallScrewParams:
    """Physical parameters of the ball-screw axis (defaults: docs/design.md section 7, X axis of paper 000).

    Parameters
    ----------
    torque_constant_Nm_per_A : float
        ``K_T``, N m/A, > 0 (0.715).
    inertia_kgm2 : float
        ``J``, kg m^2, > 0 (0.01).
    damping_Nms_per_rad : float
        ``D``, N m s/rad, >= 0 (0.1).
    lead_m_per_rad : float
        ``R``, m/rad, > 0 (1.91e-3).
    modes : tuple of (frequency_hz, zeta, a)
        Resonance modes of eq. (30); empty for the rigid body only.
    dead_time_s : float
        ``T_d`` of eq. (30), s, >= 0, a whole multiple of ``sim_step_s``.
    control_period_s : float
        ``T_u``, s, > 0: the command is held over it.
    sim_step_s : float
        Integration step ``h``, s, dividing ``control_period_s``.
    current_limit_A : float
        Amplifier saturation, A, > 0.
    initial_angle_rad, initial_velocity_rad_s : float
        Initial motor angle and velocity.
    friction : FrictionParams
        Friction inside the integration.
    disturbance : DisturbanceParams
        Injectable input disturbance.
    encoder, scale : SensorParams
        Rotary encoder (rad) and linear scale (m).
    """

    torque_constant_Nm_per_A: float = 0.715
    inertia_kgm2: float = 0.01
    damping_Nms_per_rad: float = 0.1
    lead_m_per_rad: float = 1.91e-3
    modes: tuple[tuple[float, float, float], ...] = ()
    dead_time_s: float = 0.0
    control_period_s: float = 1e-3
    sim_step_s: float = 50e-6
    current_limit_A: float = 30.0
    initial_angle_rad: float = 0.0
    initial_velocity_rad_s: float = 0.0
    friction: FrictionParams = field(default_factory=FrictionParams)
    disturbance: DisturbanceParams = field(default_factory=DisturbanceParams)
    encoder: SensorParams = field(default_factory=SensorParams)
    scale: SensorParams = field(default_factory=SensorParams)

    def __post_init__(self) -> None:
        require_positive("torque_constant_Nm_per_A", self.torque_constant_Nm_per_A)
        require_positive("inertia_kgm2", self.inertia_kgm2)
        require_nonnegative("damping_Nms_per_rad", self.damping_Nms_per_rad)
        require_positive("lead_m_per_rad", self.lead_m_per_rad)
        for i, mode in enumerate(self.modes):
            if len(mode) != 3:
                raise ConfigError(f"modes[{i}]: expected (frequency_hz, zeta, a), got {mode!r}")
            require_positive(f"modes[{i}].frequency_hz", mode[0])
            require_positive(f"modes[{i}].zeta", mode[1])
            require_finite(f"modes[{i}].a", mode[2])
        require_nonnegative("dead_time_s", self.dead_time_s)
        sim_steps(self.control_period_s, self.sim_step_s)
        whole_ratio("dead_time_s", self.dead_time_s, self.sim_step_s, "sim_step_s")
        require_positive("current_limit_A", self.current_limit_A)
        require_finite("initial_angle_rad", self.initial_angle_rad)
        require_finite("initial_velocity_rad_s", self.initial_velocity_rad_s)

    @property
    def substeps(self) -> int:
        """Simulation steps per control period."""
        return whole_ratio("control_period_s", self.control_period_s, self.sim_step_s, "sim_step_s")

    @property
    def dead_time_steps(self) -> int:
        """Dead time in simulation steps."""
        return whole_ratio("dead_time_s", self.dead_time_s, self.sim_step_s, "sim_step_s")


def continuous_model(params: BallScrewParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State-space form of eq. (30) without the dead time.

    State: ``[theta_r, omega_r, q_1, q_1', ..., q_m, q_m']``; the input is the
    effective current (A); the output rows are the motor angle
    ``theta_r + sum q_i`` (rad) and velocity ``omega_r + sum q_i'`` (rad/s).

    Returns
    -------
    a, b, c : numpy.ndarray
        Shapes (n, n), (n,), (2, n).
    """
    n = 2 + 2 * len(params.modes)
    a = np.zeros((n, n))
    b = np.zeros(n)
    c = np.zeros((2, n))
    kt, j, d = params.torque_constant_Nm_per_A, params.inertia_kgm2, params.damping_Nms_per_rad
    a[0, 1] = 1.0
    a[1, 1] = -d / j
    b[1] = kt / j
    c[0, 0] = 1.0
    c[1, 1] = 1.0
    for i, (f_hz, zeta, gain) in enumerate(params.modes):
        w = 2.0 * math.pi * f_hz
        p = 2 + 2 * i
        a[p, p + 1] = 1.0
        a[p + 1, p] = -(w**2)
        a[p + 1, p + 1] = -2.0 * zeta * w
        b[p + 1] = gain * kt / j
        c[0, p] = 1.0
        c[1, p + 1] = 1.0
    return a, b, c


class BallScrewPlant:
    """Simulator of the ball-screw axis, advanced one control period per call.

    Parameters
    ----------
    params : BallScrewParams
        Physical parameters.
    rng : numpy.random.Generator or None
        Noise source of the sensors (needed only with sensor noise).
    """

    def __init__(self, params: BallScrewParams, *, rng: np.random.Generator | None = None) -> None:
        self.params = params
        a, b, c = continuous_model(params)
        self._c = c
        self._ad, self._bd = zoh(a, b, params.sim_step_s)
        n = params.substeps
        self._n = n
        self._friction = FrictionModel(params.friction, lead_m_per_rad=params.lead_m_per_rad)
        self._encoder = PositionSensor(params.encoder, rng=rng)
        self._scale = PositionSensor(params.scale, rng=rng)
        q, r = divmod(params.dead_time_steps, n)
        self._delay_periods = q
        self._delay_rem = r
        # Whole-period matrices: r substeps with the older command, then n - r
        # with the newer one (linear fast path), and the response of the whole
        # state to a per-substep input sequence (paths with friction or a
        # disturbance): x_n = A^n x_0 + sum_j A^(n-1-j) B u_j.
        powers = [np.eye(a.shape[0])]
        for _ in range(n):
            powers.append(powers[-1] @ self._ad)
        self._phi = powers[n]
        self._gain_seq = np.column_stack([powers[n - 1 - j] @ self._bd for j in range(n)])
        self._gamma_old = self._gain_seq[:, :r].sum(axis=1)
        self._gamma_new = self._gain_seq[:, r:].sum(axis=1)
        self._mode_phi = self._phi[2:, 2:]
        self._mode_gain_seq = self._gain_seq[2:, :]
        ad, bd = self._ad, self._bd
        self._rigid = (
            float(ad[0, 0]),
            float(ad[0, 1]),
            float(ad[1, 1]),
            float(bd[0]),
            float(bd[1]),
        )
        self._has_friction = params.friction.enabled
        if self._has_friction:
            from servo_axis.core.models.ball_screw_kernels import ball_screw_rigid_with_friction

            self._kernel = ball_screw_rigid_with_friction
            rolling = self._friction.rolling
            empty = np.zeros(0)
            self._elements: tuple[np.ndarray, np.ndarray, np.ndarray] = (
                rolling.elements() if rolling is not None else (empty, empty, empty)
            )
        self._has_disturbance = params.disturbance.amplitude_Nm > 0.0
        self._substep_times = np.arange(n) * params.sim_step_s
        self.reset()

    def reset(self) -> None:
        """Return to the initial state at step 0."""
        p = self.params
        self._x = np.zeros(self._ad.shape[0])
        self._x[0] = p.initial_angle_rad
        self._x[1] = p.initial_velocity_rad_s
        self._friction.reset()  # in place: self._elements stays the live state
        self._step = 0
        # Commands still in the dead-time pipe, oldest first (zero before start).
        self._pipe: deque[float] = deque([0.0] * (self._delay_periods + 1))
        self._applied_A = 0.0
        self._friction_Nm = 0.0
        self._last_angle = float(self._x[0])

    @property
    def step_index(self) -> int:
        """Index of the current control sample."""
        return self._step

    def output(self) -> PlantOutput:
        """Readings and true state at the current control sample."""
        angle = float(self._c[0] @ self._x)
        vel = float(self._c[1] @ self._x)
        r = self.params.lead_m_per_rad
        return PlantOutput(
            step=self._step,
            encoder_rad=self._encoder.measure(angle),
            scale_m=self._scale.measure(angle * r),
            angle_rad=angle,
            velocity_rad_s=vel,
            position_m=angle * r,
            velocity_m_s=vel * r,
            motor_torque_Nm=self.params.torque_constant_Nm_per_A * self._applied_A,
            friction_force_N=self._friction_Nm / r,
        )

    def step(self, current_A: float) -> PlantOutput:
        """Hold ``current_A`` over one control period and advance to the next sample.

        Parameters
        ----------
        current_A : float
            Current reference for this period, A; saturated at
            ``+-current_limit_A`` before the dead time.

        Returns
        -------
        PlantOutput
            The state at the next control sample.
        """
        p = self.params
        cmd = clipped_current(current_A, p.current_limit_A)
        pipe = self._pipe
        pipe.append(cmd)
        older, newer = pipe[0], pipe[1]
        pipe.popleft()
        if self._has_friction:
            self._integrate_with_friction(older, newer)
        elif self._has_disturbance:
            self._x = self._phi @ self._x + self._gain_seq @ self._inputs(older, newer)
        else:
            self._x = self._phi @ self._x + self._gamma_old * older + self._gamma_new * newer
        self._applied_A = newer
        self._step += 1
        return self.output()

    def _inputs(self, older: float, newer: float) -> np.ndarray:
        """Effective input current (A) of every substep, friction aside."""
        u = np.full(self._n, newer)
        u[: self._delay_rem] = older
        if self._has_disturbance:
            p = self.params
            t = self._step * p.control_period_s + self._substep_times
            d = p.disturbance
            u += (
                d.amplitude_Nm
                * np.sin(2.0 * np.pi * d.frequency_hz * t + d.phase_rad)
                / p.torque_constant_Nm_per_A
            )
        return u

    def _integrate_with_friction(self, older: float, newer: float) -> None:
        # Friction acts on the rigid-body coordinates (theta_r, omega_r): the
        # rolling elements follow the screw's rigid motion, the modes are
        # structural vibration on top. So the rigid body and the friction are
        # stepped together, sub-step by sub-step, in a compiled loop (it
        # dominates the plant's cost), and the modes, which are linear, are
        # advanced once per period from the input sequence net of friction.
        fp = self.params.friction
        inputs = self._inputs(older, newer)
        x = self._x
        delta, stiffness, z = self._elements
        th, w, self._last_angle, self._friction_Nm = self._kernel(
            inputs,
            float(x[0]),
            float(x[1]),
            self._last_angle,
            delta,
            stiffness,
            z,
            fp.coulomb_Nm,
            fp.coulomb_smoothing_rad_s,
            fp.viscous_Nms_per_rad,
            self.params.torque_constant_Nm_per_A,
            self._rigid,
        )
        modes = self._mode_phi @ x[2:] + self._mode_gain_seq @ inputs
        self._x = np.concatenate(([th, w], modes))


def ball_screw_response(
    freq_hz: ArrayLike,
    *,
    torque_constant_Nm_per_A: float,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
    modes: tuple[tuple[float, float, float], ...] = (),
    dead_time_s: float = 0.0,
) -> NDArray[np.complex128]:
    """Frequency response of eq. (30) of 000, current (A) to motor angle (rad).

    ``P(jw) = [K_T/(J s^2 + D s) + sum_i K_i/(s^2 + 2 zeta_i w_i s + w_i^2)] e^{-T_d s}``
    with ``K_i = a_i K_T / J`` and ``modes`` as ``(f_i Hz, zeta_i, a_i)``;
    without modes and dead time it is the nominal ``P_n`` of eq. (1).
    """
    s = 2j * np.pi * np.asarray(freq_hz, dtype=float)
    kt, j, d = torque_constant_Nm_per_A, inertia_kgm2, damping_Nms_per_rad
    p = kt / (j * s**2 + d * s)
    for f_i, zeta, a in modes:
        w = 2 * np.pi * f_i
        p = p + (a * kt / j) / (s**2 + 2 * zeta * w * s + w**2)
    result: NDArray[np.complex128] = p * np.exp(-s * dead_time_s)
    return result
