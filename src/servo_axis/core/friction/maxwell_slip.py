"""Maxwell-slip element set: rolling friction with pre-sliding hysteresis.

The model behind the "region A/B" characteristic of paper 000 Fig. 4 and
paper 001 Sect. II: rate independent, a function of the displacement from
the last reversal, with non-local memory. Written once: the update is the
compiled :func:`servo_axis.core.models.ball_screw_kernels.maxwell_slip_move`,
which the ball screws' compiled sub-step loops call on the element arrays
:meth:`MaxwellSlip.elements` hands out (the rigid screw inlines it in its
rigid-body loop). It is compiled beside those loops rather than here: numba
would not notice a change to it in a cached loop of another file.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.errors import ConfigError, require_nonnegative, require_positive


class MaxwellSlip:
    """Maxwell-slip element set: rolling friction with pre-sliding hysteresis.

    Element ``i`` (1..N) is a spring of deflection ``z_i`` that follows the
    displacement until ``|z_i|`` reaches its break-away deflection
    ``delta_i = (i / N) * width``, then slips. Each element carries
    ``T_c / N`` at break-away, so the virgin curve rises piecewise linearly
    from 0 to ``T_c`` over ``width`` and a reversal from full sliding swings
    from ``-T_c`` to ``+T_c`` over ``2 width`` (Masing's rule). The torque
    depends only on the displacement path, not on its rate, and keeps the
    memory of inner reversal loops (non-local memory).

    Parameters
    ----------
    coulomb_Nm : float
        Sliding level ``T_c`` at the motor, N m, >= 0.
    width_rad : float
        Pre-sliding width on the virgin curve at the motor, rad, > 0.
    elements : int
        Number of elements N, >= 1.
    storage : ndarray or None
        Where the set keeps its elements: a C-contiguous float64 array of
        shape (3, N) (a view into a plant's one work array, which its kernel
        takes whole), filled here. None (default): an array of its own.
    """

    def __init__(
        self,
        *,
        coulomb_Nm: float,
        width_rad: float,
        elements: int,
        storage: np.ndarray | None = None,
    ) -> None:
        require_nonnegative("coulomb_Nm", coulomb_Nm)
        require_positive("width_rad", width_rad)
        if elements < 1:
            raise ConfigError(f"elements: expected >= 1, got {elements!r}")
        delta = [width_rad * (i + 1) / elements for i in range(elements)]
        # One array, rows delta, stiffness, z: what the compiled loops take.
        if storage is None:
            storage = np.zeros((3, elements))
        elif not (
            storage.shape == (3, elements)
            and storage.dtype == np.float64
            and storage.flags.c_contiguous
        ):
            raise ConfigError(
                f"storage: expected a C-contiguous float64 array of shape (3, {elements}), "
                f"got {storage.dtype} {storage.shape}"
            )
        self._packed: NDArray[np.float64] = storage
        self._packed[2] = 0.0
        self._packed[0] = delta
        self._packed[1] = [coulomb_Nm / elements / d for d in delta]
        self._delta, self._stiffness, self._z = self._packed

    def reset(self) -> None:
        """Relax every element (virgin state)."""
        self._z[:] = 0.0

    def torque(self) -> float:
        """Friction torque the elements exert against the motion, N m."""
        return math.fsum((self._stiffness * self._z).tolist())

    def elements(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Break-away deflections (rad), stiffnesses (N m/rad) and the live deflections.

        Float64 arrays of one element each; the deflection array is the
        element state itself: a caller that steps the elements in a compiled
        loop updates it in place.
        """
        return self._delta, self._stiffness, self._z

    def packed(self) -> np.ndarray:
        """The elements as one float64 array, shape (3, N): rows ``delta``, ``k``, live ``z``.

        Rows as in :meth:`elements` (views of this array); the ``z`` row is
        the element state itself.
        """
        return self._packed

    def move(self, displacement_rad: float) -> float:
        """Advance by ``displacement_rad`` and return the new torque, N m."""
        from servo_axis.core.models.ball_screw_kernels import maxwell_slip_move

        return float(
            maxwell_slip_move(self._z, self._delta, self._stiffness, float(displacement_rad))
        )
