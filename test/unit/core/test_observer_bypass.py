"""Compensation added outside the DOB (004 Fig. 5) equals the bypass-filtered one added inside."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError
from servo_axis.core.feedback.dob import DisturbanceObserver, ObserverBypass, OutsideObserver
from servo_axis.core.feedforward.terms import ReferenceBlock
from servo_axis.core.models.elastic_ball_screw import ElasticBallScrewParams, ElasticBallScrewPlant

NOMINAL = {"inertia_kgm2": 2.6e-3, "damping_Nms_per_rad": 0.070, "torque_constant_Nm_per_A": 0.715}
TU = 0.5e-3


def _run(outside: bool, compensation: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Current commands of a P loop + DOB on the elastic plant, the compensation outside the
    DOB (the DOB reads the current without it) or bypass-filtered inside (it reads all)."""
    plant = ElasticBallScrewPlant(ElasticBallScrewParams())
    dob = DisturbanceObserver(cutoff_hz=80.0, period_s=TU, **NOMINAL)
    bypass = ObserverBypass(cutoff_hz=80.0, period_s=TU)
    seen_previous = 0.0
    out = np.empty(len(reference))
    for k, (r, c) in enumerate(zip(reference, compensation, strict=True)):
        y = plant.output().encoder_rad
        u_ref = 40.0 * (r - y)
        d_hat = dob.update(y, seen_previous)
        if outside:
            u = u_ref - d_hat + c
            seen_previous = u - c
        else:
            u = u_ref - d_hat + bypass.update(float(c))
            seen_previous = u
        out[k] = u
        plant.step(u)
    return out


def test_bypass_inside_is_the_compensation_outside() -> None:
    rng = np.random.default_rng(3)
    n = 2000
    t = np.arange(n) * TU
    reference = 2.0 * np.sin(2 * np.pi * 2.0 * t)
    compensation = 0.6 * np.sign(np.cos(2 * np.pi * 2.0 * t)) + 0.05 * rng.standard_normal(n)
    outside = _run(True, compensation, reference)
    inside = _run(False, compensation, reference)
    assert np.ptp(outside) > 1.0
    assert_allclose(inside, outside, rtol=1e-9, atol=1e-9)


def test_a_constant_compensation_fades_to_nothing_below_the_cutoff() -> None:
    # A DOB nominalises the plant: a constant compensation outside it is
    # cancelled in steady state, so the bypassed current tends to 0, and its
    # integral is the one of c e^{-w_q t} (the first-order low-pass) plus
    # one sample (the DOB reads the current one sample late).
    bypass = ObserverBypass(cutoff_hz=80.0, period_s=TU)
    out = np.array([bypass.update(1.0) for _ in range(400)])
    assert out[0] == 1.0
    assert abs(out[-1]) < 1e-12
    assert_allclose(out.sum() * TU, 1.0 / (2 * np.pi * 80.0) + TU, rtol=0.01)


def test_outside_observer_sums_its_terms_then_bypasses() -> None:
    class Constant:
        def __init__(self, value: float) -> None:
            self.value = value

        def currents(self, block: ReferenceBlock) -> np.ndarray:
            return np.full(len(block.step), self.value)

    def block(k0: int, k1: int) -> ReferenceBlock:
        steps = np.arange(k0, k1)
        zero = np.zeros(len(steps))
        return ReferenceBlock(steps, zero, zero, zero)

    wrapped = OutsideObserver([Constant(0.25), Constant(0.5)], cutoff_hz=80.0, period_s=TU)
    reference = ObserverBypass(cutoff_hz=80.0, period_s=TU)
    got = np.concatenate([wrapped.currents(block(0, 7)), wrapped.currents(block(7, 30))])
    assert_allclose(got, [reference.update(0.75) for _ in range(30)], rtol=0, atol=0)


def test_bypass_refuses_a_cutoff_at_nyquist() -> None:
    with pytest.raises(ConfigError, match="cutoff_hz: expected below the Nyquist"):
        ObserverBypass(cutoff_hz=1000.0, period_s=TU)


def test_update_many_is_update_sample_by_sample() -> None:
    """The block form (its first-order low-pass written out) gives update's floats and state."""
    rng = np.random.default_rng(8)
    many = ObserverBypass(cutoff_hz=80.0, period_s=5e-4)
    one = ObserverBypass(cutoff_hz=80.0, period_s=5e-4)
    for n in (1, 7, 256, 0, 33):
        values = (rng.standard_normal(n) * 10.0 ** rng.integers(-6, 2)).tolist()
        got = many.update_many(values)
        expected = [one.update(c) for c in values]
        assert [v.hex() for v in got] == [v.hex() for v in expected]
        assert many._lpf.state == one._lpf.state
        assert many._filtered_previous == one._filtered_previous
