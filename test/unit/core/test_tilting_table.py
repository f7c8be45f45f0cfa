"""Tilting-table plant (paper 003 eq. (2)) against closed forms, scipy and energy balances."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.models.base import Plant, PlantOutput
from servo_axis.core.models.tilting_table import (
    TiltingTableParams,
    TiltingTablePlant,
    nominal,
)

# Table I plant of paper 003 and its period.
J, D, U, C = 50e-4, 130e-4, 0.3, 0.02
T = 0.4e-3
QUIET = TiltingTableParams(noise_rad=0.0)


def make(params: TiltingTableParams, seed: int = 0) -> TiltingTablePlant:
    return TiltingTablePlant(params, rng=np.random.default_rng(seed))


def run(plant: TiltingTablePlant, currents: np.ndarray) -> list[PlantOutput]:
    return [plant.step(float(i)) for i in currents]


def angles(outs: list[PlantOutput]) -> np.ndarray:
    return np.array([o.angle_rad for o in outs])


def velocities(outs: list[PlantOutput]) -> np.ndarray:
    return np.array([o.velocity_rad_s for o in outs])


def ode_solution(
    params: TiltingTableParams, torque: float, t: np.ndarray, friction: float
) -> np.ndarray:
    """Eq. (2) with a fixed friction torque, solved by scipy (DOP853), rows (th, v)."""
    p = params

    def rhs(_t: float, x: np.ndarray) -> list[float]:
        acc = (
            torque - p.damping_Nms_per_rad * x[1] - p.unbalance_Nm * math.sin(x[0]) - friction
        ) / p.inertia_kgm2
        return [x[1], acc]

    sol = scipy.integrate.solve_ivp(
        rhs,
        (0.0, float(t[-1])),
        [p.initial_angle_rad, p.initial_velocity_rad_s],
        method="DOP853",
        t_eval=t,
        rtol=1e-13,
        atol=1e-15,
    )
    assert sol.success
    y: np.ndarray = sol.y
    return y


def test_satisfies_plant_protocol_and_defaults_are_table_i() -> None:
    plant: Plant = make(TiltingTableParams())
    p = TiltingTableParams()
    assert (p.inertia_kgm2, p.damping_Nms_per_rad, p.unbalance_Nm, p.coulomb_Nm) == (J, D, U, C)
    assert p.control_period_s == T
    assert p.substeps == 10
    assert plant.step_index == 0
    assert plant.step(0.0).step == 1
    assert plant.step_index == 1


def test_linear_part_matches_closed_form() -> None:
    # C = U = 0: J th'' + D th' = K_T i, with K_T != 1 and a moving start.
    kt, i, th0, v0 = 1.3, 0.7, 0.1, 0.5
    params = replace(
        QUIET,
        coulomb_Nm=0.0,
        unbalance_Nm=0.0,
        torque_constant_Nm_per_A=kt,
        initial_angle_rad=th0,
        initial_velocity_rad_s=v0,
    )
    outs = run(make(params), np.full(2500, i))
    t = np.arange(1, 2501) * T
    a, v_inf = D / J, kt * i / D
    v_exact = v_inf + (v0 - v_inf) * np.exp(-a * t)
    th_exact = th0 + v_inf * t - (v0 - v_inf) * np.expm1(-a * t) / a
    assert_allclose(angles(outs), th_exact, rtol=1e-11, atol=1e-13)
    assert_allclose(velocities(outs), v_exact, rtol=1e-11, atol=1e-13)
    assert all(o.motor_torque_Nm == kt * i for o in outs)
    assert all(o.friction_force_N == 0.0 for o in outs)


def test_unbalance_without_friction_matches_scipy() -> None:
    # C = 0, D > 0, U > 0, large swing (nonlinear sin), constant current.
    params = replace(QUIET, coulomb_Nm=0.0, initial_angle_rad=1.2, initial_velocity_rad_s=-0.3)
    outs = run(make(params), np.full(2500, 0.05))
    t = np.arange(1, 2501) * T
    th, v = ode_solution(params, 0.05, t, 0.0)
    assert_allclose(angles(outs), th, rtol=0, atol=1e-10)
    assert_allclose(velocities(outs), v, rtol=0, atol=1e-9)


def test_energy_conserved_without_losses() -> None:
    # D = C = 0, i = 0: J v^2/2 + U (1 - cos th) is invariant. RK4 at h = 40 us
    # with w ~ sqrt(U/J) = 7.7 rad/s errs by ~(w h)^5 ~ 3e-18 per step, so over
    # 25000 steps rounding (~1e-14) dominates; 1e-12 relative bounds both.
    params = replace(
        QUIET,
        damping_Nms_per_rad=0.0,
        coulomb_Nm=0.0,
        initial_angle_rad=2.5,
        initial_velocity_rad_s=1.0,
    )
    outs = run(make(params), np.zeros(2500))
    th, v = angles(outs), velocities(outs)
    energy = 0.5 * J * v**2 + U * (1.0 - np.cos(th))
    e0 = 0.5 * J * 1.0**2 + U * (1.0 - math.cos(2.5))
    assert_allclose(energy, e0, rtol=1e-12, atol=0)
    assert np.ptp(th) > 4.0  # it really swung through the bottom


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_sticks_below_breakaway(sign: float) -> None:
    th0 = 0.5
    net = sign * 0.999 * C
    i = (U * math.sin(th0) + net) / QUIET.torque_constant_Nm_per_A
    params = replace(QUIET, initial_angle_rad=th0)
    outs = run(make(params), np.full(2000, i))
    assert np.all(angles(outs) == th0)
    assert np.all(velocities(outs) == 0.0)
    # The friction holds exactly the net torque (static friction).
    assert_allclose([o.friction_force_N for o in outs], net, rtol=1e-12, atol=0)


def test_breaks_away_just_above_breakaway() -> None:
    th0 = 0.5
    net = C + 1e-4
    i = U * math.sin(th0) + net
    params = replace(QUIET, initial_angle_rad=th0)
    outs = run(make(params), np.full(500, i))
    v = velocities(outs)
    assert np.all(v > 0.0)
    # Slides forward the whole time: eq. (2) with friction +C, solved by scipy.
    t = np.arange(1, 501) * T
    th_ref, v_ref = ode_solution(params, i, t, C)
    # atol: rounding of an angle near 0.5 rad (ulp 1.1e-16) over 5000 sub-steps.
    assert_allclose(angles(outs) - th0, th_ref - th0, rtol=1e-8, atol=1e-14)
    assert_allclose(v, v_ref, rtol=1e-8, atol=1e-16)
    assert all(o.friction_force_N == C for o in outs)


def sliding_stop(v0: float) -> tuple[float, float]:
    """Stop time and travel of J v' = -D v - C from v0 > 0 (closed form)."""
    a, vc = D / J, C / D
    t_stop = math.log1p(v0 / vc) / a
    travel = (v0 + vc) * (-math.expm1(-a * t_stop)) / a - vc * t_stop
    return t_stop, travel


