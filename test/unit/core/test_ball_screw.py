"""Plant, friction and sensor numerics against analytic results and scipy."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.signal
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.friction.maxwell_slip import MaxwellSlip
from servo_axis.core.friction.model import FrictionParams
from servo_axis.core.models.ball_screw import (
    BALL_SCREW_MODES,
    BallScrewParams,
    BallScrewPlant,
    DisturbanceParams,
)
from servo_axis.core.sensors import PositionSensor, SensorParams

KT, J, D, R = 0.715, 0.01, 0.1, 1.91e-3


def run(plant: BallScrewPlant, currents: np.ndarray) -> np.ndarray:
    return np.array([plant.step(float(i)).angle_rad for i in currents])


def rigid_step_angle(t: np.ndarray, current: float) -> np.ndarray:
    """Analytic step response of J th'' + D th' = K_T i from rest."""
    tau = J / D
    return KT * current / D * (t - tau * (1.0 - np.exp(-t / tau)))


def test_rigid_step_matches_analytic() -> None:
    plant = BallScrewPlant(BallScrewParams())
    angles = run(plant, np.full(500, 2.0))
    t = np.arange(1, 501) * 1e-3
    assert_allclose(angles, rigid_step_angle(t, 2.0), rtol=1e-10, atol=1e-14)


def test_dead_time_is_an_exact_shift() -> None:
    # 70 us dead time at a 10 us step: the step response is the undelayed one shifted.
    params = BallScrewParams(sim_step_s=10e-6, dead_time_s=70e-6)
    angles = run(BallScrewPlant(params), np.full(300, 1.5))
    t = np.arange(1, 301) * 1e-3 - 70e-6
    assert_allclose(angles, rigid_step_angle(t, 1.5), rtol=1e-9, atol=1e-15)


def test_dead_time_longer_than_a_period() -> None:
    params = BallScrewParams(sim_step_s=50e-6, dead_time_s=2.35e-3)
    angles = run(BallScrewPlant(params), np.full(100, 1.0))
    t = np.arange(1, 101) * 1e-3 - 2.35e-3
    expected = np.where(t > 0, rigid_step_angle(np.maximum(t, 0.0), 1.0), 0.0)
    assert_allclose(angles, expected, rtol=1e-9, atol=1e-15)


def test_resonance_modes_match_transfer_function_eq30() -> None:
    # Build eq. (30) independently as a transfer function, discretise at T_u by
    # ZOH with scipy and simulate with dlsim.
    params = BallScrewParams(modes=BALL_SCREW_MODES)
    # Each parallel term of eq. (30) on its own (a single high-order
    # polynomial would be badly conditioned), then summed.
    terms = [(np.array([KT]), np.array([J, D, 0.0]))]
    for f_hz, zeta, a in BALL_SCREW_MODES:
        w = 2 * math.pi * f_hz
        terms.append((np.array([a * KT / J]), np.array([1.0, 2 * zeta * w, w * w])))
    rng = np.random.default_rng(3)
    u = rng.uniform(-2.0, 2.0, 400)
    y = np.zeros(401)
    for num, den in terms:
        sysd = scipy.signal.cont2discrete((num, den), 1e-3, method="zoh")
        _, yi = scipy.signal.dlsim((sysd[0].ravel(), sysd[1], 1e-3), np.append(u, 0.0))
        y += yi.ravel()
    ours = run(BallScrewPlant(params), u)
    assert_allclose(ours, y[1:], rtol=1e-9, atol=1e-12 * np.max(np.abs(y)))


def test_fast_path_equals_substep_integration() -> None:
    # A disturbance of ~zero amplitude forces the per-substep loop; the
    # whole-period matrices must give the same trajectory to rounding.
    base = BallScrewParams(modes=BALL_SCREW_MODES, sim_step_s=10e-6, dead_time_s=70e-6)
    slow = replace(base, disturbance=DisturbanceParams(amplitude_Nm=1e-300))
    u = np.sin(np.arange(300) * 0.05) * 3.0
    assert_allclose(
        run(BallScrewPlant(base), u), run(BallScrewPlant(slow), u), rtol=1e-9, atol=1e-15
    )


def test_current_saturation() -> None:
    params = BallScrewParams(current_limit_A=5.0)
    a = run(BallScrewPlant(params), np.full(50, 500.0))
    b = run(BallScrewPlant(params), np.full(50, 5.0))
    assert_allclose(a, b, rtol=0, atol=0)
    assert BallScrewPlant(params).step(-80.0).motor_torque_Nm == pytest.approx(-5.0 * KT)


