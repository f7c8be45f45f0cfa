"""Compiled loops of the ball screws: the Maxwell-slip elements, the rigid and the elastic screw.

The two ball-screw models (:mod:`~servo_axis.core.models.ball_screw`, the
rigid body with its modes, and :mod:`~servo_axis.core.models.elastic_ball_screw`,
paper 004's two-inertia axis) advance one control period per call through
tens to a hundred integration sub-steps with Maxwell-slip friction
(:class:`~servo_axis.core.friction.maxwell_slip.MaxwellSlip`, paper 000
Fig. 4, 001 Sect. II). The element update :func:`maxwell_slip_move` is here,
beside the screws' loops that call it, rather than beside the element set:
numba caches a kernel per source file and does not notice a change to a
kernel of another file that it calls (it would serve the old code), so a
kernel calls only kernels of its own file (``test_import_rules`` checks it).

How they are compiled, and why the numbers are the interpreted Python's bit
for bit: :mod:`servo_axis.core.kernels`. ``test/unit/core/test_kernels.py``
runs each plant compiled and interpreted.
"""

from __future__ import annotations

import math

import numpy as np

from servo_axis.core.kernels import compiled

# --------------------------------------------------------------------- Maxwell slip


@compiled
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


@compiled
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


@compiled
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


@compiled
def _substep_currents(
    i: float, cmd: float, decay1: float, decay2: float, ideal: bool
) -> tuple[float, float, float]:
    """The current at a sub-step's start, middle and end (first-order loop towards ``cmd``)."""
    if ideal:
        return i, i, i
    return i, cmd + (i - cmd) * decay1, cmd + (i - cmd) * decay2


@compiled
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


@compiled
def _element_rows(
    work: np.ndarray, start: int, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # The rows delta, k, z of a Maxwell-slip set of n elements at work[start:] (views).
    return (
        work[start : start + n],
        work[start + n : start + 2 * n],
        work[start + 2 * n : start + 3 * n],
    )


@compiled
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


@compiled
def contact_load(d: float, k: float, travel: float, preload: float, y: float) -> float:
    """``y = F / F_p`` of the spring with a ball contact: ``F / k + D tanh(F / F_p) = d``.

    Safeguarded Newton from ``y`` (the last solution) inside the bracket
    ``[(d - D) k / F_p, (d + D) k / F_p]``, where the left side's sign is
    known; a step that leaves the bracket is a bisection. At most 60
    iterations, to a step below ``1e-13 (1 + |y|)``: the same floats every
    time (deterministic, no tolerance on a residual of mixed scale).
    """
    return _contact_solve(d, preload / k, travel, y, 0.0, False)[0]


@compiled
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


@compiled
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


@compiled
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
