"""Compiled matrix work of the adaptive PTC (000 Fig. 5, 003 eq. (11)).

The adaptive feedforward of paper 003 builds a new model per online estimate
and a short feedforward block per estimate: :func:`ptc_model` discretises a
model, :func:`ptc_segment` computes one model's segment of a block, for
:class:`~servo_axis.core.feedforward.ptc.MultiratePtc` built with
``compiled=True``. The products of matrices are ``np.dot``, which numba
hands to BLAS ``gemm``/``gemv`` as numpy's ``@`` does, on the same operands
(``test/unit/core/test_kernels.py`` compares them with the numpy
formulation as well as interpreted). How they are compiled:
:mod:`servo_axis.core.kernels`.
"""

from __future__ import annotations

import numpy as np

from servo_axis.core.kernels import compiled


@compiled
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


@compiled
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