def test_coulomb_and_viscous_terminal_velocity() -> None:
    # K_T i = (D + b) w + T_c  at the terminal velocity (tanh saturated).
    fr = FrictionParams(coulomb_Nm=0.5, viscous_Nms_per_rad=0.05)
    params = BallScrewParams(friction=fr, sim_step_s=100e-6)
    plant = BallScrewPlant(params)
    out = None
    for _ in range(1500):
        out = plant.step(2.0)
    assert out is not None
    expected = (KT * 2.0 - 0.5) / (D + 0.05)
    assert_allclose(out.velocity_rad_s, expected, rtol=1e-6)
    assert_allclose(out.friction_force_N * R, 0.5 + 0.05 * expected, rtol=1e-5)


def test_sinusoidal_disturbance_steady_state_amplitude() -> None:
    f = 2.0
    params = BallScrewParams(disturbance=DisturbanceParams(amplitude_Nm=0.3, frequency_hz=f))
    plant = BallScrewPlant(params)
    vel = np.array([plant.step(0.0).velocity_rad_s for _ in range(3000)])
    amplitude = 0.5 * (vel[-500:].max() - vel[-500:].min())
    expected = 0.3 / abs(1j * 2 * math.pi * f * J + D)
    assert_allclose(amplitude, expected, rtol=2e-3)


def test_maxwell_slip_virgin_curve_and_reversal() -> None:
    tc, width, n = 3.2, 5e-3, 10
    ms = MaxwellSlip(coulomb_Nm=tc, width_rad=width, elements=n)
    # Virgin curve: linear to the first break-away, T_c beyond the width.
    first = width / n
    deltas = width * np.arange(1, n + 1) / n
    assert_allclose(ms.move(0.5 * first), 0.5 * first * np.sum(tc / n / deltas), rtol=1e-12)
    ms.reset()
    assert_allclose(ms.move(2 * width), tc, rtol=1e-12)
    # Masing: after a reversal from full sliding, -T_c is reached after 2 * width.
    assert ms.move(-1.999 * width) > -tc
    assert_allclose(ms.move(-0.001 * width), -tc, rtol=1e-12)
    # Reversal curve is the virgin curve stretched by 2: T(-d) = T_c - 2 T_v(d / 2).
    fresh = MaxwellSlip(coulomb_Nm=tc, width_rad=width, elements=n)
    ms.move(4 * width)  # back to +T_c sliding
    for d in np.linspace(0.1, 1.8, 7) * width:
        probe = MaxwellSlip(coulomb_Nm=tc, width_rad=width, elements=n)
        probe.move(3 * width)
        fresh.reset()
        assert_allclose(probe.move(-d), tc - 2 * fresh.move(d / 2), rtol=1e-12, atol=1e-12)


def test_maxwell_slip_keeps_its_elements_where_it_is_told() -> None:
    # A plant hands a view of its one work array: the set fills it and steps in it,
    # exactly as in an array of its own.
    work = np.full(2 + 3 * 5, 7.0)
    view = work[2:].reshape(3, 5)
    shared = MaxwellSlip(coulomb_Nm=2.0, width_rad=1e-3, elements=5, storage=view)
    own = MaxwellSlip(coulomb_Nm=2.0, width_rad=1e-3, elements=5)
    assert np.shares_memory(shared.packed(), work)
    assert shared.packed().tobytes() == own.packed().tobytes()
    for d in (4e-4, -1.5e-3, 2e-4):
        assert shared.move(d) == own.move(d)
    assert work[2:].tobytes() == own.packed().tobytes()
    assert work[:2].tolist() == [7.0, 7.0]
    for bad in (np.zeros((3, 4)), np.zeros((3, 5), dtype=np.float32), np.zeros((5, 3)).T):
        with pytest.raises(ConfigError, match="storage: expected a C-contiguous float64 array"):
            MaxwellSlip(coulomb_Nm=2.0, width_rad=1e-3, elements=5, storage=bad)


