"""RPTC learning filters and the periodic signal generator (paper 000, Sect. III-IV)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError, TableError
from servo_axis.core.learning.filters import (
    circular_filter,
    convergence_measure,
    modelling_error_and_sensitivity,
    n_times_gain,
    n_times_taps,
    q_filter_taps,
    q_gain,
)
from servo_axis.core.learning.rptc import LearningParams, PeriodicSignalGenerator
from servo_axis.core.models.ball_screw import ball_screw_response
from servo_axis.storage import load_memory, save_memory


def centred_power(base: np.ndarray, m: int) -> np.ndarray:
    out = np.array([1.0])
    for _ in range(m):
        out = np.convolve(out, base)
    return out


@pytest.mark.parametrize("nq", [0, 1, 5, 20])
def test_q_is_the_binomial_zero_phase_filter_of_eq2(nq: int) -> None:
    taps = q_filter_taps(nq)
    assert_allclose(taps, centred_power(np.array([0.25, 0.5, 0.25]), nq), rtol=1e-12)
    assert_allclose(taps, taps[::-1], rtol=0)  # symmetric: zero phase
    assert_allclose(taps.sum(), 1.0, rtol=1e-14)  # DC gain 1


@pytest.mark.parametrize(("nq", "n"), [(20, 1), (20, 3), (20, 5), (10, 4), (3, 2)])
def test_n_times_filter_is_the_binomial_sum_of_eq19(nq: int, n: int) -> None:
    q = q_filter_taps(nq)
    half = n * nq
    expected = np.zeros(2 * half + 1)
    for m in range(1, n + 1):
        qm = centred_power(q, m)  # half-length m nq
        pad = half - m * nq
        expected[pad : pad + len(qm)] += math.comb(n, m) * (-1) ** (m + 1) * qm
    taps = n_times_taps(nq, n)
    assert len(taps) == 2 * half + 1
    assert_allclose(taps, expected, atol=1e-12)
    assert_allclose(taps.sum(), 1.0, rtol=1e-12)
    assert_allclose(taps, taps[::-1], atol=1e-15)


def test_gain_curves_match_the_taps_and_are_zero_phase() -> None:
    period = 2e-3
    f = np.linspace(0, 250, 501)
    for nq, n in ((20, 1), (20, 5), (1, 1)):
        taps = n_times_taps(nq, n)
        k = np.arange(len(taps)) - (len(taps) - 1) // 2
        response = (taps[None, :] * np.exp(-2j * np.pi * f[:, None] * period * k[None, :])).sum(
            axis=1
        )
        assert_allclose(response.imag, 0.0, atol=1e-12)
        assert_allclose(response.real, n_times_gain(f, nq=nq, n=n, period_s=period), atol=1e-12)
    assert_allclose(q_gain(0.0, nq=20, period_s=period), 1.0)
    # Sharper roll-off (000 Fig. 11): Q~5 keeps more of the pass band than Q at equal Nq.
    assert n_times_gain(10.0, nq=20, n=5, period_s=period) > q_gain(10.0, nq=20, period_s=period)


def lifted_errors(e1: np.ndarray, params: LearningParams, cycles: int) -> list[np.ndarray]:
    """With Delta = 0, S P (P_n^-1 + C) = I: e_j = e_1 - c_j (eq. (9))."""
    psg = PeriodicSignalGenerator(params)
    errors = [e1]
    for _ in range(cycles):
        psg.learn(errors[-1])
        errors.append(e1 - psg.correction)
    return errors


def test_n_times_learning_converges_n_times_faster_eq27() -> None:
    nd, nq, n = 250, 20, 3
    t = np.arange(nd) / nd
    rng = np.random.default_rng(1)
    e1 = (
        np.sin(2 * np.pi * 2 * t)
        + 0.3 * np.sin(2 * np.pi * 37 * t)
        + 0.05 * rng.standard_normal(nd)
    )
    with_q = lifted_errors(e1, LearningParams(samples_per_cycle=nd, nq=nq, n=1), 3 * n)
    with_qn = lifted_errors(e1, LearningParams(samples_per_cycle=nd, nq=nq, n=n), 3)
    for j in range(1, 4):
        assert_allclose(with_qn[j], with_q[j * n], atol=1e-12 * np.max(np.abs(e1)))
    # Independent check: (I - Q)^(jn) e_1 with the circulant matrix of Q.
    col = np.zeros(nd)
    taps = q_filter_taps(nq)
    for k, c in enumerate(taps):
        col[(k - nq) % nd] += c
    q_mat = scipy.linalg.circulant(col)
    expected = np.linalg.matrix_power(np.eye(nd) - q_mat, 2 * n) @ e1
    assert_allclose(with_qn[2], expected, atol=1e-10 * np.max(np.abs(e1)))
    # Learning removes what Q passes: the 2-per-cycle harmonic (8 Hz at
    # T_r = 2 ms) is gone, the 37th (74 Hz, |Q| = 0.011) is nearly untouched.
    first, last = np.abs(np.fft.rfft(e1)), np.abs(np.fft.rfft(with_qn[3]))
    assert last[2] < 1e-6 * first[2]
    assert last[37] > 0.9 * first[37]


def test_eq29_constraint_and_bad_memory_are_rejected() -> None:
    with pytest.raises(ConfigError, match=r"n, nq: eq\. \(29\)"):
        LearningParams(samples_per_cycle=100, nq=20, n=5)  # 5 * 20 + 2 >= 100
    LearningParams(samples_per_cycle=103, nq=20, n=5)
    psg = PeriodicSignalGenerator(LearningParams(samples_per_cycle=10, nq=1, n=2))
    with pytest.raises(SignalError, match="Nd"):
        psg.learn(np.zeros(9))
    with pytest.raises(SignalError, match="finite"):
        psg.learn(np.full(10, math.nan))
    with pytest.raises(SignalError, match="Nd"):
        psg.load(np.zeros(11), 3)


def test_state_variable_generator_central_difference() -> None:
    nd, tr = 200, 2e-3
    psg = PeriodicSignalGenerator(LearningParams(samples_per_cycle=nd, nq=0, n=1, period_s=tr))
    w = 2 * np.pi / (nd * tr)
    c = 1e-3 * np.sin(w * np.arange(nd) * tr)
    psg.learn(c)  # nq = 0: Q = I, the correction is the error itself
    pos, vel = psg.states()
    assert_allclose(pos, c, rtol=1e-15)
    # Central difference of a sine: w cos(w t) * sin(w T) / (w T), exactly.
    exact = 1e-3 * w * np.cos(w * np.arange(nd) * tr) * np.sin(w * tr) / (w * tr)
    assert_allclose(vel, exact, atol=1e-12)


def test_circular_filter_and_convergence_measure() -> None:
    x = np.zeros(8)
    x[0] = 1.0
    assert_allclose(circular_filter(x, [0.25, 0.5, 0.25]), [0.5, 0.25, 0, 0, 0, 0, 0, 0.25])
    assert convergence_measure([0.5], [1.0], [0.5]) == pytest.approx(0.25)
    f = np.linspace(0, 250, 100)
    q = n_times_gain(f, nq=20, n=5, period_s=2e-3)
    assert convergence_measure(q, np.ones_like(f), np.zeros_like(f)) <= 1.0 + 1e-15


def test_memory_file_round_trip_and_every_kind_of_bad_file(tmp_path: Path) -> None:
    params = LearningParams(samples_per_cycle=50, nq=2, n=3)
    psg = PeriodicSignalGenerator(params)
    rng = np.random.default_rng(5)
    for _ in range(2):
        psg.learn(rng.standard_normal(50))
    path = tmp_path / "memory.json"
    save_memory(path, psg, scenario="rptc_detailed")
    resumed = PeriodicSignalGenerator(params)
    resumed.load_state(load_memory(path, resumed, scenario="rptc_detailed"))
    assert resumed.correction.tolist() == psg.correction.tolist()  # exact
    assert resumed.cycles_learned == 2
    good = path.read_text()
    cases = {
        "truncated": good[: len(good) // 2],
        "garbage": "\x00\x01not json",
        "edited": good.replace(
            repr(float(psg.correction[3])), repr(float(psg.correction[3]) + 1e-9)
        ),
    }
    for name, text in cases.items():
        assert text != good
        path.write_text(text)
        with pytest.raises(TableError, match=r"memory\.json") as err:
            load_memory(path, PeriodicSignalGenerator(params), scenario="rptc_detailed")
        assert name != "edited" or "checksum" in str(err.value)
    path.write_text(good)
    with pytest.raises(TableError, match="scenario"):
        load_memory(path, PeriodicSignalGenerator(params), scenario="rptc_ideal")
    with pytest.raises(TableError, match="samples_per_cycle"):
        load_memory(
            path,
            PeriodicSignalGenerator(LearningParams(samples_per_cycle=60, nq=2, n=3)),
            scenario="rptc_detailed",
        )
    with pytest.raises(TableError, match="n is 3"):
        load_memory(
            path,
            PeriodicSignalGenerator(LearningParams(samples_per_cycle=50, nq=2, n=1)),
            scenario="rptc_detailed",
        )


def test_modelling_error_of_eq30_and_the_convergence_condition() -> None:
    from servo_axis.core.feedback.pid import design_pid_pole_placement
    from servo_axis.core.models.ball_screw import BALL_SCREW_MODES

    nominal = {"torque_constant_Nm_per_A": 0.715, "inertia_kgm2": 0.01, "damping_Nms_per_rad": 0.1}
    f = np.linspace(0.1, 249.0, 2000)
    p = ball_screw_response(f, modes=BALL_SCREW_MODES, dead_time_s=70e-6, **nominal)
    pn = ball_screw_response(f, **nominal)
    s = 2j * np.pi * f
    assert_allclose(pn, 0.715 / (0.01 * s**2 + 0.1 * s), rtol=1e-12)
    gains = design_pid_pole_placement(bandwidth_hz=45.0, **nominal)
    num, den = gains.transfer_function()
    c = np.polyval(num, s) / np.polyval(den, s)
    delta, sens = modelling_error_and_sensitivity(f, plant=p, nominal=pn, controller=c)
    # Low frequency: the rigid body dominates, Delta -> 0; near the 180 Hz
    # mode the error is large (000 Fig. 14).
    assert abs(delta[0]) < 1e-3
    assert np.max(np.abs(delta[(f > 170) & (f < 190)])) > 1.0
    assert_allclose(sens, 1 / (1 + pn * c), rtol=1e-12)
    q = q_gain(f, nq=20, period_s=2e-3)
    q5 = n_times_gain(f, nq=20, n=5, period_s=2e-3)
    # Condition (15)/(21): with the roll-off of Q (Nq = 20) and of Q~5 no
    # frequency grows from cycle to cycle (the sup is 1 where Q -> 0);
    # learning without a filter (Q = I) diverges at the resonance.
    assert convergence_measure(q, sens, delta) <= 1.0 + 1e-9
    assert convergence_measure(q5, sens, delta) <= 1.0 + 1e-9
    assert convergence_measure(np.ones_like(f), sens, delta) > 1.5
