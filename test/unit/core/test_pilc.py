"""Projection-based ILC of paper 001: basis, W, estimation, friction table, the two laws.

The closed loop is simulated here independently of the module (plant by
scipy, PID by DiscretePid, lifted Toeplitz matrices of the impulse
responses), as in test_ilc.py.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from ilc_support import (
    KT,
    LEAD,
    PERIOD_S,
    TRUE_PLANT,
    loop_matrices,
    min_jerk,
    paper_params,
    q_matrix,
)
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError, TableError
from servo_axis.core.feedback.pid import design_pid_pole_placement
from servo_axis.core.learning.base import decode_memory, encode_memory
from servo_axis.core.learning.ilc import (
    IlcParams,
    StandardIlc,
    learning_filter,
    process_sensitivity,
)
from servo_axis.core.learning.pilc import (
    LearnedFrictionTable,
    ProjectionIlc,
    ProjectionParams,
    basis,
    estimate_friction,
    estimate_parameters,
    friction_basis,
    reversal_displacement,
    reversal_state,
    weighting,
)
from servo_axis.core.models.base import NominalModel

TC_NM = 3.2  # Coulomb friction of 001 Sect. II-B
XS_M = 10e-6  # width of region 1 (Fig. 2)
N = 1200


REF1 = min_jerk(80, [(2e-3, 300), (-2e-3, 300)], 440)
REF2 = min_jerk(80, [(1e-3, 200), (-3e-3, 400), (2e-3, 250)], 110)


def curve_Nm(x_r: np.ndarray) -> np.ndarray:
    """A known rolling-friction curve normalised to the motion: -T_c at a reversal, -> +T_c."""
    return TC_NM * (1.0 - 2.0 * np.exp(-3.0 * x_r / XS_M))


def hand_reversal_case() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and x_r worked out by hand from the documented convention."""
    vel = np.array([0, 0, 1, 1, 0, 1, -1, -1, 0, -1, 1], dtype=float)
    pos = np.array([0, 0, 1, 3, 3, 4, 3, 1, 1, 0, 2], dtype=float) * 1e-6
    # rest: 0; first motion from pos[1] = 0; the rest at k = 4 keeps 3 and the
    # motion resumes forward (4); reversal at k = 6 from pos[5] = 4: 1, 3, rest
    # 3, 4; reversal at k = 10 from pos[9] = 0: 2.
    x_r = np.array([0, 0, 1, 3, 3, 4, 1, 3, 3, 4, 2], dtype=float) * 1e-6
    return pos, vel, x_r


# -- basis -----------------------------------------------------------------------------


def test_reversal_displacement_follows_the_convention() -> None:
    pos, vel, x_r = hand_reversal_case()
    assert_allclose(reversal_displacement(pos, vel), x_r, rtol=0, atol=1e-18)


def test_friction_basis_and_psi_of_eq_13_14() -> None:
    pos, vel, x_r = hand_reversal_case()
    x_mu = 5e-6
    # The direction is held through a rest; before the first move it is the
    # one the trial ends with (+1, the last move of the case).
    direction = np.array([1, 1, 1, 1, 1, 1, -1, -1, -1, -1, 1], dtype=float)
    assert_allclose(reversal_state(pos, vel)[1], direction, atol=0)
    expected = direction * np.minimum(2.0 * x_r / x_mu - 1.0, 1.0)
    b_rf = friction_basis(pos, vel, x_mu_m=x_mu)
    assert_allclose(b_rf, expected, atol=1e-12)
    # At the rest at k = 8 it keeps the value of k = 7 (rolling friction
    # is a function of the displacement, which does not change at rest).
    assert b_rf[8] == b_rf[7] != 0.0
    # k = 2: 1 um after the first reversal, forward: 2/5 - 1 = -0.6
    assert_allclose(b_rf[2], -0.6, atol=1e-12)
    acc = np.linspace(-1.0, 1.0, vel.size)
    psi = basis(pos, vel, acc, x_mu_m=x_mu)
    assert psi.shape == (vel.size, 3)
    assert_allclose(psi, np.column_stack((acc, vel, expected)), atol=1e-12)


