"""Compiled loops of the tilting table: RK4 sub-steps, the stops and sticking of Coulomb friction.

The stick/slip integration of :mod:`servo_axis.core.models.tilting_table`
(its docstring) over one control period: :func:`tilting_smooth_period`
without friction, :func:`tilting_friction_period` with it. How they are
compiled, and why the numbers are the interpreted Python's bit for bit:
:mod:`servo_axis.core.kernels`.
"""

from __future__ import annotations

import math

import numpy as np

from servo_axis.core.kernels import compiled


@compiled
def tilting_rk4(
    th: float, v: float, dt: float, b: float, d: float, u: float
) -> tuple[float, float]:
    """One RK4 step of ``th' = v, v' = b - d v - u sin th`` over ``dt`` (s)."""
    half = 0.5 * dt
    a1 = b - d * v - u * math.sin(th)
    v2 = v + half * a1
    a2 = b - d * v2 - u * math.sin(th + half * v)
    v3 = v + half * a2
    a3 = b - d * v3 - u * math.sin(th + half * v2)
    v4 = v + dt * a3
    a4 = b - d * v4 - u * math.sin(th + dt * v3)
    sixth = dt / 6.0
    return (
        th + sixth * (v + 2.0 * v2 + 2.0 * v3 + v4),
        v + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
    )


#: What ``config`` of the tilting table's kernels holds, by index.
TILTING_CONFIG = (
    "substeps",
    "h_s",
    "coulomb_Nm",
    "inverse_inertia_per_kgm2",
    "unbalance_Nm",
    "damping_per_s",
    "unbalance_per_s2",
    "event_tolerance_s",
    "event_iterations",
    "events_per_substep",
)


@compiled
def tilting_smooth_period(th: float, v: float, b: float, config: np.ndarray) -> tuple[float, float]:
    """The tilting table without friction over one control period (RK4 sub-steps).

    Parameters
    ----------
    th, v : float
        Angle (rad) and velocity (rad/s) at the period's start.
    b : float
        ``T_m / J``, rad/s^2, held over the period.
    config : ndarray
        The plant's constants, in the order of :data:`TILTING_CONFIG`.

    Returns
    -------
    th, v : float
        Angle and velocity at the period's end.
    """
    h, d, u = config[1], config[5], config[6]
    for _ in range(int(config[0])):
        th, v = tilting_rk4(th, v, h, b, d, u)
    return th, v


@compiled
def _tilting_locate_stop(
    th: float,
    v: float,
    s: float,
    tau: float,
    b: float,
    v_end: float,
    d: float,
    u: float,
    tol: float,
    iterations: int,
) -> tuple[float, float]:
    # Time dt in (0, tau] where the RK4 velocity from (th, v) is 0, and the angle there
    # (bracketed Newton on the step length; see models/tilting_table.py).
    if v_end == 0.0:
        return tau, tilting_rk4(th, v, tau, b, d, u)[0]
    lo, hi = 0.0, tau
    dt = tau * v / (v - v_end)
    for _ in range(iterations):
        th_x, v_x = tilting_rk4(th, v, dt, b, d, u)
        if v_x == 0.0:
            return dt, th_x
        if v_x * s > 0.0:
            lo = dt
        else:
            hi = dt
        acc = b - d * v_x - u * math.sin(th_x)
        new = dt - v_x / acc if acc != 0.0 else 0.5 * (lo + hi)
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        if abs(new - dt) <= tol:
            dt = new
            break
        dt = new
    return dt, tilting_rk4(th, v, dt, b, d, u)[0]


@compiled
def tilting_friction_period(
    th: float, v: float, torque: float, config: np.ndarray
) -> tuple[float, float]:
    """The tilting table with Coulomb friction over one control period.

    The stick/slip integration of :mod:`servo_axis.core.models.tilting_table`
    (its docstring): RK4 while sliding, the zero-velocity instant located by
    bracketed Newton, the stick test at rest.

    Parameters
    ----------
    th, v : float
        Angle (rad) and velocity (rad/s) at the period's start.
    torque : float
        Motor torque held over the period, N m.
    config : ndarray
        The plant's constants, in the order of :data:`TILTING_CONFIG`: the
        sub-steps per period, the sub-step (s), ``C`` (N m), ``1 / J``
        (1/(kg m^2)), ``U`` (N m), ``D / J`` (1/s), ``U / J`` (1/s^2),
        Newton's stopping step (s), at most this many Newton iterations per
        event and events per sub-step.

    Returns
    -------
    th, v : float
        Angle and velocity at the period's end.
    """
    substeps, h, coulomb, inv_j = int(config[0]), config[1], config[2], config[3]
    unbalance, d, u, tol = config[4], config[5], config[6], config[7]
    iterations, events = int(config[8]), int(config[9])
    for _ in range(substeps):
        tau = h
        for _ in range(events):
            starts_at_rest = v == 0.0
            if starts_at_rest:
                net = torque - unbalance * math.sin(th)
                if abs(net) <= coulomb:
                    # Sticks, and stays stuck to the end of the period.
                    return th, 0.0
                s = 1.0 if net > 0.0 else -1.0
            else:
                s = 1.0 if v > 0.0 else -1.0
            b = (torque - coulomb * s) * inv_j
            th1, v1 = tilting_rk4(th, v, tau, b, d, u)
            if v1 * s > 0.0:
                th, v = th1, v1
                break
            if starts_at_rest:
                # Breakaway below what RK4 resolves over tau: held.
                return th, 0.0
            dt, th = _tilting_locate_stop(th, v, s, tau, b, v1, d, u, tol, iterations)
            v = 0.0
            tau -= dt
            if tau <= 0.0:
                break
    return th, v
