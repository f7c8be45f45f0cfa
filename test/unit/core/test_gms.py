"""The GMS friction model (Al-Bender et al. 2005), its text, its fit and its feedforward term.

Paper 004 Sect. II-A, Fig. 4(b): the conventional GMS model fitted to a slow
50 um, 0.05 Hz reversal, compensated as a feedforward. No ROS.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError, TableError
from servo_axis.core.feedforward.gms_compensation import GmsTerm
from servo_axis.core.feedforward.terms import FeedforwardTerm, ReferenceBlock
from servo_axis.core.friction.gms_fitting import fit_gms
from servo_axis.core.friction.gms_model import GmsModel, simulate_gms
from servo_axis.core.friction.gms_params import GmsParams
from servo_axis.core.friction.gms_text import HEADER_LINE, gms_from_text, gms_to_text

FC = 3.2
ALPHA = (0.3, 0.45, 0.25)
BREAKAWAY = (1.5e-6, 5e-6, 12e-6)  # virgin curve: 12 um; a reversal spans 24 um
STIFFNESS = tuple(a * FC / b for a, b in zip(ALPHA, BREAKAWAY, strict=True))
KT = 0.715


def three_elements(**extra: float) -> GmsParams:
    return GmsParams(stiffness_Nm_per_m=STIFFNESS, weights=ALPHA, coulomb_Nm=FC, **extra)


def triangle(points_m: list[float], speed_m_s: float, period_s: float) -> tuple[np.ndarray, ...]:
    """Straight legs between the points at constant speed: positions and velocities."""
    pos: list[float] = [points_m[0]]
    vel: list[float] = [0.0]
    for a, b in itertools.pairwise(points_m):
        n = round(abs(b - a) / (speed_m_s * period_s))
        pos += np.linspace(a, b, n + 1)[1:].tolist()
        vel += [math.copysign(speed_m_s, b - a)] * n
    return np.array(pos), np.array(vel)


# --------------------------------------------------------------------------- (a) the model


def test_quasi_static_reversal_follows_masing_s_rule() -> None:
    """Virgin curve, then each reversal branch is twice the virgin curve stretched by 2."""
    p = three_elements()
    period = 5e-4
    # 10 um/s: at C = 5e5 /s a slip transient lasts 20 pm, below any comparison here.
    pos, vel = triangle([0.0, -40e-6, 40e-6, -40e-6], 10e-6, period)
    torque = simulate_gms(p, pos, vel, period_s=period)
    n1 = int(np.argmin(pos))
    n2 = int(np.argmax(pos))
    virgin = p.virgin_curve(pos[: n1 + 1])
    assert_allclose(torque[: n1 + 1], virgin, rtol=0, atol=1e-9)
    up = pos[n1 : n2 + 1] - pos[n1]
    assert_allclose(torque[n1 : n2 + 1], -FC + 2.0 * p.virgin_curve(up / 2.0), rtol=0, atol=1e-9)
    assert_allclose(torque[n1 : n2 + 1], p.reversal_curve(up), rtol=0, atol=1e-9)
    down = pos[n2] - pos[n2:]
    assert_allclose(torque[n2:], FC - 2.0 * p.virgin_curve(down / 2.0), rtol=0, atol=1e-9)
    # The branch spans -F_c..F_c over twice the largest break-away (24 um) and then slides.
    assert torque[n1] == pytest.approx(-FC, abs=1e-12)
    assert np.all(np.abs(torque[n1 : n2 + 1][up >= 24e-6] - FC) <= 1e-12)


def test_steady_sliding_is_coulomb_plus_viscous() -> None:
    sigma2 = 40.0  # N m s/m
    p = three_elements(static_Nm=4.0, viscous_Nms_per_m=sigma2)
    period = 5e-4
    for v in (10e-3, -10e-3):  # 10 mm/s = 10 V_s: the Stribeck term is exp(-100)
        pos = v * period * np.arange(200)
        torque = simulate_gms(p, pos, np.full(pos.size, v), period_s=period)
        assert_allclose(torque[-50:], math.copysign(FC, v) + sigma2 * v, rtol=1e-12, atol=0)


def test_stribeck_curve() -> None:
    p = three_elements(static_Nm=4.0, stribeck_velocity_m_s=2e-3, stribeck_exponent=1.5)
    v = np.array([0.0, 1e-3, -1e-3, 5e-3])
    expected = FC + 0.8 * np.exp(-(np.abs(v / 2e-3) ** 1.5))
    assert_allclose(p.stribeck(v), expected, rtol=1e-15, atol=0)
    assert three_elements().stribeck(0.0) == FC  # F_s defaults to F_c: no Stribeck effect


def test_slip_rule_is_integrated_exactly() -> None:
    """A slipping element approaches its new level as exp(-C t), whatever the step."""
    c = 2e3
    p = GmsParams(
        stiffness_Nm_per_m=(1e6,),
        weights=(1.0,),
        coulomb_Nm=1.0,
        static_Nm=2.0,
        stribeck_velocity_m_s=1e-3,
        attraction_per_s=c,
    )
    slow, fast = 1e-4, 1e-2
    s_slow = float(p.stribeck(slow))
    results = []
    for substeps in (1, 4):
        model = GmsModel(p)
        t = 1e-3 / substeps
        x = 0.0
        model.update(x, slow, t)
        for _ in range(50 * substeps):  # 5 um at 0.1 mm/s: the element slips at s(slow)
            x += slow * t
            f = model.update(x, slow, t)
        assert f == pytest.approx(s_slow, rel=1e-12)
        assert model.slipping == (True,)
        for _ in range(3 * substeps):  # then 3 ms at 10 mm/s: the level drops to F_c
            x += fast * t
            f = model.update(x, fast, t)
        results.append(f)
    expected = 1.0 + (s_slow - 1.0) * math.exp(-c * 3e-3)
    assert_allclose(results, [expected, expected], rtol=1e-12, atol=0)


def test_zero_velocity_sticks_and_the_first_sample_only_sets_the_position() -> None:
    p = GmsParams(stiffness_Nm_per_m=(1e6,), weights=(1.0,), coulomb_Nm=1.0)
    model = GmsModel(p)
    assert model.update(5e-6, 1e-5, 1e-3) == 0.0  # no increment from an unknown position
    assert model.update(7e-6, 1e-5, 1e-3) == pytest.approx(1.0, rel=1e-12)  # slips at F_c
    assert model.slipping == (True,)
    assert model.update(7e-6, 0.0, 1e-3) == pytest.approx(1.0, rel=1e-12)
    assert model.slipping == (False,)  # at rest it sticks, holding its force
    assert model.update(6.5e-6, 0.0, 1e-3) == pytest.approx(0.5, rel=1e-9)  # elastic unloading
    model.reset()
    assert model.forces_Nm == (0.0,)
    assert model.update(0.0, 0.0, 1e-3) == 0.0


def test_update_names_a_bad_argument() -> None:
    model = GmsModel(three_elements())
    with pytest.raises(SignalError, match="position_m"):
        model.update(math.nan, 0.0, 1e-3)
    with pytest.raises(SignalError, match="velocity_m_s"):
        model.update(0.0, math.inf, 1e-3)
    with pytest.raises(SignalError, match="period_s"):
        model.update(0.0, 0.0, 0.0)


# --------------------------------------------------------------------------- (b) the fit


def slow_reversal(params: GmsParams) -> tuple[np.ndarray, np.ndarray, float]:
    """004 Fig. 4(b)'s identification: 50 um, 0.05 Hz, sampled at 0.5 ms, 1.5 periods."""
    period = 5e-4
    t = np.arange(0.0, 30.0, period)
    w = 2.0 * math.pi * 0.05
    pos = 50e-6 * (1.0 - np.cos(w * t))  # starts at rest; reversals at 10 s and 20 s
    vel = 50e-6 * w * np.sin(w * t)
    return pos, simulate_gms(params, pos, vel, period_s=period), period


