"""Maxwell-slip element set: rolling friction with pre-sliding hysteresis.

The model behind the "region A/B" characteristic of paper 000 Fig. 4 and
paper 001 Sect. II: rate independent, a function of the displacement from
the last reversal, with non-local memory. Written once; the plants use it
(the ball screw inlines its update in the integration loop for speed, with
the element lists :meth:`MaxwellSlip.elements` hands out).
"""

from __future__ import annotations

import math

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
    """

    def __init__(self, *, coulomb_Nm: float, width_rad: float, elements: int) -> None:
        require_nonnegative("coulomb_Nm", coulomb_Nm)
        require_positive("width_rad", width_rad)
        if elements < 1:
            raise ConfigError(f"elements: expected >= 1, got {elements!r}")
        self._delta = [width_rad * (i + 1) / elements for i in range(elements)]
        self._stiffness = [coulomb_Nm / elements / d for d in self._delta]
        self._z = [0.0] * elements

    def reset(self) -> None:
        """Relax every element (virgin state)."""
        self._z[:] = [0.0] * len(self._z)

    def torque(self) -> float:
        """Friction torque the elements exert against the motion, N m."""
        return math.fsum(k * z for k, z in zip(self._stiffness, self._z, strict=True))

    def elements(self) -> tuple[list[float], list[float], list[float]]:
        """Break-away deflections (rad), stiffnesses (N m/rad) and the live deflection list.

        The deflection list is the element state itself: a caller that steps
        the elements inline (the plant's inner loop) updates it in place.
        """
        return self._delta, self._stiffness, self._z

    def move(self, displacement_rad: float) -> float:
        """Advance by ``displacement_rad`` and return the new torque, N m."""
        z = self._z
        total = 0.0
        for i, (d, k) in enumerate(zip(self._delta, self._stiffness, strict=True)):
            zi = z[i] + displacement_rad
            if zi > d:
                zi = d
            elif zi < -d:
                zi = -d
            z[i] = zi
            total += k * zi
        return total