def test_sliding_table_stops_and_stays_stopped() -> None:
    v0 = 1.0
    params = replace(QUIET, unbalance_Nm=0.0, initial_velocity_rad_s=v0, initial_angle_rad=0.2)
    n = 1500
    outs = run(make(params), np.zeros(n))
    th, v = angles(outs), velocities(outs)
    t = np.arange(1, n + 1) * T
    t_stop, travel = sliding_stop(v0)
    a, vc = D / J, C / D
    moving = t < t_stop
    assert 0 < moving.sum() < n - 500
    v_exact = (v0 + vc) * np.exp(-a * t[moving]) - vc
    th_exact = 0.2 + (v0 + vc) * (-np.expm1(-a * t[moving])) / a - vc * t[moving]
    assert_allclose(v[moving], v_exact, rtol=1e-11, atol=1e-13)
    assert_allclose(th[moving], th_exact, rtol=1e-12, atol=0)
    # Decelerates by (D v + C) / J: finite differences of the samples.
    acc = np.diff(v[moving]) / T
    v_mid = 0.5 * (v[moving][1:] + v[moving][:-1])
    assert_allclose(acc, -(D * v_mid + C) / J, rtol=1e-6)
    # Stopped: exactly zero velocity, angle frozen at the closed-form travel, no sign flip.
    assert np.all(v >= 0.0)
    assert np.all(v[~moving] == 0.0)
    assert np.all(th[~moving] == th[~moving][0])
    assert_allclose(th[~moving][0], 0.2 + travel, rtol=1e-12, atol=0)
    assert all(o.friction_force_N == C for o, m in zip(outs, moving, strict=True) if m)
    assert all(o.friction_force_N == 0.0 for o, m in zip(outs, moving, strict=True) if not m)


