"""Compiled kernels of the plants' sub-step loops, the adaptive PTC and the GMS model (numba).

The plants advance one control period per call, and within it tens to a
hundred integration sub-steps with friction; in plain Python those loops
bound the whole core-only loop (7-15x real time). Here they are compiled
with numba (``nopython`` mode, ``cache=True``). They are the same arithmetic
as the Python they replaced, operation for operation and in the same order,
with IEEE semantics (no ``fastmath``, no reassociation, no fused
multiply-add), and ``math.sin``/``math.tanh`` go to the same C library as
Python's ``math``: so a plant gives the same numbers bit for bit as the
Python loops it replaced (every shipped scenario's plain-call loop was
compared), and ``test/unit/core/test_kernels.py`` checks each plant compiled
against the same code interpreted (``NUMBA_DISABLE_JIT=1``).

The adaptive PTC of paper 003 (eq. (11): a new model per online estimate, a
short feedforward block per estimate) has its small matrix work here too
(:func:`ptc_model`, :func:`ptc_segment`): there the products of matrices
are ``np.dot``, which numba hands to BLAS ``gemm``/``gemv`` as numpy's
``@`` does, on the same operands (the tests compare them with the numpy
formulation as well as interpreted). The GMS friction model of the
feedforward (004, :class:`~servo_axis.core.friction.gms.GmsModel`) steps a
block of samples in one call (:func:`gms_block`), its element sum by
:func:`exact_sum`, CPython's ``math.fsum`` ported step for step.

Compiled code is cached on disk: ``$NUMBA_CACHE_DIR`` if set, else
``__pycache__`` beside this file when that is writable (a source checkout),
else the user's cache directory (``~/.cache/numba``), so an installed
package compiles once per user. A process that finds the cache imports
numba and loads the kernels in about 0.2 s; compiling them takes about
0.5 s per plant model. This module is imported by the plants' constructors
(and ``MaxwellSlip.move``), by a compiled ``MultiratePtc``'s (the
feedforward generator builds one when it takes online estimates) and by a
compiled ``GmsModel``'s (the GMS feedforward term's) only, so a node that
builds no plant, no adaptive feedforward and no GMS term never imports numba.

Everything here works on float64 scalars and contiguous float64 arrays; the
callers own the arrays (element deflections are updated in place).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np

F = TypeVar("F", bound=Callable[..., Any])


def _compiled(fn: F) -> F:
    """``fn`` compiled by numba (nopython, cached on disk, IEEE arithmetic)."""
    return cast(F, numba.njit(cache=True, fastmath=False, nogil=True)(fn))


# --------------------------------------------------------------------- Maxwell slip


@_compiled
def maxwell_slip_move(
    z: np.ndarray, delta: np.ndarray, stiffness: np.ndarray, displacement: float
) -> float:
    """Advance a Maxwell-slip element set by ``displacement``; its torque (or force).

    Parameters
    ----------
    z : ndarray, shape (N,)
        Element deflections (the state), updated in place; unit of ``delta``.
    delta : ndarray, shape (N,)
        Break-away deflections, > 0 (rad at the motor, or m).
    stiffness : ndarray, shape (N,)
        Element stiffnesses (N m/rad, or N/m).
    displacement : float
        The displacement since the last call, unit of ``delta``.

    Returns
    -------
    float
        ``sum_i k_i z_i`` after the move (N m, or N), summed in element order.
    """
    total = 0.0
    for i in range(z.shape[0]):
        zi = z[i] + displacement
        di = delta[i]
        if zi > di:
            zi = di
        elif zi < -di:
            zi = -di
        z[i] = zi
        total += stiffness[i] * zi
    return total


# ------------------------------------------------------------------------- ball screw


@_compiled
def ball_screw_rigid_with_friction(
    inputs: np.ndarray,
    th: float,
    w: float,
    prev: float,
    delta: np.ndarray,
    stiffness: np.ndarray,
    z: np.ndarray,
    coulomb: float,
    smooth: float,
    viscous: float,
    kt: float,
    rigid: tuple[float, float, float, float, float],
) -> tuple[float, float, float, float]:
    """The ball screw's rigid body and friction over one control period.

    Per sub-step: the Maxwell-slip elements move by the rigid angle's change
    since the last sub-step, the friction (elements, ``T_c tanh(w / w_s)``,
    ``b w``) is taken off the input current (as ``T_f / K_T``) and the rigid
    states step by the exact ZOH matrices.

    Parameters
    ----------
    inputs : ndarray, shape (n,)
        Effective input current of each sub-step, A; overwritten with the
        input net of friction (what the modes are driven by).
    th, w : float
        Rigid angle (rad) and velocity (rad/s) at the period's start.
    prev : float
        Rigid angle at the previous sub-step, rad (the elements' reference).
    delta, stiffness, z : ndarray, shape (N,)
        The rolling elements (see :func:`maxwell_slip_move`), in the order of
        ``MaxwellSlip.elements``; ``z`` in place.
    coulomb, smooth, viscous : float
        ``T_c`` (N m), ``w_s`` (rad/s) and ``b`` (N m s/rad); 0 switches a term off.
    kt : float
        ``K_T``, N m/A.
    rigid : tuple of 5 floats
        ``(a00, a01, a11, b0, b1)``: the ZOH matrices of the rigid states.

    Returns
    -------
    th, w, prev, friction : float
        The rigid states at the period's end, the angle of the last
        sub-step and the friction torque of the last sub-step (N m).
    """
    a00, a01, a11, b0, b1 = rigid
    fr = 0.0
    for j in range(inputs.shape[0]):
        fr = maxwell_slip_move(z, delta, stiffness, th - prev)
        prev = th
        if coulomb > 0.0:
            fr += coulomb * math.tanh(w / smooth)
        if viscous > 0.0:
            fr += viscous * w
        u = inputs[j] - fr / kt
        inputs[j] = u
        th, w = a00 * th + a01 * w + b0 * u, a11 * w + b1 * u
    return th, w, prev, fr


# ----------------------------------------------------------------- elastic ball screw


@_compiled
def _elastic_accel(
    th: float,
    w: float,
    x: float,
    v: float,
    i: float,
    tf: float,
    fg: float,
    p: np.ndarray,
) -> tuple[float, float]:
    # p: r, k, cs, g, soft, kt, bm, jm, ct, m, ... (the config of elastic_ball_screw_period).
    r, k, cs, g, soft = p[0], p[1], p[2], p[3], p[4]
    d = r * th - x
    fs = k * d + cs * (r * w - v)
    if g > 0.0:
        fs -= soft * math.tanh(d / g)
    return (p[5] * i - p[6] * w - r * fs - tf) / p[7], (fs - p[8] * v - fg) / p[9]


@_compiled
def _substep_currents(
    i: float, cmd: float, decay1: float, decay2: float, ideal: bool
) -> tuple[float, float, float]:
    """The current at a sub-step's start, middle and end (first-order loop towards ``cmd``)."""
    if ideal:
        return i, i, i
    return i, cmd + (i - cmd) * decay1, cmd + (i - cmd) * decay2


@_compiled
def _rk4_step(
    h: float,
    th: float,
    w: float,
    x: float,
    v: float,
    ws: tuple[float, float, float],
    vs: tuple[float, float, float],
    accel_m: tuple[float, float, float, float],
    accel_t: tuple[float, float, float, float],
) -> tuple[float, float, float, float]:
    """The classic RK4 update of the two-mass screw from its stages' rates.

    ``ws``, ``vs``: the motor's and the table's velocities at stages 2-4;
    ``accel_m``, ``accel_t``: their accelerations at stages 1-4.
    """
    w2, w3, w4 = ws
    v2, v3, v4 = vs
    a1, a2, a3, a4 = accel_m
    b1, b2, b3, b4 = accel_t
    return (
        th + h / 6.0 * (w + 2.0 * w2 + 2.0 * w3 + w4),
        w + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
        x + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
        v + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4),
    )


