"""Feedback loop (trips) and feedforward generator (blocks, PTC, friction table)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.feedback.loop import Fault, FeedbackLoop, SafetyLimits
from servo_axis.core.feedback.pid import DiscretePid, design_pid_pole_placement
from servo_axis.core.feedforward.friction_table import FrictionTable
from servo_axis.core.feedforward.generator import BLOCK_STEPS, FeedforwardGenerator
from servo_axis.core.feedforward.ptc import MultiratePtc
from servo_axis.core.feedforward.terms import FrictionTableTerm
from servo_axis.core.models.ball_screw import BallScrewParams, BallScrewPlant
from servo_axis.core.models.base import NominalModel
from servo_axis.core.reference import SineReference
from servo_axis.core.timing import SampleGrid

NOMINAL = {"inertia_kgm2": 0.01, "damping_Nms_per_rad": 0.1, "torque_constant_Nm_per_A": 0.715}
R = 1.91e-3
GRID = SampleGrid(control_period_s=1e-3)
P_N = NominalModel(**NOMINAL)


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
    gen = FeedforwardGenerator(reference=ref, grid=GRID, lead_m_per_rad=R, nominal=P_N)
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
    gen = FeedforwardGenerator(reference=ref, grid=GRID, lead_m_per_rad=R, nominal=P_N)
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
        grid=GRID,
        lead_m_per_rad=R,
        nominal=P_N,
        ptc_enabled=False,
        terms=[FrictionTableTerm(table, torque_constant_Nm_per_A=0.715)],
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


def test_ptc_with_a_model_replaced_from_an_instant_equals_two_ptcs() -> None:
    """003 eq. (11): from instant i0 on, the feedforward is that of the new model."""
    ref = SineReference(amplitude_m=0.01, frequency_hz=3.0)
    t = np.arange(0, 401, 2) * 1e-3
    pos, vel, _ = ref.sample(t)
    x_d = np.column_stack((pos, vel)) / R
    other = {"inertia_kgm2": 0.02, "damping_Nms_per_rad": 0.3, "torque_constant_Nm_per_A": 0.715}
    adaptive = MultiratePtc(control_period_s=1e-3, **NOMINAL)
    adaptive.replace_model(from_instant=120, **other)
    # Asked in two calls that straddle the switch: the grouping changes nothing.
    first = adaptive.feedforward(x_d[:101], 0)
    second = adaptive.feedforward(x_d[100:], 100)
    got = np.concatenate((first.current_A, second.current_A))
    before = MultiratePtc(control_period_s=1e-3, **NOMINAL).feedforward(x_d).current_A
    after = MultiratePtc(control_period_s=1e-3, **other).feedforward(x_d).current_A
    np.testing.assert_array_equal(got[:240], before[:240])
    np.testing.assert_array_equal(got[240:], after[240:])
    assert np.max(np.abs(after[240:] - before[240:])) > 1e-3  # the models differ
    with pytest.raises(ConfigError, match="from_instant"):
        adaptive.replace_model(from_instant=120, **other)  # not after the last switch


def test_input_side_corrections_add_a_current_from_their_period_on() -> None:
    """ILC-style corrections (001 eq. (3)): a current per control sample of the period."""
    ref = SineReference(amplitude_m=0.01, frequency_hz=2.0)
    plain = FeedforwardGenerator(reference=ref, grid=GRID, lead_m_per_rad=R, nominal=P_N)
    gen = FeedforwardGenerator(
        reference=ref,
        grid=GRID,
        lead_m_per_rad=R,
        nominal=P_N,
        learning_period_steps=100,
        learning_side="input",
    )
    assert gen.ready_until() == 100  # period 1 starts with its own correction
    f = np.linspace(0.0, 1.0, 100)
    gen.set_correction(1, f)
    gen.repeat_correction(2)
    got = np.array(gen.samples(0, 300))
    base = np.array(plain.samples(0, 300))
    # The blocks are cut at the period boundaries here, so the PTC products
    # may round differently (1 ulp): compare to a tolerance.
    np.testing.assert_allclose(got[:, :2], base[:, :2], rtol=1e-14, atol=1e-15)  # target untouched
    np.testing.assert_allclose(got[:100, 2], base[:100, 2], rtol=1e-14, atol=1e-13)
    np.testing.assert_allclose(got[100:200, 2] - base[100:200, 2], f, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[200:300, 2] - base[200:300, 2], f, rtol=0, atol=1e-12)
    with pytest.raises(SignalError, match="correction"):
        gen.set_correction(4, f[:50])


def test_a_late_target_correction_applies_from_the_next_sample_given() -> None:
    """Realtime (RPTC, 000): c_2 comes after the boundary went by with c_1 repeated."""
    ref = SineReference(amplitude_m=0.01, frequency_hz=2.0)

    def make() -> FeedforwardGenerator:
        return FeedforwardGenerator(
            reference=ref, grid=GRID, lead_m_per_rad=R, nominal=P_N, learning_period_steps=100
        )

    nd = 50  # reference instants per period
    c1 = (np.full(nd, 1e-4), np.zeros(nd))
    c2 = (np.linspace(0.0, 2e-4, nd), np.full(nd, 1e-3))
    late, timely, repeated = make(), make(), make()
    for gen in (late, timely, repeated):
        gen.set_correction(1, *c1)
    assert late.ready_until() == 198  # x_d one instant into period 2 from sample 198 on
    late.repeat_correction(2)
    repeated.repeat_correction(2)
    timely.set_correction(2, *c2)
    first = late.samples(0, 230)  # the boundary went by: 32 samples with c_1 again
    assert late.replace_correction(2, *c2) == 230
    rest = late.samples(230, 298)
    np.testing.assert_array_equal(first, repeated.samples(0, 230))
    np.testing.assert_array_equal(rest, timely.samples(0, 298)[230:])
    assert np.max(np.abs(np.subtract(rest, repeated.samples(230, 298)))) > 1e-6  # c_2 counts


def test_the_sample_grid() -> None:
    g = SampleGrid(control_period_s=1e-3)
    assert g.reference_period_s == 2e-3 and g.steps(2.0) == 2000
    assert g.instants_per(0.5, name="cycle_s") == 250
    assert [g.is_reference_instant(k) for k in range(4)] == [True, False, True, False]
    np.testing.assert_array_equal(g.reference_instants([0, 1, 2, 5]), [True, False, True, False])
    assert g.instant_of(7) == 3 and g.step_of(3) == 6
    with pytest.raises(ConfigError, match="cycle_s"):
        g.instants_per(0.501, name="cycle_s")
    with pytest.raises(ConfigError, match="duration_s"):
        g.steps(float("nan"))
    with pytest.raises(ConfigError, match="ratio"):
        SampleGrid(control_period_s=1e-3, ratio=0)


@pytest.mark.parametrize("with_dob", [False, True])
@pytest.mark.parametrize(
    "sensors", [("encoder", "encoder"), ("scale", "encoder"), ("scale", "scale")]
)
def test_fused_filters_equal_the_filter_objects_bit_for_bit(
    with_dob: bool, sensors: tuple[str, str]
) -> None:
    """The loop's inlined PID/DOB update (and ``current``) give the objects' floats and state."""
    from servo_axis.core.feedback.dob import DisturbanceObserver

    def build() -> FeedbackLoop:
        gains = design_pid_pole_placement(bandwidth_hz=40.0, **NOMINAL)
        dob = DisturbanceObserver(**NOMINAL, cutoff_hz=80.0, period_s=1e-3) if with_dob else None
        return FeedbackLoop(
            pid=DiscretePid(gains=gains, period_s=1e-3),
            dob=dob,
            lead_m_per_rad=R,
            limits=SafetyLimits(current_A=40.0),
            sensor=sensors[0],
            dob_sensor=sensors[1],
        )

    fused, plain, fast = build(), build(), build()
    assert fused._fused is not None
    plain._fused = None  # the objects' own update
    rng = np.random.default_rng(3)
    for k in range(3000):
        enc, scale = rng.normal(0.0, 1e-2), rng.normal(0.0, 2e-5)
        r, ff = rng.normal(0.0, 1e-2), rng.normal(0.0, 1.0) * (10.0 if k > 2900 else 1.0)
        if k == 1000:
            for loop in (fused, plain, fast):
                loop._pid.reset()
                if loop._dob is not None:
                    loop._dob.reset()
        kwargs = {"encoder_rad": enc, "scale_m": scale, "reference_rad": r, "feedforward_A": ff}
        a, b = fused.step(**kwargs), plain.step(**kwargs)
        c = fast.current(**kwargs)
        assert a == b and np.float64(a.current_A).tobytes() == np.float64(c).tobytes()
        assert fused._pid.filter.state == plain._pid.filter.state == fast._pid.filter.state
    assert fused.fault == plain.fault == fast.fault