@pytest.mark.parametrize("k", [300, 481])
@pytest.mark.parametrize("offset_s", [1e-11, -1e-11])
def test_stop_time_matches_closed_form(k: int, offset_s: float) -> None:
    # The initial velocity is chosen so the analytic stop falls 10 ps after
    # (or before) control sample k. The sample then shows the table still
    # moving (or exactly stopped): the stop is located to better than 1e-11 s
    # = 2.5e-7 of a sub-step. Justification: RK4 errs by ~(h D/J)^5 ~ 1e-22
    # per step and rounding leaves ~1e-15 rad/s on the velocity, i.e. ~3e-16 s
    # at the deceleration C/J = 4 rad/s^2; the Newton search ends below
    # 1e-10 h = 4e-15 s. (A stop this close to a sub-step boundary does not
    # test the event search inside a sub-step; the reversal test below does.)
    a, vc = D / J, C / D
    t_stop = k * T + offset_s
    v0 = vc * math.expm1(a * t_stop)
    assert_allclose(sliding_stop(v0)[0], t_stop, rtol=1e-15, atol=0)
    params = replace(QUIET, unbalance_Nm=0.0, initial_velocity_rad_s=v0)
    v = velocities(run(make(params), np.zeros(k + 20)))
    assert np.all(v[: k - 1] > 0.0)
    if offset_s > 0:
        # Still moving at sample k with the closed-form speed ((C + D v)/J) * offset.
        assert_allclose(v[k - 1], vc * math.expm1(a * offset_s), rtol=1e-3)
        assert np.all(v[k:] == 0.0)
    else:
        assert np.all(v[k - 1 :] == 0.0)


def stick_slip_reference(params: TiltingTableParams, torque: float, t: np.ndarray) -> np.ndarray:
    """Eq. (2) with stick/slip by scipy: DOP853 segments ended by a v = 0 event, rows (th, v)."""
    p = params
    out = np.empty((2, t.size))
    t0, th, v = 0.0, p.initial_angle_rad, p.initial_velocity_rad_s
    done = 0
    while done < t.size:
        if v == 0.0:
            net = torque - p.unbalance_Nm * math.sin(th)
            if abs(net) <= p.coulomb_Nm:
                out[0, done:], out[1, done:] = th, 0.0
                break
            s = math.copysign(1.0, net)
        else:
            s = math.copysign(1.0, v)

        def rhs(_t: float, x: np.ndarray, s: float = s) -> list[float]:
            friction = p.coulomb_Nm * s
            acc = torque - p.damping_Nms_per_rad * x[1] - p.unbalance_Nm * math.sin(x[0])
            return [x[1], (acc - friction) / p.inertia_kgm2]

        def stop(_t: float, x: np.ndarray) -> float:
            return float(x[1])

        stop.terminal = True  # type: ignore[attr-defined]
        stop.direction = -s  # type: ignore[attr-defined]
        sol = scipy.integrate.solve_ivp(
            rhs,
            (t0, float(t[-1])),
            [th, v],
            method="DOP853",
            events=stop,
            dense_output=True,
            rtol=1e-13,
            atol=1e-15,
        )
        stopped = sol.status == 1
        t_end = float(sol.t_events[0][0]) if stopped else math.inf
        idx = int(np.searchsorted(t, t_end, side="left"))
        if idx > done:
            out[:, done:idx] = sol.sol(t[done:idx])
        done = idx
        if stopped:
            t0, th, v = t_end, float(sol.y_events[0][0][0]), 0.0
    return out


@pytest.mark.parametrize(
    ("i", "th0", "v0"), [(0.05, 1.0, 0.0), (-0.05, 2.0, 0.0), (0.1, -0.5, 3.0)]
)
def test_reversals_and_final_stick_match_scipy_events(i: float, th0: float, v0: float) -> None:
    # Table I with U > C: the table swings, reverses inside sub-steps (friction
    # flips sign) and finally sticks. Reference: scipy DOP853 restarted at each
    # v = 0 event. After a reversal, an event time off by dt leaves a velocity
    # error ~ dt (U sin th +- C)/J: the Newton search gives ~1e-12 rad/s here,
    # linear interpolation of the crossing alone would give ~1e-8 rad/s, so
    # 1e-10 rad/s tells them apart.
    params = replace(QUIET, initial_angle_rad=th0, initial_velocity_rad_s=v0)
    n = 5000
    outs = run(make(params), np.full(n, i))
    th, v = angles(outs), velocities(outs)
    ref_th, ref_v = stick_slip_reference(params, i, np.arange(1, n + 1) * T)
    nz = v[v != 0.0]
    assert np.count_nonzero(np.diff(np.sign(nz))) >= 2
    assert np.all(v[-500:] == 0.0)
    assert_allclose(th, ref_th, rtol=0, atol=2e-11)
    assert_allclose(v, ref_v, rtol=0, atol=1e-10)
    # Stuck exactly where scipy sticks: zero velocity on the same samples.
    assert np.array_equal(v == 0.0, ref_v == 0.0)