def test_fit_recovers_the_model_it_was_generated_from() -> None:
    true = three_elements()
    pos, torque, period = slow_reversal(true)
    fit = fit_gms(pos, torque, elements=3, period_s=period)
    assert_allclose(fit.params.coulomb_Nm, FC, rtol=1e-3)
    assert_allclose(fit.params.stiffness_Nm_per_m, STIFFNESS, rtol=1e-3)
    assert_allclose(fit.params.weights, ALPHA, rtol=1e-3)
    assert fit.rms_residual_Nm < 1e-4
    assert fit.model_torque_Nm.shape == pos.shape
    # The parameters a slow reversal cannot identify keep their defaults.
    assert fit.params.static_Nm == fit.params.coulomb_Nm
    defaults = GmsParams(stiffness_Nm_per_m=(1.0,), weights=(1.0,), coulomb_Nm=1.0)
    for name in (
        "stribeck_velocity_m_s",
        "stribeck_exponent",
        "attraction_per_s",
        "viscous_Nms_per_m",
    ):
        assert getattr(fit.params, name) == getattr(defaults, name)


def test_fit_recovers_the_model_from_noisy_torque() -> None:
    true = three_elements()
    pos, torque, period = slow_reversal(true)
    noise_std = 0.02  # N m, 0.6 % of F_c
    noisy = torque + noise_std * np.random.default_rng(2005).standard_normal(torque.size)
    fit = fit_gms(pos, noisy, elements=3, period_s=period)
    assert_allclose(fit.params.coulomb_Nm, FC, rtol=1e-2)
    assert_allclose(fit.params.stiffness_Nm_per_m, STIFFNESS, rtol=3e-2)
    assert_allclose(fit.params.weights, ALPHA, rtol=3e-2)
    assert_allclose(fit.rms_residual_Nm, noise_std, rtol=0.05)