def test_maxwell_slip_is_rate_independent_with_nonlocal_memory() -> None:
    tc, width = 1.0, 1e-3
    path = [0.0, 3e-3, 1e-3, 1.6e-3, 1.2e-3, 1.6e-3, 0.5e-3]
    results = []
    for steps in (1, 7, 101):
        ms = MaxwellSlip(coulomb_Nm=tc, width_rad=width, elements=12)
        torques = []
        for a, b in itertools.pairwise(path):
            for _ in range(steps):
                torque = ms.move((b - a) / steps)
            torques.append(torque)
        results.append(torques)
    assert_allclose(results[0], results[1], rtol=1e-12)
    assert_allclose(results[0], results[2], rtol=1e-12)
    # Closing the inner loop 1.2 -> 1.6 mm returns to the outer curve: the
    # torque at 1.6 mm is the same before and after the inner excursion.
    assert_allclose(results[0][2], results[0][4], rtol=1e-12)


def test_sensor_quantisation_and_seeded_noise() -> None:
    enc = PositionSensor(SensorParams(resolution=5.99e-6))
    for value in (0.0, 1.234567e-3, -7.77e-4):
        reading = enc.measure(value)
        assert abs(reading - value) <= 0.5 * 5.99e-6 + 1e-18
        assert_allclose(reading / 5.99e-6, round(reading / 5.99e-6), atol=1e-9)
    a = PositionSensor(SensorParams(noise_std=1e-6), rng=np.random.default_rng(7))
    b = PositionSensor(SensorParams(noise_std=1e-6), rng=np.random.default_rng(7))
    ra = [a.measure(0.0) for _ in range(1000)]
    assert ra == [b.measure(0.0) for _ in range(1000)]
    assert_allclose(np.std(ra), 1e-6, rtol=0.1)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("inertia_kgm2", -1.0),
        ("sim_step_s", 3e-4),  # does not divide 1 ms
        ("dead_time_s", 75e-6),  # not a multiple of 50 us
        ("current_limit_A", 0.0),
        ("torque_constant_Nm_per_A", float("nan")),
    ],
)
def test_invalid_params_name_the_field(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=field):
        BallScrewParams(**{field: value})


def test_nan_current_rejected() -> None:
    with pytest.raises(SignalError, match="current_A"):
        BallScrewPlant(BallScrewParams()).step(float("nan"))


def test_friction_path_matches_brute_force_substep_integration() -> None:
    """Rigid body + friction stepped per substep, modes per period == a plain
    8-state substep loop written here from scipy's matrix exponential."""
    import scipy.linalg

    fr = FrictionParams(rolling_coulomb_Nm=3.2, presliding_width_m=10e-6, elements=6)
    params = BallScrewParams(
        modes=BALL_SCREW_MODES, sim_step_s=10e-6, dead_time_s=70e-6, friction=fr
    )
    n_sub, delay = 100, 7
    a = np.zeros((8, 8))
    b = np.zeros(8)
    a[0, 1], a[1, 1], b[1] = 1.0, -D / J, KT / J
    for i, (f_hz, zeta, gain) in enumerate(BALL_SCREW_MODES):
        w, p = 2 * math.pi * f_hz, 2 + 2 * i
        a[p, p + 1], a[p + 1, p], a[p + 1, p + 1], b[p + 1] = (
            1.0,
            -w * w,
            -2 * zeta * w,
            gain * KT / J,
        )
    m = np.zeros((9, 9))
    m[:8, :8], m[:8, 8] = a * 10e-6, b * 10e-6
    e = scipy.linalg.expm(m)
    ad, bd = e[:8, :8], e[:8, 8]
    ms = MaxwellSlip(coulomb_Nm=3.2, width_rad=10e-6 / R, elements=6)
    u = 6.0 * np.sin(np.arange(400) * 2 * math.pi / 100)  # reversals every 50 ms
    held = np.repeat(u, n_sub)
    delayed = np.concatenate((np.zeros(delay), held[:-delay]))
    x = np.zeros(8)
    prev = 0.0
    expected = []
    for j, cur in enumerate(delayed):
        torque = ms.move(x[0] - prev)
        prev = x[0]
        x = ad @ x + bd * (cur - torque / KT)
        if (j + 1) % n_sub == 0:
            expected.append(x[0] + x[2] + x[4] + x[6])
    ours = run(BallScrewPlant(params), u)
    assert_allclose(ours, expected, rtol=1e-9, atol=1e-12)
    # Friction visibly shapes the motion (compare with no friction).
    free = run(BallScrewPlant(replace(params, friction=FrictionParams())), u)
    assert np.max(np.abs(free - ours)) > 1e-3