def test_pendulum_with_friction_rests_where_energy_balance_says() -> None:
    # D = 0: between turning points only Coulomb friction dissipates, so
    # consecutive turning angles satisfy U (cos th_b - cos th_a) = C |th_a - th_b|
    # exactly; the table sticks at the first turning point with U |sin th| <= C
    # (here the 8th, -0.0122 rad, after 6 reversals).
    th0 = 1.0
    params = replace(QUIET, damping_Nms_per_rad=0.0, initial_angle_rad=th0)
    turns = [th0]
    while U * abs(math.sin(turns[-1])) > C:
        r = abs(turns[-1])

        def balance(y: float, r: float = r) -> float:
            # Energy at the next turning point y (mirrored so the last one is +r).
            return U * (math.cos(y) - math.cos(r)) - C * (r - y)

        y = scipy.optimize.brentq(balance, -r, math.asin(C / U), xtol=1e-15, rtol=1e-14)
        turns.append(math.copysign(1.0, turns[-1]) * y)
    outs = run(make(params), np.zeros(10000))
    th, v = angles(outs), velocities(outs)
    # Motion reverses len(turns) - 2 times, then stays exactly at rest.
    nz = v[v != 0.0]
    reversals = int(np.count_nonzero(np.diff(np.sign(nz))))
    assert reversals == len(turns) - 2
    assert np.all(v[-1000:] == 0.0)
    assert np.all(th[-1000:] == th[-1])
    assert_allclose(th[-1], turns[-1], rtol=0, atol=1e-12)


def test_noise_is_uniform_bounded_and_seeded() -> None:
    noise = 1e-5
    params = TiltingTableParams(noise_rad=noise, initial_angle_rad=0.0)  # sticks at th = 0
    outs = run(make(params, seed=1), np.zeros(5000))
    err = np.array([o.encoder_rad - o.angle_rad for o in outs])
    assert np.all(angles(outs) == 0.0)
    assert np.all(np.abs(err) <= noise)
    assert err.max() > 0.99 * noise and err.min() < -0.99 * noise
    sigma = noise / math.sqrt(3.0)
    assert abs(err.mean()) < 5 * sigma / math.sqrt(err.size)
    assert_allclose(err.std(), sigma, rtol=0.05)
    # Independent draws: no lag-1 correlation.
    assert abs(np.corrcoef(err[1:], err[:-1])[0, 1]) < 5 / math.sqrt(err.size)
    # Same seed: bit-for-bit; other seed: different.
    again = run(make(params, seed=1), np.zeros(5000))
    assert [o.encoder_rad for o in again] == [o.encoder_rad for o in outs]
    other = run(make(params, seed=2), np.zeros(5000))
    assert [o.encoder_rad for o in other] != [o.encoder_rad for o in outs]


def test_output_is_idempotent_and_zero_noise_draws_nothing() -> None:
    plant = make(TiltingTableParams(noise_rad=1e-5))
    plant.step(0.5)
    assert plant.output() == plant.output()
    rng = np.random.default_rng(5)
    before = rng.bit_generator.state
    quiet = TiltingTablePlant(QUIET, rng=rng)
    o = quiet.step(0.5)
    assert o.encoder_rad == o.angle_rad
    assert rng.bit_generator.state == before


def test_full_model_is_deterministic_bit_for_bit() -> None:
    params = TiltingTableParams(initial_angle_rad=0.3)
    t = np.arange(3000) * T
    currents = 0.35 * np.sin(2 * np.pi * 1.5 * t) + 0.1 * np.sign(np.sin(2 * np.pi * 4 * t))
    a = run(make(params, seed=7), currents)
    b = run(make(params, seed=7), currents)
    assert a == b
    v = velocities(a)
    assert np.any(v == 0.0) and np.any(v > 0.0) and np.any(v < 0.0)  # sticks and slides


def test_reset_returns_to_initial_state() -> None:
    params = replace(QUIET, initial_angle_rad=0.4, initial_velocity_rad_s=0.2)
    plant = make(params)
    first = run(plant, np.full(50, 0.3))
    plant.reset()
    assert plant.step_index == 0
    o = plant.output()
    assert (o.angle_rad, o.velocity_rad_s, o.motor_torque_Nm) == (0.4, 0.2, 0.0)
    assert o.friction_force_N == C
    assert run(plant, np.full(50, 0.3)) == first


