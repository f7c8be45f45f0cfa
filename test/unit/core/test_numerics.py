"""References, PID/DOB, PTC and the friction table against independent computations."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import scipy.signal
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError, TableError
from servo_axis.core.feedback.discrete import DiscreteFilter, tustin
from servo_axis.core.feedback.dob import DisturbanceObserver
from servo_axis.core.feedback.pid import DiscretePid, design_pid_pole_placement
from servo_axis.core.feedforward.friction_table import (
    FrictionFeedforward,
    FrictionTable,
    ReversalTracker,
    build_friction_table,
)
from servo_axis.core.feedforward.ptc import MultiratePtc
from servo_axis.core.reference import (
    OneMinusCosReference,
    PointToPointReference,
    SineReference,
    TrialReference,
    make_reference,
)
from servo_axis.storage import load_friction_table, save_friction_table

J, D, KT, TU = 0.01, 0.1, 0.715, 1e-3
NOMINAL = {"inertia_kgm2": J, "damping_Nms_per_rad": D, "torque_constant_Nm_per_A": KT}


def zoh(step_s: float) -> tuple[np.ndarray, np.ndarray]:
    m = np.zeros((3, 3))
    m[0, 1], m[1, 1], m[1, 2] = 1.0, -D / J, KT / J
    e = scipy.linalg.expm(m * step_s)
    return e[:2, :2], e[:2, 2]


# -- references ---------------------------------------------------------------


@pytest.mark.parametrize(
    "ref",
    [
        SineReference(amplitude_m=0.01, frequency_hz=2.0, offset_m=0.003, phase_rad=0.4),
        OneMinusCosReference(amplitude_m=0.025, frequency_hz=1.0),
        PointToPointReference(distance_m=-0.02, move_time_s=0.3, dwell_s=0.1, start_m=0.01),
    ],
)
def test_reference_derivatives_and_period(ref: object) -> None:
    t = np.linspace(0.0, 2.0, 200_001)
    pos, vel, acc = ref.sample(t)  # type: ignore[attr-defined]
    h = t[1] - t[0]
    scale_v, scale_a = np.max(np.abs(vel)), np.max(np.abs(acc))
    assert_allclose(np.gradient(pos, h)[1:-1], vel[1:-1], atol=1e-4 * scale_v)
    assert_allclose(np.gradient(vel, h)[2:-2], acc[2:-2], atol=2e-3 * scale_a)
    period = ref.period_s  # type: ignore[attr-defined]
    for a, b in zip(ref.sample(t[:1000]), ref.sample(t[:1000] + period), strict=True):  # type: ignore[attr-defined]
        assert_allclose(a, b, atol=1e-12)


def test_sine_and_one_minus_cos_are_the_closed_forms() -> None:
    t = np.linspace(0, 1, 101)
    pos, vel, acc = OneMinusCosReference(amplitude_m=0.025, frequency_hz=1.0).sample(t)
    w = 2 * math.pi
    assert_allclose(pos, 0.025 * (1 - np.cos(w * t)), atol=1e-15)
    assert_allclose(vel, 0.025 * w * np.sin(w * t), atol=1e-14)
    assert_allclose(acc, 0.025 * w * w * np.cos(w * t), atol=1e-13)
    pos, _, _ = SineReference(
        amplitude_m=0.01, frequency_hz=2.0, offset_m=0.01, phase_rad=-math.pi / 2
    ).sample(t)
    assert_allclose(pos, 0.01 * (1 - np.cos(2 * w * t)), atol=1e-15)


def test_ramped_sine_starts_at_rest_and_is_the_plain_sine_after_the_ramp() -> None:
    ramp, f = 0.5, 2.0
    ref = SineReference(amplitude_m=0.01, frequency_hz=f, phase_rad=0.3, ramp_s=ramp)
    t = np.linspace(0.0, 1.5, 150_001)
    pos, vel, acc = ref.sample(t)
    h = t[1] - t[0]
    # Derivatives consistent through the ramp and its end (continuous jerk).
    assert_allclose(np.gradient(pos, h)[1:-1], vel[1:-1], atol=1e-4 * np.max(np.abs(vel)))
    assert_allclose(np.gradient(vel, h)[2:-2], acc[2:-2], atol=2e-3 * np.max(np.abs(acc)))
    assert_allclose([vel[0], acc[0]], [0.0, 0.0], atol=1e-15)
    # After the ramp: the plain sine, its phase late by w T / 2.
    late = t >= ramp
    plain = SineReference(
        amplitude_m=0.01, frequency_hz=f, phase_rad=0.3 - 2 * math.pi * f * ramp / 2
    ).sample(t[late])
    for got, want in zip((pos[late], vel[late], acc[late]), plain, strict=True):
        assert_allclose(got, want, atol=1e-12)
    # Two axes with the same ramp, a quarter period apart, stay on a circle.
    radius = 0.01
    x = SineReference(
        amplitude_m=radius, frequency_hz=f, offset_m=radius, phase_rad=-math.pi / 2, ramp_s=ramp
    ).sample(t)[0]
    y = SineReference(amplitude_m=radius, frequency_hz=f, ramp_s=ramp).sample(t)[0]
    assert_allclose(np.hypot(x - radius, y), radius, rtol=1e-12)


def test_point_to_point_endpoints_rest_and_return() -> None:
    ref = PointToPointReference(distance_m=0.02, move_time_s=0.3, dwell_s=0.1, start_m=0.005)
    pos, vel, acc = ref.sample(np.array([0.0, 0.3, 0.35, 0.4, 0.7, 0.75]))
    assert_allclose(pos, [0.005, 0.025, 0.025, 0.025, 0.005, 0.005], atol=1e-15)
    assert_allclose(vel, 0.0, atol=1e-15)
    assert_allclose(acc, 0.0, atol=1e-12)
    _, vmid, _ = ref.sample(np.array([0.15, 0.55]))
    assert_allclose(vmid, [1.875 * 0.02 / 0.3, -1.875 * 0.02 / 0.3], rtol=1e-12)  # peak 15/8 d/T
    one_way = PointToPointReference(distance_m=0.02, move_time_s=0.3, back_and_forth=False)
    assert one_way.period_s is None
    assert_allclose(one_way.sample(np.array([5.0]))[0], [0.02])


def _trials() -> TrialReference:
    return TrialReference(
        trial_s=1.0,
        amplitudes_m=(2e-3, -3e-3),
        move_times_s=(0.6, 0.5),
        start_times_s=(0.1, 0.2),
        first_trials=(1, 3),
        offset_m=0.001,
    )


def test_trial_reference_is_sin4_per_trial_and_switches_at_its_trial() -> None:
    ref = _trials()
    t = np.linspace(0.0, 4.0, 400_001)
    pos, vel, acc = ref.sample(t)
    h = t[1] - t[0]
    # Derivatives are consistent across trial boundaries (smooth, at rest there).
    assert_allclose(np.gradient(pos, h)[1:-1], vel[1:-1], atol=1e-4 * np.max(np.abs(vel)))
    assert_allclose(np.gradient(vel, h)[2:-2], acc[2:-2], atol=2e-3 * np.max(np.abs(acc)))
    # The closed form, trial by trial: Ref. 1 in trials 1-2, Ref. 2 from trial 3.
    for trial, (a, t0, tm) in {
        1: (2e-3, 0.1, 0.6),
        2: (2e-3, 0.1, 0.6),
        3: (-3e-3, 0.2, 0.5),
        4: (-3e-3, 0.2, 0.5),
    }.items():
        tau = np.linspace(0.0, 0.999, 1000)
        u = np.clip((tau - t0) / tm, 0.0, 1.0)
        expected = 0.001 + a * np.sin(np.pi * u) ** 4
        assert_allclose(ref.sample(tau + (trial - 1) * 1.0)[0], expected, rtol=0, atol=1e-15)
        assert ref.trajectory_of(trial) == (0 if trial < 3 else 1)
    # At rest at both ends of every trial, at the rest position; one reversal
    # at the middle of the move, at offset + A.
    for start in (0.0, 1.0, 2.0, 3.0):
        p0, v0, a0 = ref.sample(np.array([start, start + 0.05, start + 0.95]))
        assert_allclose(p0, 0.001, atol=1e-18)
        assert_allclose(v0, 0.0, atol=0)
        assert_allclose(a0, 0.0, atol=0)
    one = (t >= 0.0) & (t < 1.0)
    crossings = np.flatnonzero(np.diff(np.sign(vel[one][vel[one] != 0])))
    assert crossings.size == 1
    assert_allclose(ref.sample(np.array([0.4]))[0], 0.001 + 2e-3, rtol=1e-12)
    assert ref.period_s is None


def test_trial_reference_refuses_what_is_not_a_trial() -> None:
    base = {
        "trial_s": 1.0,
        "amplitudes_m": (2e-3,),
        "move_times_s": (0.6,),
        "start_times_s": (0.1,),
        "first_trials": (1,),
    }
    with pytest.raises(ConfigError, match="move_times_s: a trajectory must start and end at rest"):
        TrialReference(**{**base, "start_times_s": (0.5,)})
    with pytest.raises(ConfigError, match="first_trials"):
        TrialReference(**{**base, "first_trials": (2,)})
    with pytest.raises(ConfigError, match="first_trials"):
        TrialReference(
            **{
                **base,
                "amplitudes_m": (1e-3, 2e-3),
                "move_times_s": (0.6, 0.6),
                "start_times_s": (0.1, 0.1),
                "first_trials": (1, 1),
            }
        )
    with pytest.raises(ConfigError, match="move_times_s: expected one value per trajectory"):
        TrialReference(**{**base, "amplitudes_m": (1e-3, 2e-3)})
    with pytest.raises(ConfigError, match="amplitudes_m: expected non-zero"):
        TrialReference(**{**base, "amplitudes_m": (0.0,)})
    with pytest.raises(ConfigError, match="trial_s"):
        TrialReference(**{**base, "trial_s": 0.0})
    with pytest.raises(ConfigError, match="trial"):
        _trials().trajectory_of(0)


def test_reference_validation_names_the_field() -> None:
    with pytest.raises(ConfigError, match="kind"):
        make_reference("square", amplitude_m=1.0)
    with pytest.raises(ConfigError, match="frequency_hz"):
        SineReference(amplitude_m=0.01, frequency_hz=0.0)
    with pytest.raises(ConfigError, match="distance_m"):
        PointToPointReference(distance_m=0.0, move_time_s=1.0)
    with pytest.raises(ConfigError, match="ramp_s"):
        SineReference(amplitude_m=0.01, frequency_hz=2.0, ramp_s=-0.1)


# -- PID and DOB ----------------------------------------------------------------


@pytest.mark.parametrize("bandwidth_hz", [20.0, 40.0, 45.0, 100.0])
def test_pid_places_all_four_poles_at_minus_omega(bandwidth_hz: float) -> None:
    gains = design_pid_pole_placement(bandwidth_hz=bandwidth_hz, **NOMINAL)
    num_c, den_c = gains.transfer_function()
    num_p, den_p = np.array([KT]), np.array([J, D, 0.0])
    closed = np.polyadd(np.polymul(den_p, den_c), np.polymul(num_p, num_c))
    w = 2 * math.pi * bandwidth_hz
    target = J * gains.derivative_tau_s * np.poly([-w] * 4)
    assert_allclose(closed, target, rtol=1e-9)


def test_pid_rejects_a_bandwidth_below_the_damping() -> None:
    with pytest.raises(ConfigError, match="bandwidth_hz"):
        design_pid_pole_placement(
            inertia_kgm2=0.01,
            damping_Nms_per_rad=10.0,
            torque_constant_Nm_per_A=KT,
            bandwidth_hz=1.0,
        )


def test_discrete_pid_is_the_tustin_discretisation() -> None:
    gains = design_pid_pole_placement(bandwidth_hz=40.0, **NOMINAL)
    num, den = gains.transfer_function()
    numd, dend, _ = scipy.signal.cont2discrete((num, den), TU, method="bilinear")
    numd, dend = np.ravel(numd) / dend[0], np.ravel(dend) / dend[0]
    pid = DiscretePid(gains=gains, period_s=TU)
    assert_allclose(pid.filter.b, numd, rtol=1e-10)
    assert_allclose(pid.filter.a, dend, rtol=1e-10, atol=1e-14)
    _, (step,) = scipy.signal.dstep((numd, dend, TU), n=50)
    assert_allclose([pid.update(1.0) for _ in range(50)], step.ravel(), rtol=1e-9)


def test_filter_impulse_response_and_tustin_first_order() -> None:
    f = DiscreteFilter(np.array([1.0]), np.array([1.0, -0.5]))
    assert_allclose([f.update(1.0 if k == 0 else 0.0) for k in range(10)], 0.5 ** np.arange(10))
    lp = tustin(np.array([500.0]), np.array([1.0, 500.0]), TU)
    numd, dend, _ = scipy.signal.cont2discrete(([500.0], [1.0, 500.0]), TU, method="bilinear")
    assert_allclose(lp.b, np.ravel(numd) / dend[0], rtol=1e-12)
    assert_allclose(lp.a, np.ravel(dend) / dend[0], rtol=1e-12)


def test_dob_estimates_a_constant_input_disturbance() -> None:
    ad, bd = zoh(TU)
    gains = design_pid_pole_placement(bandwidth_hz=20.0, **NOMINAL)

    def run(with_dob: bool) -> tuple[float, float]:
        pid = DiscretePid(gains=gains, period_s=TU)
        dob = DisturbanceObserver(cutoff_hz=80.0, period_s=TU, **NOMINAL)
        x, u, d_hat, worst = np.zeros(2), 0.0, 0.0, 0.0
        for k in range(500):
            y = x[0]
            worst = max(worst, abs(y)) if 20 <= k <= 60 else worst
            d_hat = dob.update(y, u)
            u = pid.update(-y) - (d_hat if with_dob else 0.0)
            x = ad @ x + bd * (u + 1.5)  # 1.5 A input disturbance
        return d_hat, worst

    d_hat, worst_with = run(True)
    _, worst_without = run(False)
    assert_allclose(d_hat, 1.5, rtol=1e-3)
    assert worst_with < 0.5 * worst_without  # the observer takes the disturbance off the PID


# -- PTC -------------------------------------------------------------------------


def test_ptc_tracks_the_nominal_plant_perfectly_at_every_reference_instant() -> None:
    ptc = MultiratePtc(control_period_s=TU, **NOMINAL)
    ad, bd = zoh(TU)
    assert_allclose(ptc.b_matrix, np.column_stack((ad @ bd, bd)), rtol=1e-12)
    assert abs(np.linalg.det(ptc.b_matrix)) > 0
    t = np.arange(201) * 2 * TU
    x_d = np.column_stack(
        (5 * np.sin(2 * math.pi * 2 * t), 5 * 2 * math.pi * 2 * np.cos(2 * math.pi * 2 * t))
    )
    out = ptc.feedforward(x_d)
    x = x_d[0].copy()
    states = [x.copy()]
    for u in out.current_A:
        x = ad @ x + bd * u
        states.append(x.copy())
    states_arr = np.array(states)
    assert_allclose(states_arr[0::2], x_d, rtol=1e-10, atol=1e-10)
    assert_allclose(states_arr[1:-1:2, 0], out.position_rad[1::2], rtol=1e-12, atol=1e-12)
    assert_allclose(states_arr[1:-1:2, 1], out.velocity_rad_s[1::2], rtol=1e-12, atol=1e-10)


def test_ptc_validation() -> None:
    with pytest.raises(ConfigError, match="ratio"):
        MultiratePtc(control_period_s=TU, ratio=3, **NOMINAL)
    ptc = MultiratePtc(control_period_s=TU, **NOMINAL)
    with pytest.raises(SignalError, match="x_d"):
        ptc.feedforward(np.zeros((5, 3)))
    with pytest.raises(SignalError, match="x_d"):
        ptc.feedforward(np.array([[0.0, 0.0], [math.nan, 0.0]]))


# -- friction table ----------------------------------------------------------------


def law(d: np.ndarray, tc: float = 3.2, d0: float = 3e-6) -> np.ndarray:
    """A known rolling-friction reversal curve: -T_c at the reversal to +T_c."""
    return tc * (2 * (1 - np.exp(-d / d0)) - 1)


def test_table_file_round_trip_and_interpolation(tmp_path: Path) -> None:
    table = FrictionTable(np.array([0.0, 1e-6, 3e-6]), np.array([-3.0, 0.1, 3.0]))
    save_friction_table(tmp_path / "t.csv", table)
    back = load_friction_table(tmp_path / "t.csv")
    assert back.displacement_m.tolist() == table.displacement_m.tolist()
    assert back.torque_Nm.tolist() == table.torque_Nm.tolist()
    assert_allclose(table.torque_Nm_at(0.5e-6), -1.45, rtol=1e-12)
    assert_allclose(table.torque_Nm_at(10e-6), 3.0)
    assert_allclose(table.torque_Nm_at(2e-6, -1), -1.55, rtol=1e-12)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("displacement_m,torque_Nm\n0,1\n1,2\n", "line 1"),
        ("# servo_axis friction table v1\ndisplacement_m,torque_Nm\n0,1\n1e-6,abc\n", "line 4"),
        ("# servo_axis friction table v1\ndisplacement_m,torque_Nm\n0,1\n1e-6,nan\n", "line 4"),
        (
            "# servo_axis friction table v1\ndisplacement_m,torque_Nm\n0,1\n2e-6,2\n1e-6,3\n",
            "line 5",
        ),
        ("# servo_axis friction table v1\ndisplacement_m,torque_Nm\n0,1\n", "at least 2 rows"),
        (
            "# servo_axis friction table v1\ndisplacement_m,torque_Nm\n1e-6,1\n2e-6,2\n",
            "starting at 0",
        ),
    ],
)
def test_corrupt_table_files_are_rejected(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(TableError, match=match) as err:
        load_friction_table(path)
    assert "bad.csv" in str(err.value)


def test_reversal_tracker_finds_the_extrema() -> None:
    t = np.arange(0, 2.0, 1e-3)
    x = np.sin(2 * math.pi * t)
    tracker = ReversalTracker()
    out = [tracker.update(float(v)) for v in x]
    flips = [k for k in range(1, len(out)) if out[k][0] != out[k - 1][0]]
    # The direction flips on the first sample after each extremum.
    extrema = (
        scipy.signal.argrelextrema(x, np.greater)[0].tolist()
        + scipy.signal.argrelextrema(x, np.less)[0].tolist()
    )
    assert flips == [k + 1 for k in sorted(extrema)]
    for k in flips:
        assert_allclose(out[k][1], abs(x[k] - x[k - 1]), rtol=1e-12)


def test_build_recovers_a_known_friction_law() -> None:
    t = np.arange(0, 10.0, 1e-3)
    pos = 20e-6 * np.sin(2 * math.pi * 0.3 * t)
    tracker = ReversalTracker()
    torque = np.empty_like(pos)
    for k, p in enumerate(pos):
        direction, d = tracker.update(float(p))
        torque[k] = direction * law(np.array(d))
    width = 0.5e-6
    table = build_friction_table(
        position_m=pos, torque_Nm=torque, bin_width_m=width, max_displacement_m=20e-6
    )
    centres = table.displacement_m[1:]
    slope = np.max(np.abs(np.gradient(law(centres), centres)))
    assert_allclose(table.torque_Nm[1:], law(centres), atol=slope * width / 2)
    with pytest.raises(TableError, match="no sample"):
        build_friction_table(
            position_m=pos, torque_Nm=torque, bin_width_m=width, max_displacement_m=60e-6
        )


def test_friction_feedforward_follows_the_direction() -> None:
    table = FrictionTable(np.array([0.0, 2e-6, 4e-6]), np.array([-3.0, 0.0, 3.0]))
    ff = FrictionFeedforward(table, torque_constant_Nm_per_A=KT)
    x = 10e-6 * np.sin(2 * math.pi * np.arange(0, 1.0, 1e-3))
    cur = np.array([ff.current_A(float(v)) for v in x])
    assert_allclose(cur[100:240], 3.0 / KT)  # moving up, far from the start
    assert_allclose(cur[400:700], -3.0 / KT)  # moving down, > 4 um past the reversal at 250
    assert cur[251] == pytest.approx(-table.torque_Nm_at(x[250] - x[251]) / KT, rel=1e-12)


def test_discrete_filter_state_round_trip_and_settle() -> None:
    from servo_axis.core.feedback.discrete import tustin

    w = 2 * math.pi * 20.0
    lpf = tustin(np.array([w * w]), np.array([1.0, 2 * w, w * w]), 4e-4)
    for x in (0.3, -1.0, 2.0):
        lpf.update(x)
    saved = lpf.state
    other = tustin(np.array([w * w]), np.array([1.0, 2 * w, w * w]), 4e-4)
    other.set_state(saved)
    assert [lpf.update(0.7) for _ in range(5)] == [other.update(0.7) for _ in range(5)]
    with pytest.raises(ConfigError, match="z: expected 2 values"):
        other.set_state([0.0])
    # Settled on x, a unit-DC-gain low-pass stays at x; its derivative at 0.
    lpf.settle(0.25)
    assert_allclose([lpf.update(0.25) for _ in range(10)], 0.25, rtol=1e-12)
    deriv = tustin(np.array([w * w, 0.0]), np.array([1.0, 2 * w, w * w]), 4e-4)
    deriv.settle(0.25)
    assert_allclose([deriv.update(0.25) for _ in range(10)], 0.0, atol=1e-12)
