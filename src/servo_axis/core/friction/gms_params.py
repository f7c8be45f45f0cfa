"""The parameters of the Generalized Maxwell-Slip friction model (GMS).

The conventional GMS model of Al-Bender, Lampaert and Swevers (IEEE TAC
50(11), 2005; "Al-Bender et al. 2005" below) is the friction model that
paper 004 (Sect. II-A, Fig. 4(b); dashed line) fits to a slow 50 um,
0.05 Hz reversal of the ball-screw X axis and compensates with (its
Fig. 6), the baseline of its sigmoid law. Its parts, one module each:

* :mod:`~servo_axis.core.friction.gms_params`: :class:`GmsParams` (here), the
  elements, the Stribeck curve and the quasi-static curves;
* :mod:`~servo_axis.core.friction.gms_model`: the model stepped per sample
  (:class:`~servo_axis.core.friction.gms_model.GmsModel`) and along a path
  (:func:`~servo_axis.core.friction.gms_model.simulate_gms`);
* :mod:`~servo_axis.core.friction.gms_text`: the parameter file's text;
* :mod:`~servo_axis.core.friction.gms_fitting`: the fit to a slow reversal;
* :mod:`~servo_axis.core.friction.gms_kernels`: the model's compiled block step.

Units: the displacement is the TABLE position (m) and the friction is the
motor torque (N m) that overcomes it, so ``k_i`` is in N m per m of table
travel. Sign: ``F`` has the sign of the motion in sliding (``+F_c`` at
``v > 0``): the torque the motor must supply, the convention of the
friction table (:mod:`servo_axis.core.feedforward.friction_table`), so that
a compensation adds it to the command as it is.

Nothing here reads a file, a clock or a logger.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import (
    ConfigError,
    require_finite,
    require_nonnegative,
    require_positive,
)

FloatArray = NDArray[np.float64]

#: Most elements a model may have (each costs a few floating-point operations per sample).
MAX_ELEMENTS = 20

#: Tolerance on ``sum(weights) == 1``.
WEIGHT_SUM_TOLERANCE = 1e-9

#: Default ``C`` (1/s): a slipping element's deficit decays as ``exp(-C t)``, i.e. over
#: ``v / C`` of travel; five of these (0.7 % left) are 0.1 um at 10 mm/s, 1/100 of the
#: ~10 um pre-sliding distance of the ball-screw axis (docs/design.md section 7; 15 um in paper 004
#: Fig. 4(b)). At the slow reversals of an identification run it is the rate-independent
#: limit ``C -> infinity`` to a few nm.
DEFAULT_ATTRACTION_PER_S = 5e5


def _float_tuple(name: str, value: object) -> tuple[float, ...]:
    if isinstance(value, str | bytes) or not isinstance(value, Sequence | np.ndarray):
        raise ConfigError(f"{name}: expected a sequence of numbers, got {value!r}")
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name}: expected a sequence of numbers, got {value!r}") from None
    return out


@dataclass(frozen=True, kw_only=True)
class GmsParams:
    """Parameters of the GMS model (Al-Bender et al. 2005), at the motor per m of table.

    Parameters
    ----------
    stiffness_Nm_per_m : tuple of float
        ``k_i``: the stiffness of each element while it sticks, N m of motor
        torque per m of table displacement, each > 0; 1..20 elements.
    weights : tuple of float
        ``alpha_i``: the share of the sliding level each element carries,
        each > 0, one per element, summing to 1 (within 1e-9). Element ``i``
        breaks away after ``alpha_i F_c / k_i`` (m) on the virgin curve.
    coulomb_Nm : float
        ``F_c``, the sliding level, N m, > 0 (3.2 N m for the ball-screw X
        axis of paper 001).
    static_Nm : float or None
        ``F_s``, the level at rest (Stribeck), N m, >= ``coulomb_Nm``.
        None (default): ``coulomb_Nm``, no Stribeck effect; the attribute
        holds that float after construction.
    stribeck_velocity_m_s : float
        ``V_s``, table velocity, m/s, > 0 (1e-3).
    stribeck_exponent : float
        ``delta`` of the Stribeck curve, > 0 (2.0, Gaussian).
    attraction_per_s : float
        ``C`` of the slip rule, 1/s, > 0: a slipping element approaches its
        level as ``exp(-C t)`` (see :mod:`~servo_axis.core.friction.gms_model`
        for the relation to Al-Bender et al.'s ``C`` in N/s). Default
        :data:`DEFAULT_ATTRACTION_PER_S` (5e5: the level within 0.7 % after
        0.1 um at 10 mm/s).
    viscous_Nms_per_m : float
        ``sigma_2``, viscous friction, N m s per m of table, >= 0 (0).

    Raises
    ------
    ConfigError
        Naming the field at fault.
    """

    stiffness_Nm_per_m: tuple[float, ...]
    weights: tuple[float, ...]
    coulomb_Nm: float
    static_Nm: float | None = None
    stribeck_velocity_m_s: float = 1e-3
    stribeck_exponent: float = 2.0
    attraction_per_s: float = DEFAULT_ATTRACTION_PER_S
    viscous_Nms_per_m: float = 0.0

    def __post_init__(self) -> None:
        k = _float_tuple("stiffness_Nm_per_m", self.stiffness_Nm_per_m)
        if not 1 <= len(k) <= MAX_ELEMENTS:
            raise ConfigError(
                f"stiffness_Nm_per_m: expected 1..{MAX_ELEMENTS} elements, got {len(k)}"
            )
        for i, v in enumerate(k):
            require_positive(f"stiffness_Nm_per_m[{i}]", v)
        w = _float_tuple("weights", self.weights)
        if len(w) != len(k):
            raise ConfigError(
                f"weights: expected one per element ({len(k)}, as stiffness_Nm_per_m), got {len(w)}"
            )
        for i, v in enumerate(w):
            require_positive(f"weights[{i}]", v)
        total = math.fsum(w)
        if abs(total - 1.0) > WEIGHT_SUM_TOLERANCE:
            raise ConfigError(
                f"weights: expected a sum of 1 (within {WEIGHT_SUM_TOLERANCE:g}), got {total!r}"
            )
        fc = require_positive("coulomb_Nm", self.coulomb_Nm)
        fs = fc if self.static_Nm is None else require_finite("static_Nm", self.static_Nm)
        if fs < fc:
            raise ConfigError(
                f"static_Nm: expected a value >= coulomb_Nm ({fc!r}), got {self.static_Nm!r}"
            )
        vs = require_positive("stribeck_velocity_m_s", self.stribeck_velocity_m_s)
        delta = require_positive("stribeck_exponent", self.stribeck_exponent)
        c = require_positive("attraction_per_s", self.attraction_per_s)
        sigma2 = require_nonnegative("viscous_Nms_per_m", self.viscous_Nms_per_m)
        for name, value in (
            ("stiffness_Nm_per_m", k),
            ("weights", w),
            ("coulomb_Nm", fc),
            ("static_Nm", fs),
            ("stribeck_velocity_m_s", vs),
            ("stribeck_exponent", delta),
            ("attraction_per_s", c),
            ("viscous_Nms_per_m", sigma2),
        ):
            object.__setattr__(self, name, value)

    @property
    def elements(self) -> int:
        """Number of elements N."""
        return len(self.stiffness_Nm_per_m)

    @property
    def breakaway_m(self) -> tuple[float, ...]:
        """Virgin-curve break-away displacement ``alpha_i F_c / k_i`` of each element, m."""
        return tuple(
            a * self.coulomb_Nm / k
            for a, k in zip(self.weights, self.stiffness_Nm_per_m, strict=True)
        )

    def stribeck(self, velocity_m_s: ArrayLike) -> FloatArray:
        """``s(v) = F_c + (F_s - F_c) exp(-|v / V_s|^delta)``, N m, per table velocity (m/s)."""
        v = np.asarray(velocity_m_s, dtype=float)
        fs = self.coulomb_Nm if self.static_Nm is None else self.static_Nm
        return np.asarray(
            self.coulomb_Nm
            + (fs - self.coulomb_Nm)
            * np.exp(-(np.abs(v / self.stribeck_velocity_m_s) ** self.stribeck_exponent)),
            dtype=float,
        )

    def virgin_curve(self, displacement_m: ArrayLike) -> FloatArray:
        """Quasi-static torque from the virgin state, N m (``C -> infinity``, ``|v| << V_s``).

        ``F(d) = sum_i sgn(d) min(k_i |d|, alpha_i F_c)`` (odd in ``d``, m).
        """
        d = np.asarray(displacement_m, dtype=float)
        out = np.zeros_like(d)
        for k, a in zip(self.stiffness_Nm_per_m, self.weights, strict=True):
            out = out + np.minimum(k * np.abs(d), a * self.coulomb_Nm)
        return np.asarray(np.sign(d) * out, dtype=float)

    def reversal_curve(self, displacement_m: ArrayLike) -> FloatArray:
        """Quasi-static torque after a reversal from full sliding, N m (``C -> infinity``).

        For motion in the positive direction after sliding in the negative
        one, against the displacement ``d >= 0`` (m) from the reversal:
        ``F(d) = sum_i [-alpha_i F_c + k_i min(d, 2 alpha_i F_c / k_i)]``, from
        ``-F_c`` to ``+F_c``; Masing's rule makes it ``-F_c + 2 F_virgin(d / 2)``.
        """
        d = np.asarray(displacement_m, dtype=float)
        out = np.zeros_like(d)
        for k, a in zip(self.stiffness_Nm_per_m, self.weights, strict=True):
            level = a * self.coulomb_Nm
            out = out - level + k * np.minimum(d, 2.0 * level / k)
        return out
