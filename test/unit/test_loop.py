"""Feedback loop (trips) and feedforward generator (blocks, PTC, friction table)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from servo_axis.core.controllers import DiscretePid, design_pid_pole_placement
from servo_axis.core.friction_table import FrictionTable
from servo_axis.core.plant import BallScrewParams, BallScrewPlant
from servo_axis.core.ptc import MultiratePtc
from servo_axis.core.servo import Fault, FeedbackLoop, SafetyLimits

from servo_axis.core.errors import ConfigError
from servo_axis.core.feedforward import BLOCK_STEPS, FeedforwardGenerator
from servo_axis.core.reference import SineReference

NOMINAL = {"inertia_kgm2": 0.01, "damping_Nms_per_rad": 0.1, "torque_constant_Nm_per_A": 0.715}
R = 1.91e-3


def make_loop(**limits: float) -> FeedbackLoop:
    gains = design_pid_pole_placement(bandwidth_hz=40.0, **NOMINAL)
    return FeedbackLoop(
        pid=DiscretePid(gains=gains, period_s=1e-3),
        dob=None,
        lead_m_per_rad=R,
        limits=SafetyLimits(**limits),
    )


def test_ptc_and_pid_track_the_nominal_plant_to_rounding() -> None:
    """Core-only closed loop: with P = P_n the error at the T_r instants is rounding."""
    ref = SineReference(amplitude_m=0.01, frequency_hz=2.0, offset_m=0.01, phase_rad=-math.pi / 2)
    gen = FeedforwardGenerator(reference=ref, control_period_s=1e-3, lead_m_per_rad=R, **NOMINAL)
    loop = make_loop()
    plant = BallScrewPlant(BallScrewParams())
    errors = []
    y = plant.output()
    for r, _, u_ff in gen.samples(0, 1000):
        errors.append(r - y.angle_rad)
        u = loop.update(angle_rad=y.encoder_rad, reference_rad=r, feedforward_A=u_ff).current_A
        y = plant.step(u)
    stroke = 0.02 / R
    assert np.max(np.abs(errors)) < 1e-12 * stroke


def test_following_error_trip_zeroes_the_current_for_good() -> None:
    loop = make_loop(following_error_m=1e-6)
    ok = loop.update(angle_rad=0.0, reference_rad=1e-4, feedforward_A=0.5)  # 0.19 um
    assert ok.fault is None and ok.current_A != 0.0
    out = loop.update(angle_rad=0.0, reference_rad=1e-3, feedforward_A=0.5)  # 1.9 um
    assert out.fault is Fault.FOLLOWING_ERROR
    assert out.fault_value == pytest.approx(1e-3 * R, rel=1e-12)
    assert out.current_A == 0.0
    later = loop.update(angle_rad=0.0, reference_rad=0.0, feedforward_A=3.0)
    assert later.current_A == 0.0 and loop.fault is Fault.FOLLOWING_ERROR


@pytest.mark.parametrize(
    ("limits", "angle", "ff", "fault"),
    [
        ({"travel_m": 0.01}, 0.011 / R, 0.0, Fault.TRAVEL),
        ({"current_A": 5.0}, 0.0, 6.0, Fault.CURRENT),
    ],
)
def test_travel_and_current_trips(
    limits: dict[str, float], angle: float, ff: float, fault: Fault
) -> None:
    loop = make_loop(following_error_m=1.0, **limits)
    out = loop.update(angle_rad=angle, reference_rad=angle, feedforward_A=ff)
    assert out.fault is fault and out.current_A == 0.0


def test_generator_equals_ptc_across_block_boundaries() -> None:
    ref = SineReference(amplitude_m=0.01, frequency_hz=3.0)
    gen = FeedforwardGenerator(reference=ref, control_period_s=1e-3, lead_m_per_rad=R, **NOMINAL)
    n = 3 * BLOCK_STEPS + 10
    got = []
    for start, stop in ((0, 7), (7, 300), (300, n)):  # requests straddle blocks
        got += gen.samples(start, stop)
    t = np.arange(0, n + 2, 2) * 1e-3
    pos, vel, _ = ref.sample(t)
    expected = MultiratePtc(control_period_s=1e-3, **NOMINAL).feedforward(
        np.column_stack((pos, vel)) / R
    )
    got_arr = np.array(got)
    assert_allclose(got_arr[:, 0], expected.position_rad[:n], rtol=1e-12, atol=1e-15)
    assert_allclose(got_arr[:, 2], expected.current_A[:n], rtol=1e-9, atol=1e-12)
    with pytest.raises(ConfigError, match="start"):
        gen.samples(0, 5)


def test_generator_without_ptc_adds_the_friction_table() -> None:
    table = FrictionTable(np.array([0.0, 10e-6, 20e-6]), np.array([-2.0, 0.0, 2.0]))
    ref = SineReference(amplitude_m=1e-3, frequency_hz=1.0)
    gen = FeedforwardGenerator(
        reference=ref,
        control_period_s=1e-3,
        lead_m_per_rad=R,
        ptc_enabled=False,
        friction_table=table,
        **NOMINAL,
    )
    out = np.array(gen.samples(0, 1000))
    pos, _, _ = ref.sample(np.arange(1000) * 1e-3)
    assert_allclose(out[:, 0], pos / R, rtol=1e-12)
    # Moving up from the start: torque = table(x - x_0); after the top
    # (t = 0.25 s) moving down: -table(x_top - x).
    up = 5  # 31 um from the start: beyond the table, +2 N m
    assert pos[up] - pos[0] > 20e-6
    assert out[up, 2] == pytest.approx(2.0 / 0.715, rel=1e-12)
    k = 251  # just after the reversal at sample 250
    d = pos[250] - pos[k]
    assert out[k, 2] == pytest.approx(
        -np.interp(d, table.displacement_m, table.torque_Nm) / 0.715, rel=1e-9
    )
