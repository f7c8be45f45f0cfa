"""Multirate perfect tracking control (PTC) for the nominal ball-screw model.

Paper 000 Sect. III-A and Fig. 5, after Fujimoto's PTC [16]: the plant
``P_n = K_T / (J s^2 + D s)`` (eq. (1)) has state ``x = [theta, omega]``
(rad, rad/s). With ``(A_d, B_d)`` its zero-order-hold discretisation at the
control period ``T_u`` and the reference period ``T_r = 2 T_u`` (two inputs
per reference sample, as many as states), the state advances over ``T_r`` as
``x[i+1] = A x[i] + B [u[2i], u[2i+1]]^T`` with ``A = A_d^2`` and
``B = [A_d B_d, B_d]``. The feedforward

    ``[u[2i], u[2i+1]]^T = B^-1 (x_d[i+1] - A x_d[i])``

makes the nominal state equal the target ``x_d`` at every reference instant
(DESIGN 1). The nominal output between them is the feedback reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from .errors import ConfigError, SignalError, require_nonnegative, require_positive


@dataclass(frozen=True)
class PtcOutput:
    """Feedforward and nominal trajectory at the control samples ``0 .. 2M-1``.

    Attributes
    ----------
    current_A : ndarray, shape (2M,)
        Feedforward current ``u[k]``, A.
    position_rad, velocity_rad_s : ndarray, shape (2M,)
        Nominal motor angle (rad) and velocity (rad/s) at sample ``k``.
    """

    current_A: NDArray[np.float64]
    position_rad: NDArray[np.float64]
    velocity_rad_s: NDArray[np.float64]


class MultiratePtc:
    """Multirate PTC feedforward with ``T_r = 2 T_u``.

    Parameters
    ----------
    inertia_kgm2, damping_Nms_per_rad, torque_constant_Nm_per_A : float
        Nominal model of eq. (1).
    control_period_s : float
        ``T_u``, s, > 0.
    ratio : int
        ``T_r / T_u``; must be 2 (the plant order) for a square ``B``.
    """

    def __init__(
        self,
        *,
        inertia_kgm2: float,
        damping_Nms_per_rad: float,
        torque_constant_Nm_per_A: float,
        control_period_s: float,
        ratio: int = 2,
    ) -> None:
        j = require_positive("inertia_kgm2", inertia_kgm2)
        d = require_nonnegative("damping_Nms_per_rad", damping_Nms_per_rad)
        kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
        tu = require_positive("control_period_s", control_period_s)
        if ratio != 2:
            raise ConfigError(
                f"ratio: expected 2 (T_r = 2 T_u for the order-2 plant), got {ratio!r}"
            )
        m = np.zeros((3, 3))
        m[0, 1] = 1.0
        m[1, 1] = -d / j
        m[1, 2] = kt / j
        e = scipy.linalg.expm(m * tu)
        self.ad: NDArray[np.float64] = e[:2, :2]
        self.bd: NDArray[np.float64] = e[:2, 2]
        self.a_matrix: NDArray[np.float64] = self.ad @ self.ad
        self.b_matrix: NDArray[np.float64] = np.column_stack((self.ad @ self.bd, self.bd))
        self._b_inv = np.linalg.inv(self.b_matrix)

    def feedforward(self, x_d: NDArray[np.float64]) -> PtcOutput:
        """Feedforward for the target states ``x_d`` at reference instants ``0 .. M``.

        Parameters
        ----------
        x_d : ndarray, shape (M+1, 2)
            Target ``[theta (rad), omega (rad/s)]`` at ``i T_r``.

        Returns
        -------
        PtcOutput
            For control samples ``0 .. 2M-1``.
        """
        x = np.asarray(x_d, dtype=float)
        if x.ndim != 2 or x.shape[1] != 2 or x.shape[0] < 2:
            raise SignalError(f"x_d: expected shape (M+1, 2) with M >= 1, got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise SignalError("x_d: expected finite values")
        u = (x[1:] - x[:-1] @ self.a_matrix.T) @ self._b_inv.T  # rows [u[2i], u[2i+1]]
        mid = x[:-1] @ self.ad.T + np.outer(u[:, 0], self.bd)  # nominal state at 2i+1
        m = x.shape[0] - 1
        current = u.reshape(2 * m)
        pos = np.empty(2 * m)
        vel = np.empty(2 * m)
        pos[0::2], vel[0::2] = x[:-1, 0], x[:-1, 1]
        pos[1::2], vel[1::2] = mid[:, 0], mid[:, 1]
        return PtcOutput(current_A=current, position_rad=pos, velocity_rad_s=vel)
