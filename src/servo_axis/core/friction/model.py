"""Friction inside the plant integration.

Three parts, summed into one torque at the motor shaft (N m), all of which
oppose the motion:

* rolling friction with pre-sliding hysteresis, as a Maxwell-slip element
  set (rate-independent, a function of the displacement from the last
  reversal, with non-local memory); the model behind the "region A/B"
  characteristic of paper 000 Fig. 4 and paper 001 Sect. II;
* Coulomb friction ``T_c sgn(w)``, regularised as ``T_c tanh(w / w_s)`` so
  that an explicit integration step does not chatter at zero velocity;
* viscous friction ``b w`` in addition to the plant's own damping ``D``.

The displacement argument is the motor angle (rad); the pre-sliding width is
given at the table (m) and converted with the lead ``R`` (m/rad).
"""

from __future__ import annotations

from dataclasses import dataclass

from servo_axis.core.errors import ConfigError, require_nonnegative, require_positive
from servo_axis.core.friction.maxwell_slip import MaxwellSlip


@dataclass(frozen=True, kw_only=True)
class FrictionParams:
    """Parameters of the friction model.

    Parameters
    ----------
    rolling_coulomb_Nm : float
        Level that the rolling (Maxwell-slip) friction reaches once the balls
        roll fully (region B), at the motor, N m, >= 0. 0 switches it off.
        Paper 001 gives 3.2 N m for the ball-screw X axis.
    presliding_width_m : float
        Displacement from a reversal, at the table, after which the rolling
        friction reaches its Coulomb level on the virgin curve (region A), m,
        > 0. About 10 um for the ball-screw X axis (docs/design.md section 7).
    elements : int
        Number of Maxwell-slip elements, 1..200. The virgin curve is
        piecewise linear with this many knots.
    coulomb_Nm : float
        Plain Coulomb friction level at the motor, N m, >= 0.
    coulomb_smoothing_rad_s : float
        Velocity ``w_s`` of the ``tanh`` regularisation of the Coulomb term,
        rad/s, > 0.
    viscous_Nms_per_rad : float
        Extra viscous friction at the motor, N m s/rad, >= 0.
    """

    rolling_coulomb_Nm: float = 0.0
    presliding_width_m: float = 10e-6
    elements: int = 8
    coulomb_Nm: float = 0.0
    coulomb_smoothing_rad_s: float = 1e-3
    viscous_Nms_per_rad: float = 0.0

    def __post_init__(self) -> None:
        require_nonnegative("rolling_coulomb_Nm", self.rolling_coulomb_Nm)
        require_positive("presliding_width_m", self.presliding_width_m)
        if not isinstance(self.elements, int) or not 1 <= self.elements <= 200:
            raise ConfigError(f"elements: expected an integer in 1..200, got {self.elements!r}")
        require_nonnegative("coulomb_Nm", self.coulomb_Nm)
        require_positive("coulomb_smoothing_rad_s", self.coulomb_smoothing_rad_s)
        require_nonnegative("viscous_Nms_per_rad", self.viscous_Nms_per_rad)

    @property
    def enabled(self) -> bool:
        """True when any friction term is non-zero."""
        return (
            self.rolling_coulomb_Nm > 0.0 or self.coulomb_Nm > 0.0 or self.viscous_Nms_per_rad > 0
        )


class FrictionModel:
    """Sum of rolling (Maxwell-slip), Coulomb and viscous friction.

    Parameters
    ----------
    params : FrictionParams
        The friction parameters.
    lead_m_per_rad : float
        Ball-screw lead ``R``, m/rad, > 0, to convert the pre-sliding width.
    """

    def __init__(self, params: FrictionParams, *, lead_m_per_rad: float) -> None:
        require_positive("lead_m_per_rad", lead_m_per_rad)
        self.params = params
        self._rolling = (
            MaxwellSlip(
                coulomb_Nm=params.rolling_coulomb_Nm,
                width_rad=params.presliding_width_m / lead_m_per_rad,
                elements=params.elements,
            )
            if params.rolling_coulomb_Nm > 0.0
            else None
        )

    @property
    def rolling(self) -> MaxwellSlip | None:
        """The Maxwell-slip element set, or None when rolling friction is off."""
        return self._rolling

    def reset(self) -> None:
        """Return to the virgin state."""
        if self._rolling is not None:
            self._rolling.reset()
