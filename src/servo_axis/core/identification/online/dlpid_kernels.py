"""Compiled per-sample kernels of the DLPID identifier (numba).

The identifier of paper 003 (:mod:`servo_axis.core.identification.online.dlpid`)
filters every control sample through four second-order filters (Fig. 3:
``G_LPF`` on the angle and the torque, ``G_PD1``, ``G_PD2`` on the angle);
as four :class:`~servo_axis.core.feedback.discrete.DiscreteFilter` calls in
plain Python they cost more than the plant. Here the four updates are one
compiled call (``nopython``, ``cache=True``), written as the same arithmetic
as :meth:`DiscreteFilter.update <servo_axis.core.feedback.discrete.DiscreteFilter.update>`,
operation for operation and in the same order, with IEEE semantics (no
``fastmath``): the same numbers bit for bit, compiled by
:func:`servo_axis.core.kernels.compiled` as the plants' kernels are.
``test/unit/core/test_identification_kernels.py`` checks the kernel compiled
against the same code interpreted (``NUMBA_DISABLE_JIT=1``) and against the
filter objects it replaces.

The compiled code is cached on disk where :mod:`servo_axis.core.kernels`
says. This module is imported by the constructors of :class:`Dlpid`,
:class:`ConditionalRls` and :class:`PeIndex` only, so a process that
builds no identifier never imports numba.
"""

from __future__ import annotations

import numpy as np

from servo_axis.core.kernels import compiled


@compiled
def second_order_bank(
    coef: np.ndarray, z: np.ndarray, angle: float, torque: float
) -> tuple[float, float, float, float]:
    """One sample through the four 2nd-order filters of 003 Fig. 3 (transposed DF II).

    Filter ``i`` is ``(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)``
    with ``coef[i] = (b0, b1, b2, a1, a2)`` (normalised by ``a0``) and state
    ``z[i] = (z0, z1)``, updated in place; per filter, exactly the steps of
    ``DiscreteFilter.update`` for order 2::

        y  = b0 x + z0
        z0 = b1 x - a1 y + z1
        z1 = b2 x - a2 y + 0.0

    Parameters
    ----------
    coef : ndarray, shape (4, 5)
        Coefficients of ``G_LPF``, ``G_PD1``, ``G_PD2`` (all fed the angle)
        and ``G_LPF`` (fed the torque), in that order.
    z : ndarray, shape (4, 2)
        The filters' states, same order; updated in place.
    angle : float
        Measured angle ``y_m``, rad.
    torque : float
        Applied torque ``u``, N m.

    Returns
    -------
    y, yd, ydd, ubar : float
        The four outputs (rad, rad/s, rad/s^2, N m).
    """
    out0 = 0.0
    out1 = 0.0
    out2 = 0.0
    out3 = 0.0
    for i in range(4):
        x = torque if i == 3 else angle
        b0 = coef[i, 0]
        b1 = coef[i, 1]
        b2 = coef[i, 2]
        a1 = coef[i, 3]
        a2 = coef[i, 4]
        z0 = z[i, 0]
        z1 = z[i, 1]
        y = b0 * x + z0
        z[i, 0] = b1 * x - a1 * y + z1
        z[i, 1] = b2 * x - a2 * y + 0.0
        if i == 0:
            out0 = y
        elif i == 1:
            out1 = y
        elif i == 2:
            out2 = y
        else:
            out3 = y
    return out0, out1, out2, out3


