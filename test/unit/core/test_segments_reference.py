"""Half-cosine segments (004 Fig. 11): rest to rest, continuous, analytic decelerations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError
from servo_axis.core.reference import OneMinusCosReference, SegmentsReference, make_reference


def test_stops_decelerations_and_continuity() -> None:
    ref = SegmentsReference(
        distances_m=(1e-3, -1e-3, 0.05), durations_s=(1.0, 1.0, 0.5), delay_s=0.2, offset_m=0.01
    )
    ends = np.array([0.2, 1.2, 2.2, 2.7])
    pos, vel, _ = ref.sample(ends)
    assert_allclose(pos, [0.01, 0.011, 0.01, 0.06], rtol=0, atol=1e-15)
    assert_allclose(vel, 0.0, atol=1e-15)
    # deceleration into each stop: |d| (pi / T)^2 / 2, just before it
    _, _, acc = ref.sample(ends[1:] - 1e-9)
    assert_allclose(
        np.abs(acc), [0.5e-3 * math.pi**2, 0.5e-3 * math.pi**2, 0.025 * 4 * math.pi**2], rtol=1e-6
    )
    # position and velocity continuous, velocity and acceleration the derivatives
    # (away from the joints, where the acceleration jumps)
    t = np.linspace(0.0, 3.0, 300001)
    p, v, a = ref.sample(t)
    assert np.max(np.abs(np.diff(p))) <= 0.16 * 1e-5  # v_max dt: no jump
    assert np.max(np.abs(np.diff(v))) <= 1.0 * 1e-5  # a_max dt
    away = np.min(np.abs(t[:, None] - ends[None, :]), axis=1) > 1e-3
    assert_allclose(np.gradient(p, t)[away], v[away], atol=1e-8)
    assert_allclose(np.gradient(v, t)[away], a[away], atol=1e-6)


def test_two_opposite_moves_are_the_one_minus_cos_reference_of_004() -> None:
    seg = make_reference("segments", distances_m=(0.05, -0.05), durations_s=(0.5, 0.5))
    cos = OneMinusCosReference(amplitude_m=0.025, frequency_hz=1.0)
    t = np.linspace(0.0, 0.999, 2000)
    for a, b in zip(seg.sample(t), cos.sample(t), strict=True):
        assert_allclose(a, b, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"distances_m": (), "durations_s": ()}, "durations_s: expected one duration per distance"),
        ({"distances_m": (1e-3,), "durations_s": (1.0, 2.0)}, "durations_s: expected one"),
        ({"distances_m": (0.0,), "durations_s": (1.0,)}, r"distances_m\[0\]: expected a non-zero"),
        (
            {"distances_m": (1e-3,), "durations_s": (0.0,)},
            r"durations_s\[0\]: expected a value > 0",
        ),
        ({"distances_m": (1e-3,), "durations_s": (1.0,), "delay_s": -1.0}, "delay_s"),
    ],
)
def test_bad_segments_are_refused_by_name(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        SegmentsReference(**kwargs)  # type: ignore[arg-type]
