"""The controlled-output function (which sensor the loop closes on), without ROS."""

from __future__ import annotations

import numpy as np
import pytest

from servo_axis.core.errors import ConfigError
from servo_axis.core.feedback.output import controlled_output


def test_controlled_output_picks_the_sensor() -> None:
    kw = {"encoder_rad": 2.0, "scale_m": 0.00382, "lead_m_per_rad": 1.91e-3}
    assert controlled_output("encoder", **kw) == 2.0
    assert controlled_output("scale", **kw) == pytest.approx(2.0, rel=1e-15)
    arrays = controlled_output(
        "scale", encoder_rad=np.zeros(3), scale_m=np.array([0.0, 1.91e-3, -3.82e-3]),
        lead_m_per_rad=1.91e-3,
    )  # fmt: skip
    np.testing.assert_allclose(arrays, [0.0, 1.0, -2.0], rtol=1e-15)
    with pytest.raises(ConfigError, match="sensor"):
        controlled_output("laser", **kw)