def test_fit_is_deterministic_and_keeps_the_fixed_values_of_initial() -> None:
    true = three_elements()
    pos, torque, period = slow_reversal(true)
    start = GmsParams(
        stiffness_Nm_per_m=tuple(1.3 * k for k in STIFFNESS),
        weights=(1 / 3, 1 / 3, 1 / 3),
        coulomb_Nm=2.5,
        attraction_per_s=1e6,
        viscous_Nms_per_m=0.0,
    )
    a = fit_gms(pos, torque, elements=3, period_s=period, initial=start)
    b = fit_gms(pos, torque, elements=3, period_s=period, initial=start)
    assert a.params == b.params
    assert a.params.attraction_per_s == 1e6
    assert_allclose(a.params.stiffness_Nm_per_m, STIFFNESS, rtol=1e-3)


def test_fit_ignores_the_virgin_start() -> None:
    """Before the first reversal the axis may be in any state: those samples do not count."""
    true = three_elements()
    pos, torque, period = slow_reversal(true)
    first = round(10.0 / period)  # the reversal at 10 s
    garbage = torque.copy()
    garbage[: first - 1] = 0.0
    fit = fit_gms(pos, garbage, elements=3, period_s=period)
    assert_allclose(fit.params.stiffness_Nm_per_m, STIFFNESS, rtol=1e-3)
    assert_allclose(fit.params.coulomb_Nm, FC, rtol=1e-3)


def test_fit_names_bad_arguments() -> None:
    pos, torque, period = slow_reversal(three_elements())
    with pytest.raises(SignalError, match="position_m, torque_Nm"):
        fit_gms(pos, torque[:-1], elements=3, period_s=period)
    bad = torque.copy()
    bad[5] = math.nan
    with pytest.raises(SignalError, match="torque_Nm"):
        fit_gms(pos, bad, elements=3, period_s=period)
    with pytest.raises(SignalError, match="position_m: expected at least"):
        fit_gms(pos[:4], torque[:4], elements=3, period_s=period)
    with pytest.raises(SignalError, match="position_m: no reversal"):
        fit_gms(pos[:1000], torque[:1000], elements=3, period_s=period)
    with pytest.raises(SignalError, match="position_m: too short after the first reversal"):
        n = round(10.0 / period) + 3
        fit_gms(pos[:n], torque[:n], elements=3, period_s=period)
    with pytest.raises(SignalError, match="position_m: expected motion"):
        fit_gms(np.zeros(100), np.zeros(100), elements=3, period_s=period)
    with pytest.raises(ConfigError, match="elements"):
        fit_gms(pos, torque, elements=21, period_s=period)
    with pytest.raises(ConfigError, match="period_s"):
        fit_gms(pos, torque, elements=3, period_s=0.0)
    with pytest.raises(ConfigError, match="initial"):
        fit_gms(pos, torque, elements=2, period_s=period, initial=three_elements())


# --------------------------------------------------------------------------- (c) the text


def test_text_round_trip_is_exact() -> None:
    p = GmsParams(
        stiffness_Nm_per_m=(0.1 + 0.2, 1 / 3 * 1e6, 7.123456789012345e5),
        weights=(0.1, 0.2, 0.7),
        coulomb_Nm=3.2000000000000006,
        static_Nm=math.pi + 0.1,
        stribeck_velocity_m_s=1 / 7,
        stribeck_exponent=1.1,
        attraction_per_s=123456.789,
        viscous_Nms_per_m=1e-300,
    )
    text = gms_to_text(p, plant_model="ball_screw", plant_fingerprint="ball_screw:0123456789abcdef")
    assert text.splitlines()[0] == HEADER_LINE
    back, model, fingerprint = gms_from_text(text, source="gms.txt")
    assert back == p
    assert gms_to_text(back, plant_model=model, plant_fingerprint=fingerprint) == text
    assert (model, fingerprint) == ("ball_screw", "ball_screw:0123456789abcdef")


