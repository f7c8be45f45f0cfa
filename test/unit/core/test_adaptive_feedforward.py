"""Adaptive PTC and the multirate nonlinearity compensator of paper 003 (no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.core.errors import ConfigError
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.core.feedforward.mnc import MncParams, NonlinearityCompensator, friction_model_Nm
from servo_axis.core.feedforward.terms import ReferenceBlock
from servo_axis.core.models.base import NominalModel
from servo_axis.core.models.tilting_table import TiltingTableParams, TiltingTablePlant
from servo_axis.core.reference import SineReference
from servo_axis.core.timing import SampleGrid

TU = 4e-4
J, D, U, C = 50e-4, 130e-4, 0.3, 0.02
#: A smooth tilt that starts at rest: 0.6 + 0.5 sin(2 pi 0.5 s(t) - pi / 2), ramped.
TILT = SineReference(
    amplitude_m=0.5, frequency_hz=0.5, offset_m=0.6, phase_rad=-math.pi / 2, ramp_s=0.5
)


def block(steps: np.ndarray, reference: SineReference = TILT) -> ReferenceBlock:
    pos, vel, acc = reference.sample(steps * TU)
    return ReferenceBlock(step=steps, position_m=pos, velocity_m_s=vel, acceleration_m_s2=acc)


def test_friction_model_of_eq_14() -> None:
    w = np.array([-10.0, -1.0, -0.05, 0.0, 0.05, 1.0, 10.0])
    got = friction_model_Nm(w, coulomb_Nm=C, alpha=1e4, omega_th_rad_s=0.05)
    expected = [
        C / math.pi * (math.atan(1e4 * (x - 0.05)) + math.atan(1e4 * (x + 0.05))) for x in w
    ]
    assert_allclose(got, expected, rtol=1e-15)
    assert got[3] == 0.0  # odd: no friction at rest
    assert_allclose(got[[0, -1]], [-C, C], rtol=1e-4)  # +-C beyond the dead zone
    assert_allclose(got[[2, 4]], [-C / 2, C / 2], rtol=1e-3)  # half at its edge


def test_mnc_takes_the_interval_ends_and_its_schedule() -> None:
    mnc = NonlinearityCompensator(
        MncParams(unbalance_Nm=U, coulomb_Nm=C, torque_constant_Nm_per_A=0.5, control_period_s=TU),
        reference=TILT,
    )
    mnc.set_parameters(from_step=6, unbalance_Nm=0.2, coulomb_Nm=0.03)
    steps = np.arange(2, 12)
    got = mnc.currents(block(steps))
    for k, value in zip(steps, got, strict=True):
        at = k if k % 2 == 0 else k + 1  # eq. (13)/(15): [f(k), f(k + 2)] for k = 2i
        pos, vel, _ = TILT.sample(np.array([at * TU]))
        u, c = (U, C) if k < 6 else (0.2, 0.03)
        torque = u * math.sin(pos[0]) + c / math.pi * (
            math.atan(1e4 * (vel[0] - 0.05)) + math.atan(1e4 * (vel[0] + 0.05))
        )
        assert value == pytest.approx(torque / 0.5, rel=1e-13, abs=1e-16)
    marc = NonlinearityCompensator(
        MncParams(unbalance_Nm=U, coulomb_Nm=C, friction=False, control_period_s=TU),
        reference=TILT,
    )  # eq. (17): the unbalance only
    pos, _, _ = TILT.sample(np.array([4 * TU, 6 * TU]))
    assert_allclose(marc.currents(block(np.array([4, 5]))), U * np.sin(pos), rtol=1e-14)
    with pytest.raises(ConfigError, match="from_step: expected an integer after 6"):
        mnc.set_parameters(from_step=6, unbalance_Nm=0.1, coulomb_Nm=0.0)
    with pytest.raises(ConfigError, match="unbalance_Nm"):
        mnc.set_parameters(from_step=8, unbalance_Nm=math.nan, coulomb_Nm=0.0)
    with pytest.raises(ConfigError, match="alpha"):
        MncParams(alpha=0.0)


def generator(
    nominal: NominalModel, *, terms: list[object] = (), estimates: bool = False, **kw: int
) -> FeedforwardGenerator:
    return FeedforwardGenerator(
        reference=TILT,
        grid=SampleGrid(control_period_s=TU),
        lead_m_per_rad=1.0,
        nominal=nominal,
        terms=list(terms),  # type: ignore[arg-type]
        estimate_period_steps=10 if estimates else None,
        estimate_latency_steps=kw.get("latency", 10),
    )


def test_estimates_apply_from_their_step_and_nothing_runs_ahead() -> None:
    initial = NominalModel(
        inertia_kgm2=20e-4, damping_Nms_per_rad=100e-4, torque_constant_Nm_per_A=1.0
    )
    true = NominalModel(inertia_kgm2=J, damping_Nms_per_rad=D, torque_constant_Nm_per_A=1.0)
    gen = generator(initial, estimates=True, latency=20)
    assert gen.ready_until() == gen.next_estimate_step == 30  # R + latency
    first = gen.samples(0, 30)
    with pytest.raises(ConfigError, match="stop: samples from 30 on wait"):
        gen.samples(30, 31)
    with pytest.raises(ConfigError, match="from_step: expected the next estimate's step 30"):
        gen.set_estimate(
            40, inertia_kgm2=J, damping_Nms_per_rad=D, unbalance_Nm=0.0, coulomb_Nm=0.0
        )
    gen.set_estimate(30, inertia_kgm2=J, damping_Nms_per_rad=D, unbalance_Nm=0.0, coulomb_Nm=0.0)
    assert gen.ready_until() == 40
    after = gen.samples(30, 40)
    # Before its step the initial model, from it the estimate: exactly what a
    # generator built with each model from the start gives.
    assert first == generator(initial).samples(0, 30)
    assert after == generator(true).samples(0, 40)[30:]
    with pytest.raises(ConfigError, match="estimate_latency_steps: expected at least one"):
        generator(initial, estimates=True, latency=2)
    with pytest.raises(ConfigError, match="estimate_latency_steps: expected a whole number"):
        generator(initial, estimates=True, latency=15)


def run_open_loop(*, unbalance: float, period_s: float, seconds: float = 1.0) -> np.ndarray:
    """|theta - theta_d| at the T_r instants, feedforward only, model and U exact."""
    plant = TiltingTablePlant(
        TiltingTableParams(
            inertia_kgm2=J,
            damping_Nms_per_rad=D,
            unbalance_Nm=unbalance,
            coulomb_Nm=0.0,
            noise_rad=0.0,
            control_period_s=period_s,
            sim_step_s=period_s / 10,
            initial_angle_rad=float(TILT.sample(np.array([0.0]))[0][0]),
        ),
        rng=np.random.default_rng(0),
    )
    mnc = NonlinearityCompensator(
        MncParams(
            unbalance_Nm=unbalance, coulomb_Nm=0.0, friction=False, control_period_s=period_s
        ),
        reference=TILT,
    )
    gen = FeedforwardGenerator(
        reference=TILT,
        grid=SampleGrid(control_period_s=period_s),
        lead_m_per_rad=1.0,
        nominal=NominalModel(inertia_kgm2=J, damping_Nms_per_rad=D, torque_constant_Nm_per_A=1.0),
        terms=[mnc],
    )
    n = round(seconds / period_s)
    errors = []
    for k, (_, _, u_ff) in enumerate(gen.samples(0, n)):
        if k % 2 == 0:
            target = TILT.sample(np.array([k * period_s]))[0][0]
            errors.append(plant.output().angle_rad - target)
        plant.step(u_ff)
    return np.abs(np.array(errors))


def test_adaptive_ptc_with_the_true_model_tracks_at_the_reference_instants() -> None:
    # Linear part only: perfect tracking at every T_r instant, to rounding.
    assert np.max(run_open_loop(unbalance=0.0, period_s=TU)) < 1e-12
    # With the unbalance the MNC holds U sin(theta_d) over each sample, so the
    # error is that of a zero-order hold: small, and second order in T_u.
    e1 = np.max(run_open_loop(unbalance=U, period_s=TU))
    e2 = np.max(run_open_loop(unbalance=U, period_s=TU / 2))
    assert 0.0 < e1 < 1e-4
    assert 2.5 < e1 / e2 < 8.0, (e1, e2)


@pytest.mark.parametrize("friction", [True, False])
def test_mnc_per_chunk_values_equal_the_per_block_formulation(friction: bool) -> None:
    """``currents`` (sin and T_f kept per chunk, one U, C a block) = ``_currents`` bit for bit."""
    ref = SineReference(amplitude_m=0.6, frequency_hz=1.3, offset_m=0.1, phase_rad=0.4)
    params = MncParams(friction=friction, ratio=2, control_period_s=4e-4, lead_m_per_rad=1.0)
    fast = NonlinearityCompensator(params, reference=ref)
    plain = NonlinearityCompensator(params, reference=ref)
    rng = np.random.default_rng(2)
    k0 = 0
    while k0 < 9000:  # across GridSamples' chunks
        n = int(rng.integers(1, 40))
        k = np.arange(k0, k0 + n)
        z = np.zeros(n)
        block = ReferenceBlock(step=k, position_m=z, velocity_m_s=z, acceleration_m_s2=z)
        got, expected = fast.currents(block), plain._currents(k)
        assert got.dtype == expected.dtype and got.tobytes() == expected.tobytes()
        # Estimates from inside the next block (U, C change within it) or at its start.
        step = max(
            k0 + n + int(rng.integers(0, 2) * rng.integers(1, 30)), fast._schedule[-1][0] + 1
        )
        u, c = float(rng.random()), float(rng.random())
        for term in (fast, plain):
            term.set_parameters(from_step=step, unbalance_Nm=u, coulomb_Nm=c)
            term.forget_before(k0 + n)
        k0 += n


def test_ptc_inverse_is_numpys() -> None:
    """The PTC's direct inverse gufunc call equals np.linalg.inv, singular matrices included."""
    from servo_axis.core.feedforward.ptc import _inv2

    rng = np.random.default_rng(4)
    for _ in range(2000):
        b = rng.standard_normal((2, 2)) * 10.0 ** rng.integers(-8, 3)
        assert _inv2(b).tobytes() == np.linalg.inv(b).tobytes()
    with pytest.raises(np.linalg.LinAlgError):
        _inv2(np.zeros((2, 2)))