def test_quantised_encoder() -> None:
    res = 1e-4
    params = TiltingTableParams(noise_rad=2e-5, encoder_resolution_rad=res, initial_angle_rad=1.0)
    outs = run(make(params), np.full(400, 0.5))
    enc = np.array([o.encoder_rad for o in outs])
    counts = np.round(enc / res)
    assert_allclose(enc, counts * res, rtol=0, atol=1e-15)
    assert np.all(np.abs(enc - angles(outs)) <= res / 2 + 2e-5 + 1e-15)
    assert np.unique(counts).size > 10


def test_no_scale_no_translation() -> None:
    o = make(TiltingTableParams(initial_velocity_rad_s=1.0)).step(1.0)
    assert (o.scale_m, o.position_m, o.velocity_m_s) == (0.0, 0.0, 0.0)
    assert o.angle_rad != 0.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_current_limit_clips(sign: float) -> None:
    params = replace(QUIET, current_limit_A=2.0, torque_constant_Nm_per_A=0.8)
    big = run(make(params), np.full(100, sign * 1e3))
    at_limit = run(make(params), np.full(100, sign * 2.0))
    assert big == at_limit
    assert all(o.motor_torque_Nm == sign * 1.6 for o in big)


def test_nominal_is_the_linear_part() -> None:
    params = TiltingTableParams(torque_constant_Nm_per_A=0.9)
    n = nominal(params)
    assert n.as_kwargs() == {
        "inertia_kgm2": J,
        "damping_Nms_per_rad": D,
        "torque_constant_Nm_per_A": 0.9,
    }
    s = 2j * np.pi * 10.0
    assert_allclose(n.response(10.0), 0.9 / (J * s**2 + D * s), rtol=1e-14)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"inertia_kgm2": -1e-3}, "inertia_kgm2"),
        ({"inertia_kgm2": 0.0}, "inertia_kgm2"),
        ({"damping_Nms_per_rad": -1e-4}, "damping_Nms_per_rad"),
        ({"unbalance_Nm": -0.1}, "unbalance_Nm"),
        ({"coulomb_Nm": float("nan")}, "coulomb_Nm"),
        ({"torque_constant_Nm_per_A": 0.0}, "torque_constant_Nm_per_A"),
        ({"control_period_s": float("inf")}, "control_period_s"),
        ({"sim_step_s": 3e-5}, "sim_step_s"),
        ({"sim_step_s": 8e-4}, "sim_step_s"),
        ({"sim_step_s": -4e-5}, "sim_step_s"),
        ({"current_limit_A": 0.0}, "current_limit_A"),
        ({"initial_angle_rad": float("nan")}, "initial_angle_rad"),
        ({"initial_velocity_rad_s": float("-inf")}, "initial_velocity_rad_s"),
        ({"noise_rad": -1e-6}, "noise_rad"),
        ({"encoder_resolution_rad": float("nan")}, "encoder_resolution_rad"),
    ],
)
def test_bad_parameters_are_refused(changes: dict[str, float], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        TiltingTableParams(**changes)


def test_bad_inputs_are_refused() -> None:
    with pytest.raises(ConfigError, match="rng"):
        TiltingTablePlant(TiltingTableParams(), rng=None)
    plant = make(TiltingTableParams())
    with pytest.raises(SignalError, match="current_A"):
        plant.step(float("nan"))
    assert plant.step_index == 0


def test_outputs_are_plant_outputs_as_the_constructor_makes_them() -> None:
    """The per-sample outputs (base.plant_output) equal the dataclass's own, field for field."""
    import dataclasses

    plant = TiltingTablePlant(TiltingTableParams(), rng=np.random.default_rng(0))
    for out in [plant.output(), *run(plant, np.linspace(-2.0, 2.0, 50))]:
        values = {f.name: getattr(out, f.name) for f in dataclasses.fields(PlantOutput)}
        assert out == PlantOutput(**values)
        assert list(vars(out)) == list(values)
        with pytest.raises(dataclasses.FrozenInstanceError):
            out.step = 0  # type: ignore[misc]


def test_noise_drawn_in_blocks_is_the_draw_per_sample() -> None:
    """The encoder noise (drawn NOISE_DRAWS at a time) is Generator.random() once per sample."""
    from servo_axis.core.models.tilting_table import NOISE_DRAWS

    params = TiltingTableParams(noise_rad=1e-5, initial_angle_rad=0.0)
    outs = run(TiltingTablePlant(params, rng=np.random.default_rng(7)), np.zeros(3 * NOISE_DRAWS))
    outs.insert(0, TiltingTablePlant(params, rng=np.random.default_rng(7)).output())
    rng = np.random.default_rng(7)
    expected = [-1e-5 + (1e-5 - -1e-5) * rng.random() for _ in range(len(outs))]
    assert [o.encoder_rad for o in outs] == expected
