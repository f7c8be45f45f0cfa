"""The encoder and the linear scale of a ball-screw axis: keys and parameters.

Shared by the plant models whose motor angle is read by a rotary encoder
and whose table position by a linear scale (``ball_screw``,
``elastic_ball_screw``); not an extension of its own.
"""

from __future__ import annotations

import math

from servo_axis.core.sensors import SensorParams
from servo_axis.params.param import Param, build
from servo_axis.plugins.values import EncoderKeys, ScaleKeys

#: The four keys: count and noise of the encoder (motor angle) and of the scale (table).
ENCODER_AND_SCALE: dict[str, Param] = {
    "encoder.resolution": Param(
        2.0 * math.pi / 2**20,
        unit="rad",
        minimum=0.0,
        meaning="rotary-encoder count on the motor angle (2 pi / 2^20 rad: 2^20 pulses per "
        "revolution, docs/design.md section 7 and 004); 0 = ideal",
    ),
    "encoder.noise_std": Param(
        0.0,
        unit="rad",
        minimum=0.0,
        meaning="standard deviation of Gaussian encoder noise before quantisation",
    ),
    "scale.resolution": Param(
        100e-9,
        unit="m",
        minimum=0.0,
        meaning="linear-scale count on the table position (100 nm, docs/design.md section 7 "
        "and 004); 0 = ideal",
    ),
    "scale.noise_std": Param(
        0.0,
        unit="m",
        minimum=0.0,
        meaning="standard deviation of Gaussian scale noise before quantisation",
    ),
}


def encoder_and_scale(encoder: EncoderKeys, scale: ScaleKeys) -> tuple[SensorParams, SensorParams]:
    """``(encoder, scale)`` from the checked ``encoder.*`` and ``scale.*`` keys."""
    return (
        build(
            "encoder.",
            SensorParams,
            resolution=encoder.resolution,
            noise_std=encoder.noise_std,
        ),
        build("scale.", SensorParams, resolution=scale.resolution, noise_std=scale.noise_std),
    )
