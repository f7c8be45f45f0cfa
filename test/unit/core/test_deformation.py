"""The deformation ratio of paper 004 eqs. (5)-(7) against exact cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.core.deformation import (
    DeformationRatio,
    DeformationTrace,
    deformation_ratio,
)
from servo_axis.core.errors import ConfigError, SignalError

R = 1.910e-3  # m/rad, 004 Table I
Q_ENC = 2.0 * math.pi / 2**20  # rad, 004 Sect. II-A
Q_SCALE = 100e-9  # m
TU = 0.5e-3  # s


def quantise(values: np.ndarray, step: float) -> np.ndarray:
    return np.round(values / step) * step


def motor_motion(n: int = 4000) -> np.ndarray:
    """A reversing motion: 5 rad amplitude, stops at t = 0.5 s and 1.5 s."""
    t = np.arange(n) * TU
    return 5.0 * np.sin(math.pi * t)


def streamed(theta: np.ndarray, x: np.ndarray, **settings: float) -> DeformationTrace:
    ratio = DeformationRatio(**settings)  # type: ignore[arg-type]
    samples = [ratio.update(float(a), float(b)) for a, b in zip(theta, x, strict=True)]
    return DeformationTrace(
        d_r_m_per_rad=np.array([s.d_r_m_per_rad for s in samples]),
        scale_increment_m=np.array([s.scale_increment_m for s in samples]),
        encoder_increment_rad=np.array([s.encoder_increment_rad for s in samples]),
        valid=np.array([s.valid for s in samples]),
    )


def assert_bitwise_equal(a: DeformationTrace, b: DeformationTrace) -> None:
    for name in ("d_r_m_per_rad", "scale_increment_m", "encoder_increment_rad"):
        assert_array_equal(
            getattr(a, name).view(np.int64), getattr(b, name).view(np.int64), err_msg=name
        )
    assert_array_equal(a.valid, b.valid)


def test_rigid_motion_is_zero_to_quantisation() -> None:
    theta_true = motor_motion()
    theta = quantise(theta_true, Q_ENC)
    x = quantise(R * theta_true, Q_SCALE)
    p, min_rot = 10, 100 * Q_ENC
    trace = deformation_ratio(
        theta, x, window_samples=p, lead_m_per_rad=R, min_rotation_rad=min_rot
    )
    v = trace.valid
    dtheta = trace.encoder_increment_rad
    assert not v[:p].any()
    assert_array_equal(v[p:], np.abs(dtheta[p:]) >= min_rot)
    # Near the two stops the rotation in p samples is below min_rot: flagged, d_r 0.
    assert (~v[p:]).sum() > 0 and v.sum() > 0.9 * v.size
    assert np.all(trace.d_r_m_per_rad[~v] == 0.0)
    # dx - R dtheta = e_x - R e_theta with |e_x| <= q_scale, |e_theta| <= q_enc
    # (two roundings of half a step each), so |d_r| <= (q_scale + R q_enc) / |dtheta|.
    bound = (Q_SCALE + R * Q_ENC) / np.abs(dtheta[v])
    d_r = np.abs(trace.d_r_m_per_rad[v])
    assert np.all(d_r <= bound * (1.0 + 1e-9))
    # The bound is not vacuous: quantisation really shows in d_r.
    assert np.max(d_r / bound) > 0.3
    print(f"rigid: max |d_r| = {d_r.max():.3e} m/rad, max |d_r|/bound = {np.max(d_r / bound):.3f}")


def test_known_deformation_gives_minus_its_slope() -> None:
    # x = R theta - delta(theta), delta = c theta^2: the secant of eq. (6) is
    # exactly -(delta[k] - delta[k-p]) / (theta[k] - theta[k-p]) = -c (theta[k] + theta[k-p]),
    # the slope -d delta / d theta at the midpoint angle (exact for a quadratic).
    c = 2e-6  # m/rad^2
    theta = motor_motion()
    x = R * theta - c * theta**2
    p = 4
    trace = deformation_ratio(theta, x, window_samples=p, lead_m_per_rad=R, min_rotation_rad=1e-6)
    v = trace.valid
    expected = -c * (theta[p:] + theta[:-p])
    assert_allclose(trace.d_r_m_per_rad[p:][v[p:]], expected[v[p:]], rtol=1e-8, atol=1e-15)
    # A constant compliance delta = kappa theta gives d_r = -kappa wherever the
    # rotation is not tiny (the rounding of x, ~eps |x|, is divided by dtheta).
    kappa = 3e-5
    trace = deformation_ratio(
        theta, R * theta - kappa * theta, window_samples=1, lead_m_per_rad=R, min_rotation_rad=1e-4
    )
    assert trace.valid.sum() > 0.95 * theta.size
    assert_allclose(trace.d_r_m_per_rad[trace.valid], -kappa, rtol=1e-8, atol=0.0)


@pytest.mark.parametrize("quantised", [False, True])
@pytest.mark.parametrize("p", [1, 7])
def test_streaming_equals_vectorised_bit_for_bit(quantised: bool, p: int) -> None:
    rng = np.random.default_rng(4)
    theta = np.cumsum(rng.normal(0.0, 3e-4, 3000)) + motor_motion(3000)
    x = R * theta + rng.normal(0.0, 2e-7, 3000)
    if quantised:
        theta, x = quantise(theta, Q_ENC), quantise(x, Q_SCALE)
    settings = {"window_samples": p, "lead_m_per_rad": R, "min_rotation_rad": 20 * Q_ENC}
    vec = deformation_ratio(theta, x, **settings)  # type: ignore[arg-type]
    stream = streamed(theta, x, **settings)
    assert_bitwise_equal(vec, stream)
    assert vec.valid.any() and not vec.valid.all()
    # reset() starts over: the same floats again.
    ratio = DeformationRatio(**settings)  # type: ignore[arg-type]
    for a, b in zip(theta[:50], x[:50], strict=True):
        ratio.update(float(a), float(b))
    ratio.reset()
    again = [ratio.update(float(a), float(b)).d_r_m_per_rad for a, b in zip(theta, x, strict=True)]
    assert_array_equal(np.array(again).view(np.int64), vec.d_r_m_per_rad.view(np.int64))


def test_short_records_and_stops_are_never_nan() -> None:
    trace = deformation_ratio(
        [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], window_samples=5, lead_m_per_rad=R, min_rotation_rad=0.0
    )
    assert_array_equal(trace.d_r_m_per_rad, 0.0)
    assert not trace.valid.any()
    # A standstill with min_rotation_rad = 0: dtheta = 0 is still refused, not divided by.
    theta = np.array([0.0, 1.0, 1.0, 1.0, 2.0])
    trace = deformation_ratio(
        theta, R * theta + 1e-6, window_samples=1, lead_m_per_rad=R, min_rotation_rad=0.0
    )
    assert_array_equal(trace.valid, [False, True, False, False, True])
    assert np.all(np.isfinite(trace.d_r_m_per_rad))
    empty = deformation_ratio([], [], window_samples=1, lead_m_per_rad=R, min_rotation_rad=0.0)
    assert empty.d_r_m_per_rad.size == 0


@pytest.mark.parametrize(
    ("settings", "name"),
    [
        ({"window_samples": 0}, "window_samples"),
        ({"window_samples": -3}, "window_samples"),
        ({"window_samples": 2.0}, "window_samples"),
        ({"window_samples": True}, "window_samples"),
        ({"lead_m_per_rad": 0.0}, "lead_m_per_rad"),
        ({"lead_m_per_rad": -R}, "lead_m_per_rad"),
        ({"lead_m_per_rad": math.nan}, "lead_m_per_rad"),
        ({"min_rotation_rad": -1e-3}, "min_rotation_rad"),
    ],
)
def test_bad_settings_are_refused_by_name(settings: dict[str, object], name: str) -> None:
    kwargs: dict[str, object] = {"window_samples": 2, "lead_m_per_rad": R, "min_rotation_rad": 0.0}
    kwargs.update(settings)
    with pytest.raises(ConfigError, match=name):
        deformation_ratio([0.0, 1.0, 2.0], [0.0, R, 2 * R], **kwargs)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=name):
        DeformationRatio(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_readings_are_refused_by_name(bad: float) -> None:
    settings = {"window_samples": 1, "lead_m_per_rad": R, "min_rotation_rad": 0.0}
    with pytest.raises(SignalError, match="encoder_rad"):
        deformation_ratio([0.0, bad], [0.0, 1.0], **settings)  # type: ignore[arg-type]
    with pytest.raises(SignalError, match="scale_m"):
        deformation_ratio([0.0, 1.0], [bad, 1.0], **settings)  # type: ignore[arg-type]
    with pytest.raises(SignalError, match="encoder_rad, scale_m"):
        deformation_ratio([0.0, 1.0], [0.0], **settings)  # type: ignore[arg-type]
    ratio = DeformationRatio(**settings)  # type: ignore[arg-type]
    ratio.update(0.0, 0.0)
    with pytest.raises(SignalError, match="encoder_rad"):
        ratio.update(bad, 1.0)
    with pytest.raises(SignalError, match="scale_m"):
        ratio.update(1.0, bad)
    # A refused reading is not taken: the window still holds (0, 0).
    sample = ratio.update(1.0, R + 1e-6)
    assert sample.valid
    assert_allclose(sample.d_r_m_per_rad, 1e-6, rtol=1e-9)