def test_after_the_estimates_stop_the_estimates_in_force_go_on() -> None:
    """The identifier fallback (``stop_estimates``) mid-block: the samples go on
    with the last estimate in force, as a generator built with it gives."""
    initial = NominalModel(
        inertia_kgm2=20e-4, damping_Nms_per_rad=100e-4, torque_constant_Nm_per_A=1.0
    )
    true = NominalModel(inertia_kgm2=J, damping_Nms_per_rad=D, torque_constant_Nm_per_A=1.0)

    def mnc() -> NonlinearityCompensator:
        return NonlinearityCompensator(
            MncParams(unbalance_Nm=U, coulomb_Nm=C, control_period_s=TU), reference=TILT
        )

    gen = generator(initial, terms=[mnc()], estimates=True, latency=20)
    gen.samples(0, 30)
    gen.set_estimate(30, inertia_kgm2=J, damping_Nms_per_rad=D, unbalance_Nm=0.2, coulomb_Nm=0.03)
    gen.samples(30, 37)  # into the estimate's period, not to its end
    gen.stop_estimates()
    assert gen.ready_until() is None
    got = gen.samples(37, 300)  # across the blocks that follow
    # Built with the estimate from the start: the same samples from 37 on.
    term = mnc()
    term.set_parameters(from_step=1, unbalance_Nm=0.2, coulomb_Nm=0.03)
    assert got == generator(true, terms=[term]).samples(0, 300)[37:]