def test_w_zeroes_exactly_the_samples_within_the_threshold() -> None:
    pos, vel, acc = REF2
    x_r = reversal_displacement(pos, vel)
    threshold = 1e-4
    w = weighting(x_r, threshold_m=threshold)
    assert_allclose(w, np.where(x_r > threshold, 1.0, 0.0), atol=0)
    assert 0 < np.count_nonzero(w == 0.0) < w.size
    # With the velocity, the rests beyond the threshold are out as well.
    moving = weighting(x_r, threshold_m=threshold, velocity_m_s=vel)
    assert_allclose(moving, np.where((x_r > threshold) & (vel != 0.0), 1.0, 0.0), atol=0)
    assert np.any((w == 1.0) & (vel == 0.0)) and not np.any((moving == 1.0) & (vel == 0.0))
    with pytest.raises(SignalError, match=r"threshold_m: no sample .* while moving"):
        weighting(x_r, threshold_m=threshold, velocity_m_s=np.zeros_like(vel))
    # Garbage where W = 0 does not reach the estimate of eq. (23).
    theta = np.array([12.0, 80.0, 4.4])
    psi = basis(pos, vel, acc, x_mu_m=5e-6)
    f_np = psi @ theta + np.where(w == 0.0, 7.0 * np.cos(np.arange(N)), 0.0)
    sens = process_sensitivity(paper_params(N))
    assert_allclose(estimate_parameters(f_np, psi, sensitivity=sens, weights=w), theta, rtol=1e-8)
    # ... while eq. (19) without W sees it.
    assert not np.allclose(estimate_parameters(f_np, psi, sensitivity=sens), theta, rtol=1e-2)


def test_projection_recovers_theta_when_f_np_is_in_the_basis() -> None:
    theta = np.array(
        [
            TRUE_PLANT.inertia_kgm2 / (LEAD * KT),
            TRUE_PLANT.damping_Nms_per_rad / (LEAD * KT),
            TC_NM / KT,
        ]
    )
    sens = process_sensitivity(paper_params(N))
    for ref in (REF1, REF2):
        psi = basis(*ref, x_mu_m=5e-6)
        assert_allclose(estimate_parameters(psi @ theta, psi, sensitivity=sens), theta, rtol=1e-8)


def test_friction_table_reproduces_a_known_curve() -> None:
    pos, vel, acc = REF2
    threshold = 1e-4
    x_r = reversal_displacement(pos, vel)
    t_rf = np.sign(vel) * curve_Nm(x_r)
    theta = np.array([8.8, 88.0, 4.4])
    f_np = theta[0] * acc + theta[1] * vel + t_rf / KT
    estimate = estimate_friction(f_np, acc, vel, theta=theta, torque_constant_Nm_per_A=KT)
    assert_allclose(estimate, t_rf, atol=1e-12)
    table = LearnedFrictionTable.from_trial(x_r, vel, estimate, threshold_m=threshold)
    x_tab, t_tab = table.arrays()
    keep = (x_r <= threshold) & (vel != 0.0)
    # One entry per displacement any reversal of the trial was sampled at.
    assert_allclose(x_tab, np.unique(x_r[keep]), atol=0)
    assert np.all(np.diff(x_tab) > 0.0) and x_tab[-1] <= threshold
    # The mean of the reversals' curves, each interpolated linearly between
    # its own samples: off the known curve by at most gap^2 / 8 * max|T''|.
    segment = np.concatenate(([0], np.cumsum(np.diff(x_r) < 0.0)))
    gaps = [np.max(np.diff(np.sort(x_r[keep & (segment == g)]))) for g in np.unique(segment[keep])]
    curvature = 18.0 * TC_NM / XS_M**2  # max |d^2 curve / d x_r^2|
    assert_allclose(t_tab, curve_Nm(x_tab), atol=max(gaps) ** 2 / 8.0 * curvature + 1e-11)
    assert t_tab[0] < -0.9 * TC_NM and t_tab[-1] > 0.99 * TC_NM
    # Closest lookup between the entries: off by at most slope * half the gap.
    mid = 0.5 * (x_tab[1:] + x_tab[:-1])
    slope = 6.0 * TC_NM / XS_M  # max |d curve / d x_r|
    half_gap = 0.5 * np.max(np.diff(x_tab))
    assert_allclose(table.lookup(mid), curve_Nm(mid), atol=slope * half_gap + 1e-12)
    assert_allclose(table.lookup(x_tab), t_tab, atol=0)


