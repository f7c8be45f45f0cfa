"""The identification numerics (core/identification/offline): signals, the closed-loop estimator, models, fits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.signal import cont2discrete, dlsim

from servo_axis.core.errors import ConfigError
from servo_axis.core.friction.maxwell_slip import MaxwellSlip
from servo_axis.core.identification.offline import fit as sysfit
from servo_axis.core.identification.offline import friction_fit
from servo_axis.core.identification.offline.excitation import Excitation
from servo_axis.core.identification.offline.frf import closed_loop_frf, remove_trend
from servo_axis.core.identification.offline.models import rigid_modes, sampled_response, two_inertia

T = 1e-3


def _exc(**kw: object) -> Excitation:
    base: dict[str, object] = {
        "amplitude_Nm": 2.0,
        "min_frequency_hz": 5.0,
        "max_frequency_hz": 200.0,
        "period_samples": 500,
        "control_period_s": T,
    }
    base.update(kw)
    return Excitation(**base)  # type: ignore[arg-type]


@pytest.mark.parametrize("signal", ["multisine", "chirp", "prbs"])
def test_signals_are_periodic_with_the_peak_amplitude(signal: str) -> None:
    exc = _exc(signal=signal, periods=2, settle_periods=1, start_step=30)
    k = np.arange(0, 30 + 3 * 500 + 40)
    x = exc.torque_Nm(k)
    assert_allclose(np.abs(x).max(), 2.0, rtol=1e-12)
    assert np.all(x[:30] == 0.0) and np.all(x[30 + 1500 :] == 0.0)
    assert_allclose(x[30:530], x[530:1030], rtol=0, atol=0)
    assert exc.window == (530, 1530)


def test_multisine_puts_its_power_on_the_band_lines_only() -> None:
    exc = _exc()
    spec = np.abs(np.fft.rfft(exc.one_period()))
    band = np.zeros(spec.size, dtype=bool)
    band[exc.lines] = True
    assert_allclose(exc.frequency_hz[[0, -1]], [6.0, 200.0])  # lines 2 Hz apart
    assert spec[~band].max() < 1e-9 * spec[band].min()
    # Flat amplitude spectrum, Schroeder phases: a crest factor well below sqrt(2 M).
    assert_allclose(spec[band] / spec[band].mean(), 1.0, rtol=1e-9)
    x = exc.one_period()
    assert x.max() / np.sqrt(np.mean(x**2)) < 2.0


def test_excitation_refuses_a_band_beyond_nyquist() -> None:
    with pytest.raises(ConfigError, match="max_frequency_hz"):
        _exc(max_frequency_hz=600.0)
    with pytest.raises(ConfigError, match="period_samples"):
        _exc(min_frequency_hz=0.1, max_frequency_hz=0.5, period_samples=100)


def test_sampled_response_matches_scipy_zoh() -> None:
    a, b, c = rigid_modes(inertia_kgm2=0.01, damping_Nms_per_rad=0.1, modes=((150.0, 0.05, 0.3),))
    f = np.array([3.0, 40.0, 149.0, 310.0])
    z = np.exp(2j * math.pi * f * T)
    ad, bd, cd, _, _ = cont2discrete((a, b, c, np.zeros((1, 1))), T, method="zoh")
    expect = np.array([(cd @ np.linalg.solve(zi * np.eye(4) - ad, bd))[0, 0] for zi in z])
    got = sampled_response(a, b, c, frequency_hz=f, control_period_s=T)[0]
    assert_allclose(got, expect, rtol=1e-10)
    # Whole samples of dead time: z^-m.
    delayed = sampled_response(a, b, c, frequency_hz=f, control_period_s=T, dead_time_s=2 * T)[0]
    assert_allclose(delayed, expect * z**-2, rtol=1e-9)


def test_fractional_dead_time_reproduces_the_held_input_in_time() -> None:
    """The sampled response with a fractional dead time against a fine simulation.

    A periodic input held over each period and delayed by 1.37 periods,
    simulated exactly on a grid of T / 100 (the held, delayed input is
    constant on it: the zero-order hold of that grid is exact), sampled; in
    the steady state the DFT ratio at each line is the sampled response.
    """
    w, zeta = 2 * math.pi * 90.0, 0.3  # a stable second-order system: no drift to leak
    a = np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]])
    b = np.array([[0.0], [w * w]])
    c = np.array([[1.0, 0.0]])
    td, fine, period = 1.37e-3, 100, 100
    shift = round(td / (T / fine))
    up = np.tile(np.random.default_rng(3).standard_normal(period), 12)
    held = np.repeat(up, fine)
    held = np.concatenate([np.zeros(shift), held[:-shift]])
    ad, bd, cd, dd, _ = cont2discrete((a, b, c, np.zeros((1, 1))), T / fine, method="zoh")
    _, yp = dlsim((ad, bd, cd, dd, T / fine), held)[:2]
    ys = yp[::fine, 0][-period:]
    us = up[-period:]
    lines = np.arange(1, 50)
    ratio = np.fft.rfft(ys)[lines] / np.fft.rfft(us)[lines]
    model = sampled_response(
        a, b, c, frequency_hz=lines / (period * T), control_period_s=T, dead_time_s=td
    )[0]
    # What is left of the transient after 11 periods: e^(-zeta w 1.1 s), nothing.
    assert_allclose(model, ratio, rtol=1e-8)


def _loop(noise_std: float, seed: int = 0) -> tuple[Excitation, np.ndarray, np.ndarray, np.ndarray]:
    """A discrete plant P = 0.5 z^-1 / (1 - 0.6 z^-1) in a loop u = d - K y with output noise."""
    exc = _exc(periods=64, settle_periods=1, max_frequency_hz=400.0, amplitude_Nm=1.0)
    steps = exc.stop_step
    d = exc.torque_Nm(np.arange(steps))
    rng = np.random.default_rng(seed)
    v = noise_std * rng.standard_normal(steps)
    x, gain = 0.0, 0.8
    u = np.empty(steps)
    y = np.empty(steps)
    for k in range(steps):
        y[k] = x + v[k]
        u[k] = d[k] - gain * y[k]
        x = 0.6 * x + 0.5 * u[k]
    first, stop = exc.window
    return exc, d[first:stop], u[first:stop], y[first:stop]


def _true(f: np.ndarray) -> np.ndarray:
    z = np.exp(2j * math.pi * f * T)
    return 0.5 / (z - 0.6)


def test_closed_loop_estimate_is_the_plant_and_the_direct_one_is_not() -> None:
    exc, d, u, y = _loop(noise_std=0.3)
    frf = closed_loop_frf(
        excitation=d,
        plant_input=u,
        output=y,
        period_samples=exc.period_samples,
        lines=exc.lines,
        control_period_s=T,
    )
    p = _true(frf.frequency_hz)
    err = np.abs(frf.response - p)
    # Within the estimator's own uncertainty (a 4-sigma band on every line) ...
    assert np.all(err < 4.0 * frf.std)
    # ... and its uncertainty is what the spread of independent repetitions is.
    reps = []
    for seed in range(1, 13):
        e2, d2, u2, y2 = _loop(noise_std=0.3, seed=seed)
        reps.append(
            closed_loop_frf(
                excitation=d2,
                plant_input=u2,
                output=y2,
                period_samples=e2.period_samples,
                lines=e2.lines,
                control_period_s=T,
            ).response
        )
    spread = np.sqrt(np.mean(np.abs(np.array(reps) - p) ** 2, axis=0))
    assert_allclose(np.median(frf.std / spread), 1.0, rtol=0.25)
    # The direct estimate S_uy / S_uu goes towards -1/K where the noise feeds back.
    big_u = np.fft.rfft(u.reshape(-1, exc.period_samples), axis=1)[:, exc.lines]
    big_y = np.fft.rfft(y.reshape(-1, exc.period_samples), axis=1)[:, exc.lines]
    direct = (np.conj(big_u) * big_y).mean(0) / (np.abs(big_u) ** 2).mean(0)
    assert np.median(np.abs(direct - p) / np.abs(p)) > 3 * np.median(err / np.abs(p))


def test_noise_free_loop_gives_the_plant_exactly_with_coherence_one() -> None:
    exc, d, u, y = _loop(noise_std=0.0)
    frf = closed_loop_frf(
        excitation=d,
        plant_input=u,
        output=y,
        period_samples=exc.period_samples,
        lines=exc.lines,
        control_period_s=T,
    )
    assert_allclose(frf.response, _true(frf.frequency_hz), rtol=1e-9)
    assert_allclose(frf.coherence, 1.0, atol=1e-9)
    # The sensitivity seen by d: 1 / (1 + K P).
    assert_allclose(frf.sensitivity, 1.0 / (1.0 + 0.8 * _true(frf.frequency_hz)), rtol=1e-9)


def test_trend_removal_keeps_the_periodic_part() -> None:
    period, count = 64, 5
    rng = np.random.default_rng(4)
    periodic = np.tile(rng.standard_normal(period), count)
    t = np.linspace(-1, 1, period * count)
    drift = 3.0 + 2.0 * t - 0.7 * t**2 + 0.2 * t**3
    cleaned = remove_trend(periodic + drift, period, count, 3)
    # What is left is the periodic part plus a constant (the constant is periodic too).
    assert_allclose(cleaned - cleaned.mean(), periodic - periodic.mean(), atol=1e-10)


def test_rigid_modes_fit_recovers_keys_from_a_noisy_response() -> None:
    true = {
        "inertia_kgm2": 0.013,
        "damping_Nms_per_rad": 0.08,
        "modes.frequency_hz[0]": 160.0,
        "modes.zeta[0]": 0.04,
        "modes.a[0]": 0.3,
        "dead_time_s": 1.3e-4,
    }
    t = 5e-4
    f = np.arange(2.0, 451.0)
    p = sysfit.rigid_modes_response(true, f, modes=1, control_period_s=t)
    rng = np.random.default_rng(5)
    rel = 0.01
    noisy = p * (
        1 + rel * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)) / math.sqrt(2)
    )
    from servo_axis.core.identification.offline.frf import FrequencyResponse

    frf = FrequencyResponse(f, noisy, np.ones(f.size), rel * np.abs(p), np.ones(f.size, complex), 4)
    fit = sysfit.fit_rigid_modes(frf, control_period_s=t)
    for key, value in true.items():
        assert_allclose(fit.value(key), value, rtol=0.02, err_msg=key)
        # The standard error covers the error (4 sigma) and is not absurdly wide.
        assert abs(fit.value(key) - value) < 4 * fit.error(key) + 1e-12, key
        assert fit.error(key) < 0.02 * abs(value), key
    assert_allclose(fit.rms_residual, 1.0, rtol=0.15)


def test_two_inertia_fit_recovers_keys() -> None:
    r, t = 1.91e-3, 5e-4
    true = {
        "motor_inertia_kgm2": 1.7e-3,
        "motor_damping_Nms_per_rad": 0.03,
        "table_mass_kg": 250.0,
        "table_damping_Ns_per_m": 9e3,
        "stiffness_N_per_m": 1.4e8,
        "screw_damping_Ns_per_m": 1.5e4,
        "current_bandwidth_hz": 900.0,
    }
    f = np.arange(2.0, 451.0)
    both = sysfit.two_inertia_response(true, f, lead_m_per_rad=r, control_period_s=t)
    from servo_axis.core.identification.offline.frf import FrequencyResponse

    data = [
        FrequencyResponse(
            f, both[i], np.ones(f.size), 1e-3 * np.abs(both[i]), np.ones(f.size, complex), 4
        )
        for i in range(2)
    ]
    fit = sysfit.fit_two_inertia(data[0], data[1], lead_m_per_rad=r, control_period_s=t)
    for key, value in true.items():
        assert_allclose(fit.value(key), value, rtol=1e-4, err_msg=key)


def test_two_inertia_without_a_mode_in_the_band_is_refused() -> None:
    r, t = 1.91e-3, 5e-4
    a, b, c = two_inertia(
        motor_inertia_kgm2=1.7e-3,
        motor_damping_Nms_per_rad=0.03,
        table_mass_kg=250.0,
        table_damping_Ns_per_m=9e3,
        stiffness_N_per_m=1.4e8,
        screw_damping_Ns_per_m=1.5e4,
        lead_m_per_rad=r,
        current_bandwidth_hz=0.0,
    )
    f = np.arange(2.0, 60.0)
    resp = sampled_response(a, b, c, frequency_hz=f, control_period_s=t)
    from servo_axis.core.identification.offline.frf import FrequencyResponse

    data = [
        FrequencyResponse(
            f, resp[i], np.ones(f.size), 1e-3 * np.abs(resp[i]), np.ones(f.size, complex), 4
        )
        for i in range(2)
    ]
    with pytest.raises(
        sysfit.IdentificationError, match="stiffness_N_per_m: expected the axial mode"
    ):
        sysfit.fit_two_inertia(data[0], data[1], lead_m_per_rad=r, control_period_s=t)


def test_maxwell_slip_fit_recovers_level_and_width() -> None:
    r = 1.91e-3
    k = np.arange(6000)
    angle = (50e-6 - 50e-6 * np.cos(2 * math.pi * 0.2 * k * 1e-3)) / r
    direction = np.sign(np.gradient(angle))
    ms = MaxwellSlip(coulomb_Nm=2.0, width_rad=9e-6 / r, elements=8)
    torque = np.array([ms.move(d) for d in np.diff(angle, prepend=angle[0])]) + 0.3 * direction
    torque = torque + 0.01 * np.random.default_rng(6).standard_normal(k.size)
    fit = friction_fit.fit_maxwell_slip(
        angle_rad=[angle], direction=[direction], torque_Nm=[torque], lead_m_per_rad=r, elements=8
    )
    assert_allclose(fit.values, [2.0, 9e-6, 0.3], rtol=0.01)
    assert np.all(np.abs(fit.values - [2.0, 9e-6, 0.3]) < 5 * fit.std)