@compiled
def conditional_rls_update(
    theta: np.ndarray,
    p: np.ndarray,
    inv_sqrt_lambda: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    updates: np.ndarray,
    phi: np.ndarray,
    u: float,
    enabled: np.ndarray,
) -> None:
    """One conditional RLS step of 003 eqs. (5), (6), (16), in place.

    The arithmetic of :meth:`ConditionalRls.update
    <servo_axis.core.identification.online.rls.ConditionalRls.update>` (see its
    module for the equations) step for step: the products of matrices and
    vectors are ``np.dot`` on contiguous copies of the same blocks (BLAS,
    as numpy's ``@``), the rest element by element in numpy's order.

    Parameters
    ----------
    theta : ndarray, shape (n,)
        ``theta[k-1]``, replaced by ``theta[k]``.
    p : ndarray, shape (n, n)
        ``P[k-1]``, replaced by ``P[k]``.
    inv_sqrt_lambda, lower, upper : ndarray, shape (n,)
        ``1 / sqrt(lambda_i)`` and the bounds of eq. (6).
    updates : ndarray of int64, shape (n,)
        Update counts, incremented for the enabled parameters.
    phi : ndarray, shape (n,)
        Regressor ``phi[k]`` (finite).
    u : float
        Left side ``u[k]`` (finite).
    enabled : ndarray of bool, shape (n,)
        The parameters to update (at least one).
    """
    n = theta.shape[0]
    ne = 0
    for i in range(n):
        if enabled[i]:
            ne += 1
    nd = n - ne
    e = np.empty(ne, dtype=np.int64)
    d = np.empty(nd, dtype=np.int64)
    ie = 0
    idd = 0
    for i in range(n):
        if enabled[i]:
            e[ie] = i
            ie += 1
        else:
            d[idd] = i
            idd += 1
    # y = u - phi_d^T theta_d
    phi_d = np.empty(nd)
    theta_d = np.empty(nd)
    for j in range(nd):
        phi_d[j] = phi[d[j]]
        theta_d[j] = theta[d[j]]
    y = u - np.dot(phi_d, theta_d)
    phi_e = np.empty(ne)
    theta_e = np.empty(ne)
    s = np.empty(ne)
    for j in range(ne):
        phi_e[j] = phi[e[j]]
        theta_e[j] = theta[e[j]]
        s[j] = inv_sqrt_lambda[e[j]]
    # Pbar = Lambda^-1/2 P Lambda^-1/2 on the enabled rows, then columns.
    p_bar = p.copy()
    for a in range(ne):
        for c in range(n):
            p_bar[e[a], c] *= s[a]
    for r in range(n):
        for b in range(ne):
            p_bar[r, e[b]] *= s[b]
    p_ee = np.empty((ne, ne))
    for a in range(ne):
        for b in range(ne):
            p_ee[a, b] = p_bar[e[a], e[b]]
    gain = np.dot(p_ee, phi_e) / (1.0 + np.dot(np.dot(phi_e, p_ee), phi_e))
    t = np.empty((ne, ne))
    for a in range(ne):
        for b in range(ne):
            t[a, b] = (1.0 if a == b else 0.0) - gain[a] * phi_e[b]
    p_new_ee = np.dot(t, p_ee)
    for a in range(ne):
        for b in range(ne):
            p_bar[e[a], e[b]] = p_new_ee[a, b]
    if nd:
        p_ed0 = np.empty((ne, nd))
        for a in range(ne):
            for b in range(nd):
                p_ed0[a, b] = p_bar[e[a], d[b]]
        p_ed = np.dot(t, p_ed0)
        for a in range(ne):
            for b in range(nd):
                p_bar[e[a], d[b]] = p_ed[a, b]
                p_bar[d[b], e[a]] = p_ed[a, b]
    for r in range(n):
        for c in range(n):
            p[r, c] = 0.5 * (p_bar[r, c] + p_bar[c, r])
    # Eq. (5) increment and eq. (6) projection, per component.
    err = y - np.dot(phi_e, theta_e)
    for a in range(ne):
        i = e[a]
        inc = gain[a] * err
        old = theta_e[a]
        trial = old + inc
        lo = lower[i]
        hi = upper[i]
        blocked = (trial >= hi and inc >= 0.0) or (trial <= lo and inc <= 0.0)
        v = old if blocked else trial
        if v < lo:
            v = lo
        if v > hi:
            v = hi
        theta[i] = v
        updates[i] += 1


@compiled
def outer_window_add(
    buffer: np.ndarray,
    total: np.ndarray,
    slot: int,
    v: np.ndarray,
    full: bool,
    window: int,
    kappa: bool,
) -> float:
    """One regressor into the PE window of 003 eq. (7), in place; ``kappa`` if asked.

    The arithmetic of :meth:`PeIndex.update_checked
    <servo_axis.core.identification.online.pe.PeIndex.update_checked>` between its
    recomputes, element by element as numpy does it::

        if full: total -= np.outer(buffer[slot], buffer[slot])
        buffer[slot] = v
        total += np.outer(v, v)
        kappa = np.linalg.eigvalsh(total / window)[0]

    (``np.outer(a, b)[i, j]`` is ``a[i] * b[j]``; ``-=``, ``+=`` and ``/``
    are elementwise; numba's ``eigvalsh`` calls LAPACK ``syevd`` on the lower
    triangle as numpy's does).

    Parameters
    ----------
    buffer : ndarray, shape (W, n)
        The ring buffer of regressors; row ``slot`` is replaced by ``v``.
    total : ndarray, shape (n, n)
        The running sum of their outer products, updated.
    slot : int
        The row the new regressor goes to (the oldest one's).
    v : ndarray, shape (n,)
        The regressor ``phi[k]``.
    full : bool
        Whether the window was full (the oldest is dropped from the sum).
    window : int
        ``W``.
    kappa : bool
        Return the smallest eigenvalue of ``total / W`` after the update
        (else 0.0).

    Returns
    -------
    float
        ``kappa[k]`` when asked, else 0.0.
    """
    n = v.shape[0]
    if full:
        for i in range(n):
            for j in range(n):
                total[i, j] = total[i, j] - buffer[slot, i] * buffer[slot, j]
    for i in range(n):
        buffer[slot, i] = v[i]
    for i in range(n):
        for j in range(n):
            total[i, j] = total[i, j] + v[i] * v[j]
    if not kappa:
        return 0.0
    mean = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            mean[i, j] = total[i, j] / window
    return float(np.linalg.eigvalsh(mean)[0])
