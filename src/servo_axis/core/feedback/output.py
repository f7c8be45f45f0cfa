"""The one function that picks the controlled output from the measured signals.

Semi-closed loop (paper 000, 001): the rotary encoder on the motor, in rad.
Full-closed loop (paper 004's table position): the linear scale divided by
the lead ``R``, so that it is in rad of motor angle like the references.
The feedback loop, the learning unit, the headless simulation and the
reports all call this function, so they agree on what the error is.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from servo_axis.core.errors import ConfigError

#: The sensors that can close the loop.
SENSORS = ("encoder", "scale")

Value = TypeVar("Value", float, np.ndarray)


def controlled_output(
    sensor: str, *, encoder_rad: Value, scale_m: Value, lead_m_per_rad: float
) -> Value:
    """Controlled output ``y`` (rad of motor angle) from the readings.

    Parameters
    ----------
    sensor : str
        ``"encoder"`` (``y`` = encoder angle) or ``"scale"`` (``y`` = scale
        position / ``R``).
    encoder_rad : float or ndarray
        Encoder reading(s), rad.
    scale_m : float or ndarray
        Linear scale reading(s), m.
    lead_m_per_rad : float
        ``R``, m/rad, > 0.

    Raises
    ------
    ConfigError
        For an unknown ``sensor``.
    """
    if sensor == "encoder":
        return encoder_rad
    if sensor == "scale":
        result: Value = scale_m / lead_m_per_rad
        return result
    raise ConfigError(f"sensor: expected one of {SENSORS}, got {sensor!r}")
