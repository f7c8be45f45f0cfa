"""Standard ILC of paper 001: process sensitivity, ZPETC, Q, eq. (6)/(7), the S-ILC law.

The loop is simulated here independently of the module: the plant is
discretised by scipy, the PID runs as DiscretePid, and the lifted
matrices of S and S P are Toeplitz matrices of the simulated impulse
responses.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
from typing import Any

import numpy as np
import pytest
import scipy.linalg
import scipy.signal
from ilc_support import (
    KT,
    LEAD,
    NOMINAL,
    PERIOD_S,
    PID,
    TRUE_PLANT,
    RunningLoop,
    lifted,
    loop_responses,
    min_jerk,
    paper_params,
    q_matrix,
)
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.feedback.pid import design_pid_pole_placement
from servo_axis.core.learning.base import decode_memory, encode_memory
from servo_axis.core.learning.filters import q_filter_taps
from servo_axis.core.learning.ilc import (
    IlcParams,
    StandardIlc,
    Zpetc,
    convergence_gain,
    convergence_measure,
    learning_filter,
    process_sensitivity,
    process_sensitivity_response,
    trial_q,
)
from servo_axis.core.models.base import NominalModel


def dtft(h: np.ndarray, freq_hz: np.ndarray) -> np.ndarray:
    k = np.arange(len(h))
    return np.exp(-2j * np.pi * freq_hz[:, None] * PERIOD_S * k[None, :]) @ h


# -- process sensitivity and ZPETC ----------------------------------------------------


def test_process_sensitivity_is_the_simulated_loop() -> None:
    params = paper_params(64, nq=4)
    for plant in (None, TRUE_PLANT):
        num, den = process_sensitivity(params, plant=plant)
        _, h_sp = loop_responses(plant or NOMINAL, PID, 400)
        impulse = np.zeros(400)
        impulse[0] = 1.0
        got = scipy.signal.lfilter(num, den, impulse)
        assert_allclose(got, h_sp, atol=1e-9 * np.max(np.abs(h_sp)))
        f = np.array([1.0, 10.0, 100.0, 400.0])
        assert_allclose(
            process_sensitivity_response(f, params=params, plant=plant),
            dtft(h_sp, f),
            rtol=1e-6,
        )


def test_zpetc_of_the_nominal_loop_is_zero_phase_with_unit_low_frequency_gain() -> None:
    params = paper_params(64, nq=4)
    _, h_sp = loop_responses(NOMINAL, PID, 3000)
    f = np.linspace(0.5, 0.8 * 500.0, 400)
    product = dtft(h_sp, f) * learning_filter(params).response(f)
    assert_allclose(np.angle(product), 0.0, atol=1e-6)
    low = f < 5.0
    assert_allclose(np.abs(product[low]), 1.0, atol=3e-4)
    assert np.all(np.abs(product) <= 1.0 + 1e-6)  # S_n P_n L <= 1: no amplification
    # The kept ZOH zero near -1 removes the gain at Nyquist instead of inverting it.
    assert np.abs(product[-1]) < np.abs(product[0])


def test_zpetc_with_every_zero_cancelled_is_an_exact_inverse() -> None:
    # G = z^-2 (1 - 0.5 z^-1)(1 + 0.3 z^-1) / ((1 - 0.8 z^-1)(1 - 0.2 z^-1)):
    # both zeros are acceptable (|z| < 0.98, Re z > -0.5).
    num = np.concatenate(([0.0, 0.0], 2.0 * np.convolve([1.0, -0.5], [1.0, 0.3])))
    den = np.convolve([1.0, -0.8], [1.0, -0.2])
    zpetc = Zpetc(num, den, period_s=PERIOD_S)
    assert zpetc.unacceptable_zeros.size == 0
    assert zpetc.preview == 2
    f = np.linspace(0.0, 500.0, 101)
    _, g = scipy.signal.freqz(num, den, worN=f, fs=1.0 / PERIOD_S)
    assert_allclose(g * zpetc.response(f), 1.0, atol=1e-12)
    u = np.random.default_rng(0).standard_normal(200)
    y = scipy.signal.lfilter(num, den, u)
    assert_allclose(zpetc.apply(y)[:-2], u[:-2], atol=1e-12)


def test_zpetc_applied_to_a_trial_matches_its_frequency_response() -> None:
    # An unstable zero (1.5), one near -1 (-0.9), one cancelled (0.4).
    num = np.concatenate(([0.0], np.poly([1.5, -0.9, 0.4])))
    den = np.poly([0.7, 0.5 + 0.3j, 0.5 - 0.3j]).real
    zpetc = Zpetc(num, den, period_s=PERIOD_S)
    assert_allclose(np.sort(zpetc.unacceptable_zeros.real), [-0.9, 1.5], atol=1e-12)
    f = np.array([0.0, 37.0, 180.0, 410.0])
    _, g = scipy.signal.freqz(num, den, worN=f, fs=1.0 / PERIOD_S)
    product = g * zpetc.response(f)
    assert_allclose(product.imag, 0.0, atol=1e-12)
    b_u = np.poly([1.5, -0.9])
    expected = np.abs(np.polyval(b_u[::-1], np.exp(-2j * np.pi * f * PERIOD_S))) ** 2
    assert_allclose(product.real, expected / np.sum(b_u) ** 2, rtol=1e-10)
    k = np.arange(2000)
    for freq, gain in zip(f[1:], zpetc.response(f[1:]), strict=True):
        x = np.cos(2 * np.pi * freq * PERIOD_S * k)
        y = zpetc.apply(x)
        mid = slice(500, 1500)  # transients of the cancelled zero 0.4 have decayed
        expected_y = np.abs(gain) * np.cos(2 * np.pi * freq * PERIOD_S * k + np.angle(gain))
        assert_allclose(y[mid], expected_y[mid], atol=1e-9 * np.abs(gain))


def test_l_inverts_the_nominal_process_sensitivity_at_low_frequency() -> None:
    n = 600
    params = paper_params(n)
    _, h_sp = loop_responses(NOMINAL, PID, n)
    u = 0.5 * np.exp(-(((np.arange(n) - 300.0) / 40.0) ** 2))  # a smooth current, A
    recovered = learning_filter(params).apply(lifted(h_sp) @ u)
    assert_allclose(recovered, u, atol=2e-3 * np.max(np.abs(u)))


# -- Q --------------------------------------------------------------------------------


def test_trial_q_is_the_symmetric_fir_with_end_value_extension() -> None:
    x = np.random.default_rng(1).standard_normal(60)
    for nq in (0, 3, 16):
        assert_allclose(trial_q(x, nq), q_matrix(60, nq) @ x, rtol=1e-12, atol=1e-14)
    assert_allclose(trial_q(np.full(40, 2.5), 16), 2.5, rtol=1e-13)  # constants pass


# -- convergence (eq. (6), (7)) ---------------------------------------------------------


def test_convergence_measure_on_the_paper_numbers() -> None:
    params = paper_params(1000, nq=16)
    nominal = convergence_measure(params=params)
    true = convergence_measure(params=params, plant=TRUE_PLANT)
    assert nominal < 1.0
    assert true < 1.0
    # Independent check of the true-plant curve away from DC: Q from the taps,
    # S P from the simulated loop, L from the module.
    f = np.linspace(1.0, 500.0, 300)
    _, h_sp = loop_responses(TRUE_PLANT, PID, 3000)
    taps = q_filter_taps(16)
    q = dtft(taps, f) * np.exp(2j * np.pi * f * PERIOD_S * 16)  # centred: zero phase
    expected = np.abs(q * (1.0 - dtft(h_sp, f) * learning_filter(params).response(f)))
    assert_allclose(
        convergence_gain(f, params=params, plant=TRUE_PLANT), expected, rtol=1e-6, atol=1e-9
    )
    assert np.max(expected) <= true + 1e-9


def test_small_nq_on_the_paper_numbers_and_a_refused_case() -> None:
    # With the nominal ZPETC |S_n P_n L| <= 1, so even Nq = 0 meets eq. (7) on
    # the paper's nominal model (barely: the ZOH zero is just inside -1).
    measure = convergence_measure(params=paper_params(1000, nq=0))
    assert 0.999 < measure < 1.0
    StandardIlc(paper_params(1000, nq=0))
    # Constructed violation: D_n = 0 puts the ZOH zero on z = -1, where
    # S_n P_n L = 0, so |Q(1 - S_n L P_n)| = 1 at Nyquist without Q.
    undamped = NominalModel(
        inertia_kgm2=0.015, damping_Nms_per_rad=0.0, torque_constant_Nm_per_A=KT
    )
    params = IlcParams(
        samples_per_trial=1000,
        nq=0,
        period_s=PERIOD_S,
        lead_m_per_rad=LEAD,
        nominal=undamped,
        pid=design_pid_pole_placement(bandwidth_hz=30.0, **undamped.as_kwargs()),
    )
    assert_allclose(convergence_measure(params=params), 1.0, atol=1e-12)
    with pytest.raises(
        ConfigError, match=r"nq: Nq = 0 gives max \|Q\(1 - S_n L P_n\)\| = 1 .*eq. \(7\)"
    ):
        StandardIlc(params)
    StandardIlc(dataclasses.replace(params, nq=1))  # Q removes Nyquist: accepted


def test_standard_ilc_on_a_linear_plant_follows_eq_6() -> None:
    n, nq = 700, 16
    params = paper_params(n, nq=nq)
    h_s, h_sp = loop_responses(TRUE_PLANT, PID, n)
    s, sp = lifted(h_s), lifted(h_sp)
    q = q_matrix(n, nq)
    # Out and back: every trial starts and ends at rest at 0 (001 Sect. III-A).
    r, _, _ = min_jerk(40, [(3e-3, 175), (-3e-3, 175)], 270)
    law = StandardIlc(params)
    zpetc = learning_filter(params)
    loop = RunningLoop(TRUE_PLANT)
    assert_allclose(law.next_correction(period=1)[0], 0.0, atol=0)  # trial 1: f = 0
    e = loop.trial(r, np.zeros(n))
    assert_allclose(e, s @ r, atol=1e-12)  # trial 1 starts from rest: eq. (4)
    errors, start = [e], 0.0
    for j in range(1, 7):
        (f_j,) = law.next_correction()
        law.learn(e, period=j)
        (f_next,) = law.next_correction()
        # eq. (3) on the input relative to the level the trial starts from
        assert_allclose(f_next - f_j[-1], q @ (f_j - start + zpetc.apply(e)), rtol=1e-9, atol=1e-12)
        e_next = loop.trial(r, f_next)
        # The running loop starts trial j + 1 from the equilibrium f_j[N-1]
        # left: eq. (4) of the relative input (the tail of 270 samples lets
        # the 30 Hz loop settle to 1e-8 of the error).
        assert_allclose(e_next, s @ r - sp @ (f_next - f_j[-1]), atol=1e-7 * np.max(np.abs(e)))
        # eq. (6) with d = 0: Q and the lifted S P commute up to the trial's
        # ends, where the signals are at rest.
        predicted = q @ (e - sp @ zpetc.apply(e)) + s @ r - q @ (s @ r)
        assert_allclose(e_next, predicted, atol=1e-4 * np.max(np.abs(e)))
        start = f_j[-1]
        e = e_next
        errors.append(e)
    # The limit of eq. (6): e_inf = (I - Q (I - S P L))^-1 (I - Q) S r.
    l_mat = np.column_stack([zpetc.apply(col) for col in np.eye(n)])
    e_inf = np.linalg.solve(np.eye(n) - q @ (np.eye(n) - sp @ l_mat), (np.eye(n) - q) @ s @ r)
    distance = [np.linalg.norm(x - e_inf) for x in errors]
    assert all(b < a for a, b in itertools.pairwise(distance))
    assert distance[-1] < 1e-3 * np.linalg.norm(e_inf)
    assert np.linalg.norm(errors[-1]) < 0.02 * np.linalg.norm(errors[0])


def test_standard_ilc_relearns_when_the_held_disturbance_flips() -> None:
    """The level mode of back-to-back trials (ilc module docstring), on a linear plant.

    Trials 1-5 hold an input disturbance of -h at rest (friction left by a
    move in -x); trial 6 flips it to +h at its middle (a reference whose
    last move is in +x); from trial 7 it is +h throughout. A constant
    disturbance from the equilibrium the last trial left is no disturbance,
    so the error must go back to the limit of eq. (6) it had before the
    flip, the learned input taking over the jump 2 h at rest. Eq. (3) on the
    absolute ``f`` instead keeps a level mode with eigenvalue -1: its input
    at the trial start alternates between two values 2 h apart, trial after
    trial, and the error never comes back.
    """
    n, nq, h = 700, 16, 3.2 / KT
    params = paper_params(n, nq=nq)
    zpetc = learning_filter(params)
    r, _, _ = min_jerk(40, [(3e-3, 175), (-3e-3, 175)], 270)

    def held(trial: int) -> np.ndarray:
        d = np.full(n, -h if trial < 6 else h)
        if trial == 6:
            d[: n // 2] = -h
        return d

    def run(law_update: Any) -> tuple[list[float], list[np.ndarray]]:
        loop = RunningLoop(TRUE_PLANT)
        loop.trial(np.zeros(n), np.zeros(n), np.full(n, -h))  # at rest, holding -h
        f, rms, inputs = np.zeros(n), [], []
        for j in range(1, 17):
            e = loop.trial(r, f, held(j))
            rms.append(float(np.sqrt(np.mean(e**2))))
            inputs.append(f)
            f = law_update(e)
        return rms, inputs

    law = StandardIlc(params)

    def fixed(e: np.ndarray) -> np.ndarray:
        law.learn(e)
        return law.next_correction()[0]

    absolute = [np.zeros(n)]

    def plain(e: np.ndarray) -> np.ndarray:
        absolute.append(trial_q(absolute[-1] + zpetc.apply(e), nq))
        return absolute[-1]

    rms, inputs = run(fixed)
    rms_plain, inputs_plain = run(plain)
    # Before the flip both are the same law (the starting levels are 0).
    assert_allclose(rms_plain[:6], rms[:6], rtol=1e-9)
    # The fixed law: back to the level of trial 5, the jump 2 h learned at rest.
    assert_allclose(rms[-1], rms[4], rtol=0.01)
    assert_allclose(inputs[-1][-1] - inputs[5][-1], 2.0 * h, rtol=0.01)
    for prev, nxt in itertools.pairwise(inputs[7:]):
        assert abs(nxt[0] - prev[-1]) < 1e-3 * h  # each trial starts where the last ended
    # Eq. (3) on the absolute f: the start level alternates by 2 h, the error stays.
    starts = np.array([f[0] for f in inputs_plain[8:]])
    assert_allclose(np.abs(np.diff(starts)), 2.0 * h, rtol=0.02)
    assert min(rms_plain[8:]) > 20.0 * rms[4]


# -- the law's interface ---------------------------------------------------------------


def test_bad_parameters_and_signals_are_refused_with_their_names() -> None:
    with pytest.raises(
        ConfigError, match=r"nq: Nq too large for the trial.*N = samples_per_trial = 40"
    ):
        paper_params(40, nq=10)
    with pytest.raises(ConfigError, match="samples_per_trial"):
        paper_params(7, nq=0)
    with pytest.raises(ConfigError, match="nq: expected an integer >= 0"):
        paper_params(100, nq=-1)
    law = StandardIlc(paper_params(100, nq=4))
    with pytest.raises(SignalError, match=r"error: expected 100 values .* got shape \(99,\)"):
        law.learn(np.zeros(99))
    bad = np.zeros(100)
    bad[3] = np.nan
    with pytest.raises(SignalError, match="error: expected finite values"):
        law.learn(bad)
    with pytest.raises(SignalError, match=r"feedforward_A: expected 100 values"):
        law.load_state({"feedforward_A": [0.0] * 101, "trials_learned": 1})
    with pytest.raises(SignalError, match="trials_learned"):
        law.load_state({"feedforward_A": [0.0] * 100, "trials_learned": -1})
    with pytest.raises(SignalError, match="start_level_A: expected a finite number"):
        law.load_state({"feedforward_A": [0.0] * 100, "trials_learned": 1})
    assert law.periods_learned == 0


def test_memory_round_trip_gives_the_same_correction() -> None:
    n = 200
    params = paper_params(n, nq=8)
    law = StandardIlc(params)
    rng = np.random.default_rng(2)
    for j in (1, 2):
        law.learn(1e-5 * rng.standard_normal(n), period=j)
    text = encode_memory(law, scenario="s")
    fresh = StandardIlc(params)
    fresh.load_state(json.loads(json.dumps(law.state())))
    assert np.array_equal(fresh.next_correction()[0], law.next_correction()[0])
    assert fresh.periods_learned == 2
    other = StandardIlc(paper_params(n, nq=8))
    other.load_state(decode_memory(text, other, scenario="s"))
    assert np.array_equal(other.next_correction()[0], law.next_correction()[0])
    assert law.identity()["law"] == "silc" and law.identity()["nq"] == 8


def test_a_memory_of_another_law_or_trial_length_is_refused_by_name() -> None:
    from servo_axis.core.errors import TableError

    law = StandardIlc(paper_params(200, nq=8))
    law.learn(np.full(200, 1e-6), period=1)
    text = encode_memory(law, scenario="s")
    longer = StandardIlc(paper_params(300, nq=8))
    with pytest.raises(TableError, match=r"memory: samples_per_trial is 200, this run has 300"):
        decode_memory(text, longer, scenario="s")
    other_nq = StandardIlc(paper_params(200, nq=6))
    with pytest.raises(TableError, match=r"memory: nq is 8, this run has 6"):
        decode_memory(text, other_nq, scenario="s")
    body = json.loads(text)
    body["law"] = "pilc_bfft"
    with pytest.raises(TableError, match=r"memory: law is 'pilc_bfft', this run has 'silc'"):
        decode_memory(json.dumps(body), law, scenario="s")
