"""004 eq. (9) with sgn(v) and z of the measured stage, in the feedback loop (issue 33)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.feedback.dob import DisturbanceObserver
from servo_axis.core.feedback.loop import FeedbackLoop, SafetyLimits
from servo_axis.core.feedback.pid import DiscretePid, design_pid_pole_placement
from servo_axis.core.feedback.stage_sigmoid import StageSigmoid
from servo_axis.core.feedforward.sigmoid import (
    PAPER_SIGMA_M2_PER_RAD,
    SigmoidParams,
    gamma_for_width,
    sigmoid_torque,
)
from servo_axis.params import factories, resolve
from servo_axis.params.scenario import load_scenario

CONFIG = Path(__file__).resolve().parents[3] / "config"
KT = 0.715
PARAMS = SigmoidParams(
    sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD,
    gamma_m_per_rad=gamma_for_width(sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, half_width_m=7.5e-6),
    coulomb_Nm=0.4225,
)
COUNT_M = 100e-9  # the linear scale's count
T_U = 5e-4


def scale_readings() -> np.ndarray:
    """x = 25 (1 - cos 2 pi t) mm on a 100 nm scale, 0.5 ms samples, 2 s: reversals at 0.5, 1, 1.5 s."""
    t = np.arange(4001) * T_U
    return np.round(0.025 * (1.0 - np.cos(2 * np.pi * t)) / COUNT_M) * COUNT_M


def test_sign_and_distance_are_the_measured_ones_and_the_torque_is_eq_9() -> None:
    x = scale_readings()
    law = StageSigmoid(PARAMS, torque_constant_Nm_per_A=KT)
    torque = np.array([law.torque_Nm(float(xi)) for xi in x])
    # Independently: the direction of the last change of the reading, the
    # reversal at the extremum before the first reading behind it.
    step = np.sign(np.diff(x))
    direction = np.zeros(len(x))
    last = 0.0
    for k in range(1, len(x)):
        last = step[k - 1] if step[k - 1] != 0 else last
        direction[k] = last
    flips = np.flatnonzero(np.diff(direction) * direction[:-1] < 0) + 1  # first sample behind
    assert_allclose(flips * T_U, [0.5, 1.0, 1.5], atol=0.005)  # within 10 samples of the extrema
    z = np.full(len(x), np.inf)
    for i, k in enumerate(flips):
        end = flips[i + 1] if i + 1 < len(flips) else len(x)
        z[k:end] = np.abs(x[k:end] - x[k - 1])
    expected = sigmoid_torque(z, direction, PARAMS)
    assert_array_equal(torque, expected)  # the same floats as the reference law's function
    assert law.direction == -1 and law.reversal_m == pytest.approx(0.05, abs=COUNT_M)
    # What the paper's law does, measured: F_0 up to the reversal, 0 at it, 0.9 F_0 at x_s / 2.
    k = flips[1]
    assert torque[k - 1] == pytest.approx(-0.4225, rel=1e-3) and abs(torque[k]) < 0.02
    after = np.flatnonzero(np.abs(torque[k:]) >= 0.9 * 0.4225)[0] + k
    assert abs(x[after - 1] - x[k - 1]) < 7.5e-6 + COUNT_M <= abs(x[after] - x[k - 1]) + 2 * COUNT_M
    assert_allclose(law.current_A(float(x[-1])), torque[-1] / KT, rtol=1e-15)


def test_no_current_before_the_stage_moves_and_a_bad_reading_is_refused() -> None:
    law = StageSigmoid(PARAMS, torque_constant_Nm_per_A=KT)
    assert [law.torque_Nm(0.0) for _ in range(3)] == [0.0, 0.0, 0.0]
    assert law.torque_Nm(-COUNT_M) == -0.4225  # moving, no reversal yet: z = inf
    with pytest.raises(SignalError, match="table_m"):
        law.torque_Nm(float("nan"))
    with pytest.raises(ConfigError, match="torque_constant_Nm_per_A"):
        StageSigmoid(PARAMS, torque_constant_Nm_per_A=0.0)


def make_loop(compensation: StageSigmoid | None) -> FeedbackLoop:
    nominal = {"inertia_kgm2": 2.6e-3, "damping_Nms_per_rad": 0.070, "torque_constant_Nm_per_A": KT}
    gains = design_pid_pole_placement(bandwidth_hz=20.0, **nominal)
    return FeedbackLoop(
        pid=DiscretePid(gains=gains, period_s=T_U),
        dob=DisturbanceObserver(cutoff_hz=80.0, period_s=T_U, **nominal),
        lead_m_per_rad=1.91e-3,
        limits=SafetyLimits(current_A=1e9),  # open loop: the readings ignore the command
        sensor="scale",
        compensation=compensation,
    )


def test_the_loop_adds_it_outside_the_dob_as_004_fig_5() -> None:
    """The DOB reads the current without F_c: on the same readings, the command with the
    law is the command without it plus F_c / K_T, sample for sample (exact floats)."""
    x = scale_readings()[:2400]
    encoder = x / 1.91e-3 + 1e-5 * np.sin(np.arange(len(x)))  # a screw that is not rigid
    reference = (x + 2e-6) / 1.91e-3
    bare, compensated = (
        make_loop(None),
        make_loop(StageSigmoid(PARAMS, torque_constant_Nm_per_A=KT)),
    )
    alone = StageSigmoid(PARAMS, torque_constant_Nm_per_A=KT)
    for k in range(len(x)):
        reading = {"encoder_rad": encoder[k], "scale_m": x[k], "reference_rad": reference[k]}
        u0 = bare.step(**reading, feedforward_A=0.1).current_A
        u1 = compensated.current(**reading, feedforward_A=0.1)
        assert u1 == u0 + alone.current_A(float(x[k])), k
    assert not bare.tripped and not compensated.tripped
    with pytest.raises(ConfigError, match="needs step"):
        compensated.update(angle_rad=0.0, reference_rad=0.0, feedforward_A=0.0)


def test_the_key_moves_the_law_from_the_feedforward_to_the_loop() -> None:
    """``sigmoid.source: stage``: the feedback copies sigmoid.* of the feedforward section and
    builds the law; the feedforward's term is off. ``reference`` (the default): the reverse."""
    for name, in_loop in (
        ("fast_reversal_contact_sigmoid_stage", True),
        ("fast_reversal_contact_sigmoid", False),
    ):
        scenario = load_scenario(CONFIG / f"{name}.yaml")
        fb = resolve.node_values(scenario, "feedback")
        assert fb["sigmoid.enabled"] is True and fb["sigmoid.coulomb_Nm"] == 0.4225
        loop = factories.build_loop(fb)
        law = loop._compensation
        assert (law is not None) == in_loop
        ff = resolve.node_values(scenario, "feedforward")
        terms = [type(t).__name__ for t in factories.build_terms(ff)]
        assert terms == ([] if in_loop else ["OutsideObserver"]), terms
        if law is not None:
            assert law.params.gamma_m_per_rad == 0.011012 and law.params.sigma_m2_per_rad == 4e-8


def test_the_feedback_copies_have_the_feedforward_term_s_defaults() -> None:
    from servo_axis.params import schemas
    from servo_axis.plugins.sigmoid import SCHEMA

    for key, param in schemas.FEEDBACK_SIGMOID.items():
        assert param.default == SCHEMA[key].default, key