def good_text() -> str:
    return gms_to_text(
        three_elements(), plant_model="ball_screw", plant_fingerprint="ball_screw:ab"
    )


def replace_line(text: str, key: str, line: str | None) -> str:
    out = []
    for row in text.splitlines():
        if row.startswith(f"{key} ="):
            if line is not None:
                out.append(line)
        else:
            out.append(row)
    return "\n".join(out) + "\n"


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("", "line 1: expected header"),
        (good_text().replace("v1", "v2", 1), "line 1: expected header"),
        (replace_line(good_text(), "coulomb_Nm", None), "missing key(s) coulomb_Nm"),
        (replace_line(good_text(), "plant_model", None), "missing key(s) plant_model"),
        (
            replace_line(good_text(), "coulomb_Nm", "coulomb_Nm = 3,2"),
            "coulomb_Nm: expected a number",
        ),
        (
            replace_line(good_text(), "coulomb_Nm", "coulomb_Nm = nan"),
            "coulomb_Nm: expected a finite",
        ),
        (replace_line(good_text(), "weights", "weights = 0.5, inf"), "weights: expected a finite"),
        (replace_line(good_text(), "weights", "weights = 0.5, 0.5"), "unequal lengths"),
        (
            replace_line(good_text(), "weights", "weights = 0.5, 0.4, 0.2"),
            "weights: expected a sum",
        ),
        (
            replace_line(good_text(), "static_Nm", "static_Nm = 1.0"),
            "static_Nm: expected a value >=",
        ),
        (
            replace_line(good_text(), "plant_model", "plant_model ="),
            "plant_model: expected a non-empty",
        ),
        (good_text() + "colomb_Nm = 3.2\n", "unknown key 'colomb_Nm'"),
        (good_text() + "coulomb_Nm = 3.2\n", "key 'coulomb_Nm' given twice"),
        (good_text() + "just words\n", "expected 'key = value'"),
    ],
)
def test_malformed_text_names_the_problem(text: str, problem: str) -> None:
    with pytest.raises(TableError) as info:
        gms_from_text(text, source="gms.txt")
    assert str(info.value).startswith("gms.txt: ")
    assert problem in str(info.value)


def test_gms_to_text_refuses_a_plant_name_that_would_not_read_back() -> None:
    with pytest.raises(ConfigError, match="plant_model"):
        gms_to_text(three_elements(), plant_model="", plant_fingerprint="x")
    with pytest.raises(ConfigError, match="plant_fingerprint"):
        gms_to_text(three_elements(), plant_model="ball_screw", plant_fingerprint="a\nb")


# --------------------------------------------------------------------------- (d) validation


def test_static_level_defaults_to_coulomb() -> None:
    assert three_elements().static_Nm == FC
    assert three_elements() == three_elements(static_Nm=FC)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"stiffness_Nm_per_m": ()}, "stiffness_Nm_per_m: expected 1..20"),
        (
            {"stiffness_Nm_per_m": (1.0,) * 21, "weights": (1 / 21,) * 21},
            "stiffness_Nm_per_m: expected 1..20",
        ),
        ({"stiffness_Nm_per_m": (1.0, -1.0, 1.0)}, "stiffness_Nm_per_m[1]"),
        ({"stiffness_Nm_per_m": (1.0, math.nan, 1.0)}, "stiffness_Nm_per_m[1]"),
        ({"stiffness_Nm_per_m": "abc"}, "stiffness_Nm_per_m: expected a sequence"),
        ({"weights": (0.5, 0.5)}, "weights: expected one per element"),
        ({"weights": (0.5, 0.6, -0.1)}, "weights[2]"),
        ({"weights": (0.3, 0.3, 0.3)}, "weights: expected a sum of 1"),
        ({"coulomb_Nm": 0.0}, "coulomb_Nm"),
        ({"static_Nm": 3.0}, "static_Nm"),
        ({"static_Nm": math.inf}, "static_Nm"),
        ({"stribeck_velocity_m_s": 0.0}, "stribeck_velocity_m_s"),
        ({"stribeck_exponent": -1.0}, "stribeck_exponent"),
        ({"attraction_per_s": 0.0}, "attraction_per_s"),
        ({"viscous_Nms_per_m": -1e-3}, "viscous_Nms_per_m"),
    ],
)
def test_params_validation_names_the_field(change: dict[str, object], field: str) -> None:
    values: dict[str, object] = {
        "stiffness_Nm_per_m": STIFFNESS,
        "weights": ALPHA,
        "coulomb_Nm": FC,
        **change,
    }
    with pytest.raises(ConfigError) as info:
        GmsParams(**values)  # type: ignore[arg-type]
    assert str(info.value).startswith(field)