#: The lengths of the state and the config in the elastic screws' work arrays:
#: ``(state, config)`` of :func:`elastic_ball_screw_period` and of
#: :func:`elastic_ball_screw_contact_period`.
ELASTIC_LAYOUT = (7, 15)
ELASTIC_CONTACT_LAYOUT = (10, 17)


@_compiled
def _element_rows(
    work: np.ndarray, start: int, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # The rows delta, k, z of a Maxwell-slip set of n elements at work[start:] (views).
    return (
        work[start : start + n],
        work[start + n : start + 2 * n],
        work[start + 2 * n : start + 3 * n],
    )


@_compiled
def elastic_ball_screw_period(work: np.ndarray, cmd: float) -> None:
    """The elastic ball screw over one control period: RK4 sub-steps and friction.

    One array holds all the kernel reads and writes: a compiled function's
    call costs about 80 ns per array argument (its type and buffer looked
    up), a sixth of a control period's Python around the kernel.

    Parameters
    ----------
    work : ndarray, shape (7 + 15 + 6 N,)
        In order (:data:`ELASTIC_LAYOUT`):

        * the state: ``th`` (rad), ``w`` (rad/s), ``x`` (m), ``v`` (m/s),
          ``i`` (A), the nut's friction torque ``T_f`` (N m) and the guide's
          force ``f_g`` (N); updated in place to the period's end;
        * the config: ``R`` (m/rad), ``k_h`` (N/m), ``c_s`` (N s/m), ``g``
          (m), ``(k_h - k_0) g`` (N), ``K_T`` (N m/A), ``B_m`` (N m s/rad),
          ``J_m`` (kg m^2), ``C_t`` (N s/m), ``M`` (kg); then the sub-steps
          per period, the sub-step ``h`` (s), ``e^{-w_c h/2}``,
          ``e^{-w_c h}`` and 1.0 for an ideal current loop (``i = cmd`` over
          the whole period), else 0.0;
        * the two Maxwell-slip sets of N elements, the nut's then the
          guide's, each as ``MaxwellSlip.packed`` holds it (rows ``delta``,
          ``k``, ``z``, flattened); ``z`` in place.
    cmd : float
        The commanded current held over the period, A (saturated).
    """
    state = work[:7]
    config = work[7:22]
    n = (work.shape[0] - 22) // 6
    nut_delta, nut_k, nut_z = _element_rows(work, 22, n)
    guide_delta, guide_k, guide_z = _element_rows(work, 22 + 3 * n, n)
    th, w, x, v, i, tf, fg = state[0], state[1], state[2], state[3], state[4], state[5], state[6]
    substeps = int(config[10])
    h = config[11]
    decay1 = config[12]
    decay2 = config[13]
    ideal_current = config[14] != 0.0
    half = h / 2.0
    if ideal_current:
        i = cmd
    for _ in range(substeps):
        th_start, x_start = th, x
        i0, i1, i2 = _substep_currents(i, cmd, decay1, decay2, ideal_current)
        a1, b1 = _elastic_accel(th, w, x, v, i0, tf, fg, config)
        a2, b2 = _elastic_accel(
            th + half * w, w + half * a1, x + half * v, v + half * b1, i1, tf, fg, config
        )
        w2, v2 = w + half * a1, v + half * b1
        a3, b3 = _elastic_accel(
            th + half * w2, w + half * a2, x + half * v2, v + half * b2, i1, tf, fg, config
        )
        w3, v3 = w + half * a2, v + half * b2
        a4, b4 = _elastic_accel(th + h * w3, w + h * a3, x + h * v3, v + h * b3, i2, tf, fg, config)
        th, w, x, v = _rk4_step(
            h,
            th,
            w,
            x,
            v,
            (w2, w3, w + h * a3),
            (v2, v3, v + h * b3),
            (a1, a2, a3, a4),
            (b1, b2, b3, b4),
        )
        i = i2
        tf = maxwell_slip_move(nut_z, nut_delta, nut_k, th - th_start)
        fg = maxwell_slip_move(guide_z, guide_delta, guide_k, x - x_start)
    state[0], state[1], state[2], state[3], state[4], state[5], state[6] = th, w, x, v, i, tf, fg


@_compiled
def contact_load(d: float, k: float, travel: float, preload: float, y: float) -> float:
    """``y = F / F_p`` of the spring with a ball contact: ``F / k + D tanh(F / F_p) = d``.

    Safeguarded Newton from ``y`` (the last solution) inside the bracket
    ``[(d - D) k / F_p, (d + D) k / F_p]``, where the left side's sign is
    known; a step that leaves the bracket is a bisection. At most 60
    iterations, to a step below ``1e-13 (1 + |y|)``: the same floats every
    time (deterministic, no tolerance on a residual of mixed scale).
    """
    return _contact_solve(d, preload / k, travel, y, 0.0, False)[0]


@_compiled
def _contact_solve(
    d: float, a: float, travel: float, y: float, t: float, known: bool
) -> tuple[float, float, bool]:
    # contact_load with a = F_p / k (the same quotient, computed once by the caller), from
    # a y whose tanh(y) is t when known. Returns the solution, its tanh and whether that
    # was computed: when the last iteration's residual is exactly 0 its tanh is the
    # solution's, which the next solve from there needs first (the same float, not
    # computed again); when the step was below the tolerance it is not known.
    lo = (d - travel) / a
    hi = (d + travel) / a
    if not lo <= y <= hi:
        y = 0.5 * (lo + hi)
        known = False
    if not known:
        t = math.tanh(y)
    for _ in range(60):
        f = a * y + travel * t - d
        if f > 0.0:
            hi = y
        elif f < 0.0:
            lo = y
        else:
            return y, t, True
        step = f / (a + travel * (1.0 - t * t))
        new = y - step
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        if abs(new - y) <= 1e-13 * (1.0 + abs(y)):
            return new, t, False
        y = new
        t = math.tanh(y)
    return y, t, True


@_compiled
def _contact_accel(
    th: float,
    w: float,
    x: float,
    v: float,
    i: float,
    tf: float,
    fg: float,
    y: float,
    p: np.ndarray,
) -> tuple[float, float]:
    # As _elastic_accel with the contact's spring at its solved y = F / F_p.
    r, cs = p[0], p[2]
    fs = p[16] * y + cs * (r * w - v)
    return (p[5] * i - p[6] * w - r * fs - tf) / p[7], (fs - p[8] * v - fg) / p[9]


@_compiled
def elastic_ball_screw_contact_period(work: np.ndarray, cmd: float) -> None:
    """The elastic ball screw with a ball contact and the nut's friction on it.

    The sub-steps of :func:`elastic_ball_screw_period` (the same RK4), with
    the spring ``F / k_h + D tanh(F / F_p) = delta`` (a linear part in series
    with the balls' contact deformation ``delta_c = D tanh(F / F_p)``,
    :func:`contact_load`) and three Maxwell-slip sets updated at the end of
    each sub-step: the ball nut's on the change of ``delta_c`` (m), the screw
    bearings' on the motor angle (rad), the guide's on the table position (m).

    The contact law is solved at each RK4 stage and at the end of each
    sub-step, each time from the last solution. The first stage of a
    sub-step solves at the deformation of the solve before it (the same
    ``th`` and ``x``), whose ``tanh`` gave ``delta_c``; any solve whose
    last iteration found a residual of exactly 0 has the ``tanh`` of its
    solution, the first one the next solve's Newton needs. Those are taken
    rather than computed again (the same floats: ``tanh`` is on the path
    from stage to stage, so each one saved is its latency).
    ``F_p / k_h`` is computed once per call.

    Parameters
    ----------
    work : ndarray, shape (10 + 17 + 9 N,)
        One array, as for :func:`elastic_ball_screw_period`
        (:data:`ELASTIC_CONTACT_LAYOUT`):

        * the state: ``th``, ``w``, ``x``, ``v``, ``i``, ``T_f`` (N m: nut +
          bearings, what the motor feels), ``f_g`` (N), the nut's and the
          bearings' shares of ``T_f`` (N m) and ``F / F_p`` of the last
          solution; updated in place to the period's end;
        * the config: as for :func:`elastic_ball_screw_period` (``g``
          unused), then the contact's travel ``D`` (m, >= 0) and the preload
          ``F_p`` (N, > 0);
        * the Maxwell-slip sets of N elements (rows ``delta``, ``k``, ``z``,
          flattened; ``z`` in place): the nut's in m of contact deformation
          and N m, the bearings' in rad and N m, the guide's in m and N.
    cmd : float
        The commanded current held over the period, A (saturated).
    """
    state = work[:10]
    config = work[10:27]
    n = (work.shape[0] - 27) // 9
    nut_delta, nut_k, nut_z = _element_rows(work, 27, n)
    bearing_delta, bearing_k, bearing_z = _element_rows(work, 27 + 3 * n, n)
    guide_delta, guide_k, guide_z = _element_rows(work, 27 + 6 * n, n)
    th, w, x, v, i, tf, fg = state[0], state[1], state[2], state[3], state[4], state[5], state[6]
    t_nut, t_bearing, y = state[7], state[8], state[9]
    r, k, travel, preload = config[0], config[1], config[15], config[16]
    substeps = int(config[10])
    h = config[11]
    decay1 = config[12]
    decay2 = config[13]
    ideal_current = config[14] != 0.0
    half = h / 2.0
    a = preload / k
    if ideal_current:
        i = cmd
    y, t, known = _contact_solve(r * th - x, a, travel, y, 0.0, False)
    if not known:
        t = math.tanh(y)
    contact = travel * t
    for _ in range(substeps):
        th_start, x_start = th, x
        i0, i1, i2 = _substep_currents(i, cmd, decay1, decay2, ideal_current)
        y, t, known = _contact_solve(r * th - x, a, travel, y, t, True)
        a1, b1 = _contact_accel(th, w, x, v, i0, tf, fg, y, config)
        th_s, w_s, x_s, v_s = th + half * w, w + half * a1, x + half * v, v + half * b1
        y, t, known = _contact_solve(r * th_s - x_s, a, travel, y, t, known)
        a2, b2 = _contact_accel(th_s, w_s, x_s, v_s, i1, tf, fg, y, config)
        w2, v2 = w + half * a1, v + half * b1
        th_s, w_s, x_s, v_s = th + half * w2, w + half * a2, x + half * v2, v + half * b2
        y, t, known = _contact_solve(r * th_s - x_s, a, travel, y, t, known)
        a3, b3 = _contact_accel(th_s, w_s, x_s, v_s, i1, tf, fg, y, config)
        w3, v3 = w + half * a2, v + half * b2
        th_s, w_s, x_s, v_s = th + h * w3, w + h * a3, x + h * v3, v + h * b3
        y, t, known = _contact_solve(r * th_s - x_s, a, travel, y, t, known)
        a4, b4 = _contact_accel(th_s, w_s, x_s, v_s, i2, tf, fg, y, config)
        th, w, x, v = _rk4_step(
            h,
            th,
            w,
            x,
            v,
            (w2, w3, w + h * a3),
            (v2, v3, v + h * b3),
            (a1, a2, a3, a4),
            (b1, b2, b3, b4),
        )
        i = i2
        y, t, known = _contact_solve(r * th - x, a, travel, y, t, known)
        if not known:
            t = math.tanh(y)
        contact_end = travel * t
        t_nut = maxwell_slip_move(nut_z, nut_delta, nut_k, contact_end - contact)
        contact = contact_end
        t_bearing = maxwell_slip_move(bearing_z, bearing_delta, bearing_k, th - th_start)
        tf = t_nut + t_bearing
        fg = maxwell_slip_move(guide_z, guide_delta, guide_k, x - x_start)
    state[0], state[1], state[2], state[3], state[4], state[5], state[6] = th, w, x, v, i, tf, fg
    state[7], state[8], state[9] = t_nut, t_bearing, y


# ----------------------------------------------------------------------- tilting table


@_compiled
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


@_compiled
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


@_compiled
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


@_compiled
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


# --------------------------------------------------------------------- adaptive PTC


@_compiled
def ptc_segment(
    x: np.ndarray,
    lo: int,
    hi: int,
    a_matrix: np.ndarray,
    b_inv: np.ndarray,
    ad: np.ndarray,
    bd: np.ndarray,
    current: np.ndarray,
    position: np.ndarray,
    velocity: np.ndarray,
) -> None:
    """The multirate PTC (000 Fig. 5, 003 eq. (11)) over rows ``lo .. hi - 1`` of one model.

    The arithmetic of :meth:`MultiratePtc.feedforward
    <servo_axis.core.feedforward.ptc.MultiratePtc.feedforward>` for one
    segment, step for step: with ``x0 = x[lo:hi]``, ``x1 = x[lo + 1:hi + 1]``

        u   = (x1 - x0 @ A^T) @ (B^-1)^T
        mid = x0 @ A_d^T + u[:, 0:1] * B_d

    where the three products are ``np.dot`` of contiguous copies of the
    same rows and the model's matrices transposed (BLAS ``gemm``, as numpy's
    ``@`` calls it: the same numbers, which
    ``test/unit/core/test_kernels.py`` checks against numpy and interpreted),
    and the rest element by element. The adaptive feedforward computes one
    short block per online estimate, often with two models; this is one call
    for what was a dozen numpy calls.

    Parameters
    ----------
    x : ndarray, shape (M+1, 2)
        The targets ``x_d`` of the block (rad, rad/s).
    lo, hi : int
        The rows (reference intervals) of this model, ``0 <= lo < hi <= M``.
    a_matrix, b_inv, ad : ndarray, shape (2, 2)
        ``A = A_d^2``, ``B^-1`` and ``A_d`` of the model (C order).
    bd : ndarray, shape (2,)
        ``B_d``.
    current, position, velocity : ndarray, shape (2M,)
        The block's feedforward (A) and nominal angle (rad) and velocity
        (rad/s) per control sample; samples ``2 lo .. 2 hi - 1`` are written.
    """
    n = hi - lo
    x0 = np.empty((n, 2))
    x1 = np.empty((n, 2))
    for i in range(n):
        for j in range(2):
            x0[i, j] = x[lo + i, j]
            x1[i, j] = x[lo + i + 1, j]
    p = np.dot(x0, a_matrix.T)
    for i in range(n):
        for j in range(2):
            x1[i, j] = x1[i, j] - p[i, j]
    u = np.dot(x1, b_inv.T)
    q = np.dot(x0, ad.T)
    for i in range(n):
        k = 2 * (lo + i)
        current[k] = u[i, 0]
        current[k + 1] = u[i, 1]
        position[k] = x[lo + i, 0]
        velocity[k] = x[lo + i, 1]
        position[k + 1] = q[i, 0] + u[i, 0] * bd[0]
        velocity[k + 1] = q[i, 1] + u[i, 0] * bd[1]


@_compiled
def ptc_model(e: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``A_d``, ``B_d``, ``A = A_d^2`` and ``B = [A_d B_d, B_d]`` from ``expm`` of the augmented matrix.

    What :func:`~servo_axis.core.feedforward.ptc._discretise` computes from
    ``e = expm([[A_c, B_c], [0, 0]] T_u)`` (3 x 3) before the inverse, step
    for step: ``A_d = e[:2, :2]``, ``B_d = e[:2, 2]`` (copied: contiguous),
    and the products ``A_d @ B_d`` and ``A_d @ A_d`` as ``np.dot`` (BLAS, as
    numpy's ``@``). One call per online estimate (003 eq. (11)).

    Parameters
    ----------
    e : ndarray, shape (3, 3)
        The matrix exponential.

    Returns
    -------
    ad, bd, a_matrix, b_matrix : ndarray
        Shapes (2, 2), (2,), (2, 2), (2, 2), C order.
    """
    ad = np.empty((2, 2))
    bd = np.empty(2)
    for i in range(2):
        for j in range(2):
            ad[i, j] = e[i, j]
        bd[i] = e[i, 2]
    adbd = np.dot(ad, bd)
    b_matrix = np.empty((2, 2))
    for i in range(2):
        b_matrix[i, 0] = adbd[i]
        b_matrix[i, 1] = bd[i]
    return ad, bd, np.dot(ad, ad), b_matrix


# --------------------------------------------------------------------- GMS model


@_compiled
def exact_sum(values: np.ndarray, partials: np.ndarray) -> float:
    """``math.fsum(values)`` of finite values: CPython's algorithm, step for step.

    Shewchuk's exact partials, then the correctly rounded sum of them with
    CPython's half-even correction (``Modules/mathmodule.c``, ``math_fsum``)
    for finite inputs whose partial sums do not overflow (the caller checks
    the result is finite, else takes ``math.fsum``). ``partials`` is work
    space of at least ``len(values)`` elements.
    """
    n = 0
    for idx in range(values.shape[0]):
        x = values[idx]
        i = 0
        for j in range(n):
            y = partials[j]
            if abs(x) < abs(y):
                t = x
                x = y
                y = t
            hi = x + y
            lo = y - (hi - x)
            if lo != 0.0:
                partials[i] = lo
                i += 1
            x = hi
        n = i
        if x != 0.0:
            partials[n] = x
            n += 1
    hi = 0.0
    if n > 0:
        n -= 1
        hi = partials[n]
        lo = 0.0
        while n > 0:
            x = hi
            n -= 1
            y = partials[n]
            hi = x + y
            yr = hi - x
            lo = y - yr
            if lo != 0.0:
                break
        if n > 0 and ((lo < 0.0 and partials[n - 1] < 0.0) or (lo > 0.0 and partials[n - 1] > 0.0)):
            y = lo * 2.0
            x = hi + y
            yr = x - hi
            if y == yr:
                hi = x
    return float(hi)


@_compiled
def gms_block(
    stiffness: np.ndarray,
    weights: np.ndarray,
    force: np.ndarray,
    slipping: np.ndarray,
    state: np.ndarray,
    positions: np.ndarray,
    velocities: np.ndarray,
    periods: np.ndarray,
    out: np.ndarray,
    partials: np.ndarray,
) -> None:
    """:meth:`GmsModel.update <servo_axis.core.friction.gms.GmsModel.update>` of each sample in turn.

    The same steps in the same order (see that method and its class), on
    finite arguments with ``periods > 0`` (the caller checks them), the
    element sum by :func:`exact_sum` (``math.fsum``); ``math.exp`` and
    ``**`` go to the C library's ``exp`` and ``pow`` as Python's do.

    Parameters
    ----------
    stiffness, weights : ndarray, shape (N,)
        ``k_i`` and ``alpha_i``.
    force : ndarray, shape (N,)
        The element forces ``F_i``, updated in place.
    slipping : ndarray of bool, shape (N,)
        Whether each element slips, updated in place.
    state : ndarray, shape (10,)
        ``[has a last position (0/1), last position, last sign, F_c, F_s,
        v_s, delta, C, sigma_2, Stribeck (0/1)]``; the first three updated.
    positions, velocities, periods : ndarray, shape (M,)
        The samples' arguments.
    out : ndarray, shape (M,)
        The torques, N m.
    partials : ndarray, shape (>= N,)
        Work space of :func:`exact_sum`.
    """
    has_last = state[0] != 0.0
    last = state[1]
    previous_sign = int(state[2])
    fc = state[3]
    fs = state[4]
    vs = state[5]
    delta = state[6]
    attraction = state[7]
    sigma2 = state[8]
    stribeck = state[9] != 0.0
    n = stiffness.shape[0]
    for j in range(positions.shape[0]):
        position = positions[j]
        v = velocities[j]
        sign = 1 if v > 0.0 else (-1 if v < 0.0 else 0)
        if sign != previous_sign or sign == 0:
            for i in range(n):
                slipping[i] = False
        previous_sign = sign
        if not has_last:
            has_last = True
            last = position
            out[j] = exact_sum(force, partials) + sigma2 * v
            continue
        dx = position - last
        last = position
        s = fc
        if stribeck:
            s += (fs - fc) * math.exp(-(abs(v / vs) ** delta))
        decay = math.exp(-attraction * periods[j])
        for i in range(n):
            level = weights[i] * s
            if slipping[i]:
                target = sign * level
                force[i] = target + (force[i] - target) * decay
            else:
                f = force[i] + stiffness[i] * dx
                if f >= level:
                    f = level
                    slipping[i] = sign > 0
                elif f <= -level:
                    f = -level
                    slipping[i] = sign < 0
                force[i] = f
        out[j] = exact_sum(force, partials) + sigma2 * v
    state[0] = 1.0 if has_last else 0.0
    state[1] = last
    state[2] = previous_sign
