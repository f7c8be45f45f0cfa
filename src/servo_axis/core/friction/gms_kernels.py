"""Compiled block step of the GMS friction model (004) and its exact element sum.

:func:`gms_block` steps a block of samples of
:class:`~servo_axis.core.friction.gms_model.GmsModel` (the GMS feedforward's
model) in one call, its element sum by :func:`exact_sum`, CPython's
``math.fsum`` ported step for step. How they are compiled, and why the
numbers are the interpreted Python's bit for bit: :mod:`servo_axis.core.kernels`.
"""

from __future__ import annotations

import math

import numpy as np

from servo_axis.core.kernels import compiled


@compiled
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


@compiled
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
    """:meth:`GmsModel.update <servo_axis.core.friction.gms_model.GmsModel.update>` of each sample in turn.

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
