"""Position sensors: rotary encoder on the motor, linear scale on the table.

A sensor adds optional seeded Gaussian noise and quantises to its resolution
(nearest count, i.e. ideal interpolation of the count edges). Resolution 0
means an ideal sensor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import require_nonnegative


@dataclass(frozen=True, kw_only=True)
class SensorParams:
    """Resolution and noise of one position sensor.

    Parameters
    ----------
    resolution : float
        Size of one count in the sensor's unit (rad for the encoder, m for the
        scale), >= 0; 0 is an ideal sensor. 2^20 pulses/rev is
        5.99e-6 rad; the scale of the ball-screw X axis is 100e-9 m.
    noise_std : float
        Standard deviation of additive Gaussian noise before quantisation,
        same unit, >= 0.
    """

    resolution: float = 0.0
    noise_std: float = 0.0

    def __post_init__(self) -> None:
        require_nonnegative("resolution", self.resolution)
        require_nonnegative("noise_std", self.noise_std)


class PositionSensor:
    """Quantising, optionally noisy position sensor.

    Parameters
    ----------
    params : SensorParams
        Resolution and noise.
    rng : numpy.random.Generator or None
        Source of the noise; required when ``params.noise_std > 0``.
    """

    def __init__(self, params: SensorParams, *, rng: np.random.Generator | None = None) -> None:
        if params.noise_std > 0.0 and rng is None:
            raise ValueError("rng: a numpy.random.Generator is needed when noise_std > 0")
        self.params = params
        self._rng = rng
        # Read at every sample: the (frozen) parameters' two values as plain attributes.
        self._noise_std = params.noise_std
        self._resolution = params.resolution

    def measure(self, true_value: float) -> float:
        """Return the reading for ``true_value`` (same unit as the resolution)."""
        value = true_value
        if self._noise_std > 0.0 and self._rng is not None:
            value += self._noise_std * float(self._rng.standard_normal())
        res = self._resolution
        if res > 0.0:
            value = math.floor(value / res + 0.5) * res
        return value