def test_weights_sum_tolerance_is_1e_9() -> None:
    GmsParams(stiffness_Nm_per_m=(1.0, 1.0), weights=(0.5, 0.5 + 0.9e-9), coulomb_Nm=1.0)
    with pytest.raises(ConfigError, match="weights"):
        GmsParams(stiffness_Nm_per_m=(1.0, 1.0), weights=(0.5, 0.5 + 1.1e-9), coulomb_Nm=1.0)


# --------------------------------------------------------------------------- (e) the term


def reference_blocks(pos: np.ndarray, vel: np.ndarray, cuts: list[int]) -> list[ReferenceBlock]:
    steps = np.arange(pos.size, dtype=np.int64)
    edges = [0, *cuts, pos.size]
    return [
        ReferenceBlock(
            step=steps[a:b],
            position_m=pos[a:b],
            velocity_m_s=vel[a:b],
            acceleration_m_s2=np.zeros(b - a),
        )
        for a, b in itertools.pairwise(edges)
    ]


def test_term_is_the_model_torque_over_kt_and_continuous_across_blocks() -> None:
    # Stribeck and a finite C: the result depends on the state and the period, not only the path.
    p = three_elements(static_Nm=4.0, attraction_per_s=300.0, viscous_Nms_per_m=20.0)
    period = 1e-3
    pos, vel = triangle([0.0, 30e-6, -20e-6, 25e-6], 2e-4, period)
    expected = simulate_gms(p, pos, vel, period_s=period) / KT

    whole: FeedforwardTerm = GmsTerm(p, torque_constant_Nm_per_A=KT, control_period_s=period)
    (block,) = reference_blocks(pos, vel, [])
    one = whole.currents(block)
    assert_allclose(one, expected, rtol=0, atol=0)

    split = GmsTerm(p, torque_constant_Nm_per_A=KT, control_period_s=period)
    parts = [split.currents(b) for b in reference_blocks(pos, vel, [1, 37, 38, 150, 401])]
    assert_allclose(np.concatenate(parts), one, rtol=0, atol=0)


def test_term_steps_the_model_by_the_gap_between_steps() -> None:
    p = three_elements(static_Nm=4.0, attraction_per_s=300.0)
    period = 1e-3
    pos, vel = triangle([0.0, 30e-6], 1e-3, period)
    pos, vel = pos[::2], vel[::2]  # every other control sample
    term = GmsTerm(p, torque_constant_Nm_per_A=KT, control_period_s=period)
    block = ReferenceBlock(
        step=2 * np.arange(pos.size, dtype=np.int64),
        position_m=pos,
        velocity_m_s=vel,
        acceleration_m_s2=np.zeros(pos.size),
    )
    expected = simulate_gms(p, pos, vel, period_s=2 * period) / KT
    assert_allclose(term.currents(block), expected, rtol=0, atol=0)
    again = ReferenceBlock(
        step=block.step[-1:], position_m=pos[-1:], velocity_m_s=vel[-1:], acceleration_m_s2=vel[-1:]
    )
    with pytest.raises(SignalError, match=r"block\.step"):
        term.currents(again)


def test_term_supplies_coulomb_in_the_direction_of_motion() -> None:
    """Steady sliding at v > 0: +F_c / K_T (the compensation pushes with the motion)."""
    p = three_elements()
    period = 1e-3
    for v in (5e-3, -5e-3):
        pos = v * period * np.arange(100)
        term = GmsTerm(p, torque_constant_Nm_per_A=KT, control_period_s=period)
        (block,) = reference_blocks(pos, np.full(pos.size, v), [])
        assert_allclose(term.currents(block)[-10:], math.copysign(FC, v) / KT, rtol=1e-12)


def test_term_validates_its_constants() -> None:
    with pytest.raises(ConfigError, match="torque_constant_Nm_per_A"):
        GmsTerm(three_elements(), torque_constant_Nm_per_A=0.0, control_period_s=1e-3)
    with pytest.raises(ConfigError, match="control_period_s"):
        GmsTerm(three_elements(), torque_constant_Nm_per_A=KT, control_period_s=-1.0)