def test_without_waiting_a_late_estimate_applies_from_the_first_instant_not_given() -> None:
    """Realtime (``stop_waiting_for_estimates``): samples past an estimate's step
    go on with the model in force; a late estimate applies from the next
    reference instant not given, a second late one an interval after it."""
    initial = NominalModel(
        inertia_kgm2=20e-4, damping_Nms_per_rad=100e-4, torque_constant_Nm_per_A=1.0
    )

    def model(scale: float) -> NominalModel:
        return NominalModel(
            inertia_kgm2=J * scale, damping_Nms_per_rad=D * scale, torque_constant_Nm_per_A=1.0
        )

    def mnc(u: float | None = None, c: float | None = None) -> NonlinearityCompensator:
        term = NonlinearityCompensator(
            MncParams(unbalance_Nm=U, coulomb_Nm=C, control_period_s=TU), reference=TILT
        )
        if u is not None and c is not None:
            term.set_parameters(from_step=1, unbalance_Nm=u, coulomb_Nm=c)
        return term

    def estimate(scale: float, u: float, c: float) -> dict[str, float]:
        return {
            "inertia_kgm2": J * scale,
            "damping_Nms_per_rad": D * scale,
            "unbalance_Nm": u,
            "coulomb_Nm": c,
        }

    gen = generator(initial, terms=[mnc()], estimates=True, latency=20)
    gen.stop_waiting_for_estimates()
    assert gen.ready_until() is None
    early = gen.samples(0, 37)  # past step 30, whose estimate is not in
    in_force = generator(initial, terms=[mnc()]).samples(0, 300)
    assert early == in_force[:37]
    # Sample 37 is the second of reference interval 18: the estimate applies
    # from instant 19, sample 38, and the generator keeps its schedule.
    assert gen.set_estimate(30, **estimate(1.0, 0.2, 0.03)) == 38
    assert gen.next_estimate_step == 40
    late = gen.samples(37, 300)
    assert late[0] == in_force[37]
    assert late[1:] == generator(model(1.0), terms=[mnc(0.2, 0.03)]).samples(0, 300)[38:]
    # Two more, both late, before any other sample is given.
    assert gen.set_estimate(40, **estimate(1.1, 0.25, 0.02)) == 300
    assert gen.set_estimate(50, **estimate(0.9, 0.28, 0.01)) == 302
    after = gen.samples(300, 400)
    assert after[:2] == generator(model(1.1), terms=[mnc(0.25, 0.02)]).samples(0, 302)[300:]
    assert after[2:] == generator(model(0.9), terms=[mnc(0.28, 0.01)]).samples(0, 400)[302:]
    # An estimate on time still applies from its own step.
    assert gen.set_estimate(60, **estimate(1.0, 0.3, 0.02)) == 400
    assert gen.set_estimate(70, **estimate(1.0, 0.3, 0.02)) == 402