def test_friction_table_closest_entry_by_hand() -> None:
    table = LearnedFrictionTable([3e-5, 0.0, 1e-5], [1.0, -1.0, 0.0])  # sorted on construction
    assert_allclose(table.arrays()[0], [0.0, 1e-5, 3e-5], atol=0)
    got = table.lookup(np.array([0.4e-5, 0.6e-5, 1.9e-5, 2.1e-5, 5e-5]))
    assert_allclose(got, [-1.0, 0.0, 0.0, 1.0, 1.0], atol=0)
    with pytest.raises(TableError, match="x_r_m: the friction table is empty"):
        LearnedFrictionTable([], [])


# -- the laws --------------------------------------------------------------------------


def reference_of(trial: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return REF1 if trial <= 4 else REF2  # Ref. 1 until trial 4, then Ref. 2 (001 Fig. 9)


def friction_A(pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Rolling friction as an input disturbance, A (a function of the reference; held at rest)."""
    x_r, direction = reversal_state(pos, vel)
    return direction * curve_Nm(x_r) / KT


def run_law(law: StandardIlc | ProjectionIlc, trials: int) -> list[float]:
    """RMS error per trial on the lifted true plant with rolling friction; checks eq. (3)."""
    s, sp = loop_matrices(TRUE_PLANT, N)
    q = q_matrix(N, 16)
    zpetc = learning_filter(paper_params(N))
    rms = []
    for j in range(1, trials + 1):
        pos, vel, _ = reference_of(j)
        (f,) = law.next_correction(period=j)
        assert np.array_equal(law.next_correction(period=j)[0], f)  # pure
        e = s @ pos - sp @ (f - friction_A(pos, vel))  # eq. (2)
        rms.append(float(np.sqrt(np.mean(e**2))))
        f_np = law.learn(e, period=j)
        if isinstance(law, ProjectionIlc):
            assert_allclose(f_np, q @ (f + zpetc.apply(e)), rtol=1e-9, atol=1e-12)  # eq. (3)
    return rms


def test_projection_laws_carry_over_to_a_new_reference() -> None:
    projection = ProjectionParams()
    laws = {
        table: ProjectionIlc(
            ilc=paper_params(N),
            projection=projection,
            reference_of=reference_of,
            friction_table=table,
        )
        for table in (False, True)
    }
    silc = run_law(StandardIlc(paper_params(N)), 5)
    bf, bfft = run_law(laws[False], 5), run_law(laws[True], 5)
    # Trial 5 is the first on Ref. 2: S-ILC starts over, the P-ILCs do not (Fig. 10).
    assert silc[4] > 0.8 * silc[0]
    assert bf[4] < 0.2 * silc[4] and bfft[4] < 0.2 * silc[4]
    # The proposal estimates J, D, T_c from the Coulomb region only (eq. (23)).
    est = laws[True].physical_parameters()
    assert_allclose(est["inertia_kgm2"], TRUE_PLANT.inertia_kgm2, rtol=0.03)
    assert_allclose(est["damping_Nms_per_rad"], TRUE_PLANT.damping_Nms_per_rad, rtol=0.1)
    assert_allclose(est["coulomb_Nm"], TC_NM, rtol=0.03)
    d_bf = laws[False].physical_parameters()["damping_Nms_per_rad"]
    assert abs(est["damping_Nms_per_rad"] - 0.12) < abs(
        d_bf - 0.12
    )  # the approximation biases (19)
    x_tab, t_tab = laws[True].friction_table()
    assert x_tab.size > 0 and np.all(x_tab <= projection.threshold_m)
    assert_allclose(t_tab[x_tab > 3 * XS_M], TC_NM, atol=0.15 * TC_NM)
    assert laws[False].friction_table()[0].size == 0
    assert_allclose(
        laws[True].parameters() * [LEAD * KT, LEAD * KT, KT],
        [est["inertia_kgm2"], est["damping_Nms_per_rad"], est["coulomb_Nm"]],
        rtol=1e-12,
    )


def make(table: bool, ref: object = reference_of) -> ProjectionIlc:
    return ProjectionIlc(
        ilc=paper_params(N),
        projection=ProjectionParams(),
        reference_of=ref,  # type: ignore[arg-type]
        friction_table=table,
    )


@pytest.mark.parametrize("table", [False, True])
def test_memory_round_trip_gives_the_same_correction(table: bool) -> None:
    law = make(table)
    assert_allclose(law.next_correction(period=1)[0], 0.0, atol=0)  # nothing learned: zeros
    run_law(law, 2)
    fresh = make(table)
    fresh.load_state(json.loads(json.dumps(law.state())))
    for j in (3, 5):
        assert np.array_equal(fresh.next_correction(period=j)[0], law.next_correction(period=j)[0])
    assert fresh.periods_learned == 2 and fresh.state()["last_trial"] == 2
    other = make(table)
    other.load_state(decode_memory(encode_memory(law, scenario="s"), other, scenario="s"))
    assert np.array_equal(other.next_correction(period=5)[0], law.next_correction(period=5)[0])
    assert law.name == ("pilc_bfft" if table else "pilc_bf") == law.identity()["law"]


def test_bad_input_is_refused_with_its_name() -> None:
    with pytest.raises(ConfigError, match="x_mu_m: expected a value > 0"):
        ProjectionParams(x_mu_m=0.0)
    with pytest.raises(ConfigError, match="threshold_m: expected a value > 0"):
        ProjectionParams(threshold_m=-1e-4)
    with pytest.raises(ConfigError, match=r"nq: Nq too large for the trial"):
        paper_params(60, nq=15)
    undamped = NominalModel(
        inertia_kgm2=0.015, damping_Nms_per_rad=0.0, torque_constant_Nm_per_A=KT
    )
    with pytest.raises(ConfigError, match=r"nq: Nq = 0 gives .*eq. \(7\)"):
        ProjectionIlc(
            ilc=IlcParams(
                samples_per_trial=N,
                nq=0,
                period_s=PERIOD_S,
                lead_m_per_rad=LEAD,
                nominal=undamped,
                pid=design_pid_pole_placement(bandwidth_hz=30.0, **undamped.as_kwargs()),
            ),
            projection=ProjectionParams(),
            reference_of=reference_of,
            friction_table=True,
        )
    # A trial that never gets 100 um from a reversal: W of eq. (27) all zero.
    short = min_jerk(100, [(5e-5, 300), (-5e-5, 300)], 400)
    law = make(True, lambda trial: short)
    with pytest.raises(SignalError, match=r"threshold_m = 0.0001 m .*W of eq. \(27\) is all zero"):
        law.learn(np.zeros(N), period=1)
    assert law.periods_learned == 0
    with pytest.raises(SignalError, match=r"weights: W of eq. \(23\) is all zero"):
        estimate_parameters(
            np.ones(N),
            np.ones((N, 3)),
            sensitivity=process_sensitivity(paper_params(N)),
            weights=np.zeros(N),
        )
    law = make(False)
    with pytest.raises(SignalError, match=r"error: expected 1200 values .*got shape \(10,\)"):
        law.learn(np.zeros(10), period=1)
    with pytest.raises(SignalError, match="error: expected finite values"):
        law.learn(np.full(N, np.inf), period=1)
    with pytest.raises(SignalError, match="period: expected the 1-based trial number"):
        law.learn(np.zeros(N))
    with pytest.raises(SignalError, match="period: expected the 1-based trial number"):
        law.next_correction()
    bad_ref = make(False, lambda trial: (np.zeros(N), np.zeros(N - 1), np.zeros(N)))
    with pytest.raises(SignalError, match=r"reference_of\(1\) velocity_m_s: expected 1200 values"):
        bad_ref.next_correction(period=1)
    state = law.state()
    with pytest.raises(SignalError, match=r"theta: expected 3 values \(J, D and T_c terms"):
        law.load_state({**state, "theta": [1.0, 2.0]})
    with pytest.raises(SignalError, match="table_x_r_m: expected no friction table for pilc_bf"):
        law.load_state({**state, "table_x_r_m": [0.0], "table_torque_Nm": [1.0]})
    with pytest.raises(SignalError, match="table_x_r_m, table_torque_Nm: expected two lists"):
        make(True).load_state({**state, "table_x_r_m": [0.0, 1e-6], "table_torque_Nm": [1.0]})
