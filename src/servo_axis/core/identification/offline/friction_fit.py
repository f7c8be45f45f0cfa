"""The friction of a slow reversal fitted by the plants' own laws, each value with a standard error.

Rigid screw (:func:`fit_maxwell_slip`): the slow-reversal torque of
:mod:`servo_axis.identify.friction` against the motor angle, fitted by the
plant's own law (:class:`servo_axis.core.friction.maxwell_slip.MaxwellSlip`
plus a Coulomb step at the velocity's reversal) run along the measured
angle: the level, the pre-sliding width and the plain Coulomb level.
Elastic screw (:func:`fit_nut_and_guide`, paper 004): the nut's set on the
motor angle and the guide's on the table position. The fits and their
standard errors are those of :mod:`servo_axis.core.identification.offline.fit`
(:class:`~servo_axis.core.identification.offline.fit.Fit`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from servo_axis.core.friction.maxwell_slip import MaxwellSlip
from servo_axis.core.identification.offline.fit import Fit, FloatArray, IdentificationError

FRICTION_KEYS = ("rolling_coulomb_Nm", "presliding_width_m", "coulomb_Nm")


def maxwell_slip_torque(
    angle_rad: FloatArray,
    direction: FloatArray,
    *,
    rolling_coulomb_Nm: float,
    presliding_width_m: float,
    coulomb_Nm: float,
    lead_m_per_rad: float,
    elements: int,
) -> FloatArray:
    """The friction of the ball-screw plant's law along a measured angle, N m.

    Maxwell-slip rolling friction on the angle's increments plus ``coulomb_Nm``
    times the motion's direction (the sign of the reference velocity).
    """
    out = np.empty(angle_rad.size)
    if rolling_coulomb_Nm > 0.0:
        ms = MaxwellSlip(
            coulomb_Nm=rolling_coulomb_Nm,
            width_rad=presliding_width_m / lead_m_per_rad,
            elements=elements,
        )
        move = ms.move
        prev = float(angle_rad[0])
        for i, x in enumerate(angle_rad.tolist()):
            out[i] = move(x - prev)
            prev = x
    else:
        out[:] = 0.0
    return out + coulomb_Nm * direction


def fit_maxwell_slip(
    *,
    angle_rad: Sequence[ArrayLike],
    direction: Sequence[ArrayLike],
    torque_Nm: Sequence[ArrayLike],
    lead_m_per_rad: float,
    elements: int = 8,
) -> Fit:
    """Fit rolling level, pre-sliding width and Coulomb level to slow-reversal torques.

    Each run is a segment of its own, the law starting from its virgin
    state in each (a run starts at rest).

    Parameters
    ----------
    angle_rad : sequence of array_like
        The measured motor angle per sample of each run, rad.
    direction : sequence of array_like
        The motion's direction per sample (+1, -1; 0 at rest).
    torque_Nm : sequence of array_like
        The friction torque estimate (:func:`servo_axis.identify.friction.estimate_friction_torque`), N m.
    lead_m_per_rad : float
        ``R``, m/rad (the width is at the table).
    elements : int
        Maxwell-slip elements of the model.
    """
    # The law is rate independent: a monotone stretch ends where it ends whatever the
    # samples on the way, so every ``stride``-th sample (about 2000 a run) is enough.
    th, sgn, taus = [], [], []
    for a, d, t in zip(angle_rad, direction, torque_Nm, strict=True):
        a, d, t = (np.asarray(v, dtype=float) for v in (a, d, t))
        stride = max(1, a.size // 2000)
        th.append(a[::stride])
        sgn.append(d[::stride])
        taus.append(t[::stride])
    tau = np.concatenate(taus)
    level = float(np.percentile(np.abs(tau), 90))
    travel = max(float(np.ptp(a)) for a in th) * lead_m_per_rad
    if level <= 0.0 or travel <= 0.0:
        raise IdentificationError(
            "friction: expected a slow-reversal run with motion and friction torque, got none"
        )
    scale = np.array([level, travel, level])

    def model(z: FloatArray) -> FloatArray:
        x = z * scale
        return np.concatenate(
            [
                maxwell_slip_torque(
                    a,
                    s,
                    rolling_coulomb_Nm=x[0],
                    presliding_width_m=x[1],
                    coulomb_Nm=x[2],
                    lead_m_per_rad=lead_m_per_rad,
                    elements=elements,
                )
                for a, s in zip(th, sgn, strict=True)
            ]
        )

    best = None
    for frac in (0.1, 0.3):
        sol = least_squares(
            lambda z: model(z) - tau,
            np.array([0.8, frac, 0.1]),
            bounds=([0.0, 1e-3, 0.0], [5.0, 1.0, 5.0]),
            diff_step=1e-4,
        )
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    dof = max(tau.size - 3, 1)
    s2 = 2.0 * best.cost / dof
    # A key on its bound (a Coulomb level of 0) is held there: the errors of the others.
    free = best.active_mask == 0
    std = np.zeros(3)
    jac = best.jac[:, free]
    try:
        std[free] = np.sqrt(np.clip(np.diag(np.linalg.inv(jac.T @ jac) * s2), 0.0, None))
    except np.linalg.LinAlgError:
        std[free] = np.inf
    std = std * scale
    return Fit(
        names=FRICTION_KEYS,
        values=np.asarray(best.x * scale, dtype=float),
        std=np.asarray(std, dtype=float),
        rms_residual=math.sqrt(s2),
        points=int(tau.size),
    )


def fit_nut_and_guide(
    *,
    angle_rad: Sequence[ArrayLike],
    table_m: Sequence[ArrayLike],
    torque_Nm: Sequence[ArrayLike],
    guide_friction_N: float,
    lead_m_per_rad: float,
    elements: int = 8,
) -> Fit:
    """Nut level and the pre-sliding width of the elastic screw's two friction sets (004).

    The motor torque of a slow reversal is the nut's set on the motor angle
    plus ``R`` times the guide's on the table position (the table lags the
    motor by the screw's deformation, which stretches the guide's curve
    against the angle); the guide's level is given (from the deformation),
    the nut's level and one width for both are fitted.

    Parameters
    ----------
    angle_rad, table_m, torque_Nm : sequence of array_like
        Per run: motor angle (rad), table position (m), friction torque (N m).
    guide_friction_N : float
        The guide's level, N.
    lead_m_per_rad : float
        ``R``, m/rad.
    elements : int
        Maxwell-slip elements of each set.
    """
    r = lead_m_per_rad
    runs = []
    for a, x, t in zip(angle_rad, table_m, torque_Nm, strict=True):
        a, x, t = (np.asarray(v, dtype=float) for v in (a, x, t))
        stride = max(1, a.size // 2000)
        runs.append((a[::stride], x[::stride], t[::stride]))
    tau = np.concatenate([t for _, _, t in runs])
    level = float(np.percentile(np.abs(tau), 90))
    travel = max(float(np.ptp(a)) for a, _, _ in runs) * r
    if level <= 0.0 or travel <= 0.0:
        raise IdentificationError(
            "friction: expected a slow-reversal run with motion and friction torque, got none"
        )
    scale = np.array([level, travel])

    def model(z: FloatArray) -> FloatArray:
        nut, width = z * scale
        out = []
        for a, x, _ in runs:
            still = np.zeros(a.size)
            t_nut = maxwell_slip_torque(
                a,
                still,
                rolling_coulomb_Nm=nut,
                presliding_width_m=width,
                coulomb_Nm=0.0,
                lead_m_per_rad=r,
                elements=elements,
            )
            t_guide = maxwell_slip_torque(
                x / r,
                still,
                rolling_coulomb_Nm=r * guide_friction_N,
                presliding_width_m=width,
                coulomb_Nm=0.0,
                lead_m_per_rad=r,
                elements=elements,
            )
            out.append(t_nut + t_guide)
        return np.concatenate(out)

    best = None
    for frac in (0.1, 0.3):
        sol = least_squares(
            lambda z: model(z) - tau,
            np.array([0.5, frac]),
            bounds=([0.0, 1e-3], [5.0, 1.0]),
            diff_step=1e-4,
        )
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    s2 = 2.0 * best.cost / max(tau.size - 2, 1)
    try:
        std = np.sqrt(np.clip(np.diag(np.linalg.inv(best.jac.T @ best.jac) * s2), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(2, np.inf)
    return Fit(
        names=("nut_friction_Nm", "presliding_width_m"),
        values=np.asarray(best.x * scale, dtype=float),
        std=np.asarray(std * scale, dtype=float),
        rms_residual=math.sqrt(s2),
        points=int(tau.size),
    )
