"""The ball-nut friction on the contact deformation (issue 21) and its frozen calibration.

Each calibration check of ``scripts/calibrate_contact.py`` is a test on the
shipped (frozen) contact scenarios, against paper 004's own data and never the
sigmoid-vs-GMS comparison: the slow loop of Fig. 4(b), the rigid model of eq.
(1), the first axial mode, eq. (8) before a fast stop and Fig. 11 before a slow
one, the nut's reversal with the deformation pattern (Sect. III-B), Fig. 6.
Core only: the plain-call loop (``scripts/ballnut.py`` on :func:`servo_axis.simulate.simulate`), no ROS.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from servo_axis.core.deformation import deformation_ratio
from servo_axis.core.errors import ConfigError
from servo_axis.core.models.ball_screw_kernels import contact_load
from servo_axis.core.models.elastic_ball_screw import (
    ElasticBallScrewParams,
    ElasticBallScrewPlant,
)
from servo_axis.core.sensors import SensorParams
from servo_axis.params import resolve
from servo_axis.params.scenario import load_scenario
from servo_axis.plugins.elastic_ball_screw import elastic_ball_screw_params

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "scripts"))
import ballnut as bn

CONFIG = Path(__file__).resolve().parents[3] / "src" / "servo_axis" / "scenarios"
IDEAL = SensorParams(resolution=0.0)
PAPER_SIGMA = 0.04e-6  # m^2/rad: 0.04 with z in mm and d_r in mm/rad (004 Fig. 13a)
IDENTIFIED_F0 = 0.4289  # N m: the GMS fit of the default plant (gms_elastic_ball_screw.txt)
FAST_STOP = 3000  # the reversal of x = 25 (1 - cos 2 pi t) mm at 1.5 s, T_u = 0.5 ms


def contact_params() -> ElasticBallScrewParams:
    """The frozen plant of the contact scenarios."""
    values = resolve.node_values(load_scenario(CONFIG / "fast_reversal_contact_gms.yaml"), "plant")
    return elastic_ball_screw_params(values)


def bare(name: str, tmp_path: Path, **everywhere: object) -> Path:
    """A shipped contact scenario without its compensation term."""
    ff = {"gms.enabled": False, "sigmoid.enabled": False}
    return bn.scenario_with(
        CONFIG / f"{name}.yaml", tmp_path / f"{name}.yaml", {"feedforward": ff, "/**": everywhere}
    )


@pytest.fixture(scope="module")
def fast(tmp_path_factory: pytest.TempPathFactory) -> bn.PlantTrace:
    tmp = tmp_path_factory.mktemp("fast")
    return bn.run_trace(bare("fast_reversal_contact_gms", tmp, duration_s=1.6))


@pytest.fixture(scope="module")
def slow_loop(tmp_path_factory: pytest.TempPathFactory) -> bn.PlantTrace:
    return bn.run_trace(CONFIG / "friction_id_contact.yaml")


# ------------------------------------------------------------------------- the model


def test_contact_load_solves_the_contact_law() -> None:
    k, travel, preload = 1.5e8, 19e-6, 80.0
    for d in (-60e-6, -19e-6, -1e-6, 0.0, 3e-7, 12e-6, 40e-6):
        for start in (0.0, -50.0, 1e6):
            y = contact_load(d, k, travel, preload, start)
            force = preload * y
            assert_allclose(force / k + travel * math.tanh(y), d, rtol=0.0, atol=1e-17)
    # no contact travel: a linear spring
    assert_allclose(80.0 * contact_load(2e-6, k, 0.0, 80.0, 0.0), k * 2e-6, rtol=1e-14)


def test_displacement_is_the_default_and_contact_needs_its_own_law() -> None:
    assert ElasticBallScrewParams().nut_friction == "displacement"
    with pytest.raises(ConfigError, match="nut_friction: expected one of displacement, contact"):
        ElasticBallScrewParams(nut_friction="balls")
    with pytest.raises(ConfigError, match="bearing_friction_Nm: expected 0 with nut_friction"):
        ElasticBallScrewParams(bearing_friction_Nm=0.1)
    with pytest.raises(ConfigError, match="contact_zone_m: expected 0 with nut_friction contact"):
        ElasticBallScrewParams(nut_friction="contact")
    with pytest.raises(ConfigError, match="contact_presliding_m: expected below contact_travel_m"):
        ElasticBallScrewParams(
            nut_friction="contact",
            contact_zone_m=0.0,
            contact_travel_m=1e-6,
            contact_presliding_m=2e-6,
        )


def test_static_load_deforms_the_contact_by_its_law() -> None:
    # At constant velocity without friction the screw carries C_t v, and
    # delta = F / k_h + D tanh(F / F_p) (the contact in series with k_h).
    p = dataclasses.replace(
        contact_params(),
        nut_friction_Nm=0.0,
        bearing_friction_Nm=0.0,
        guide_friction_N=0.0,
        encoder=IDEAL,
        scale=IDEAL,
    )
    plant = ElasticBallScrewPlant(p)
    for _ in range(4000):
        plant.step(0.4)
    force = p.table_damping_Ns_per_m * plant.output().velocity_m_s
    expected = force / p.stiffness_N_per_m + p.contact_travel_m * math.tanh(force / p.nut_preload_N)
    assert_allclose(plant.deformation_m, expected, rtol=1e-6)
    assert_allclose(plant.spring_force_N, force, rtol=1e-6)
    assert_allclose(
        plant.contact_deformation_m,
        p.contact_travel_m * math.tanh(force / p.nut_preload_N),
        rtol=1e-6,
    )
    assert 0.2 < force / p.nut_preload_N < 3.0  # inside the flank change: the law counts


# ------------------------------------------------------------ the frozen calibration


def test_slow_reversal_loop_is_fig_4b(slow_loop: bn.PlantTrace) -> None:
    # 50 um, 0.05 Hz: F_0 as identified on the default plant, pre-sliding about 15 um.
    loop = bn.presliding_loop(
        slow_loop, inertia_kgm2=2.6e-3, damping_Nms_per_rad=0.070, fraction=0.975
    )
    print(
        f"F_0 {loop.coulomb_Nm:.4f} N m, pre-sliding {[round(d * 1e6, 2) for d in loop.presliding_m]} um"
    )
    assert_allclose(loop.coulomb_Nm, IDENTIFIED_F0, rtol=0.03)
    assert len(loop.presliding_m) == 2
    assert_allclose(loop.presliding_m, 15e-6, rtol=0.2)


def test_rigid_model_in_motion_is_eq_1() -> None:
    # The FRF torque -> motor angle at 1-20 Hz on top of a steady 40 mm/s (the
    # contact loaded on one flank, friction constant), least-squares J s^2 + B s:
    # J_n = 2.6e-3, B_n = 0.070 within 10 % (004 eq. (1), Fig. 3).
    p = dataclasses.replace(contact_params(), encoder=IDEAL, scale=IDEAL)
    tu = p.control_period_s
    n_total, n_window = 8000, 4000
    t = np.arange(n_total) * tu
    freqs = np.array([1.0, 2.0, 5.0, 10.0, 20.0])
    w0 = 0.04 / p.lead_m_per_rad
    steady = p.rigid_damping_Nms_per_rad * w0 + p.nut_friction_Nm + p.bearing_friction_Nm
    steady_A = (steady + p.guide_friction_N * p.lead_m_per_rad) / p.torque_constant_Nm_per_A
    ac = sum(0.06 * np.sin(2 * np.pi * f * t) for f in freqs)
    driven, reference = ElasticBallScrewPlant(p), ElasticBallScrewPlant(p)
    angle = np.empty(n_total)
    slowest = np.inf
    for k in range(n_total):
        angle[k] = driven.output().angle_rad - reference.output().angle_rad
        slowest = min(slowest, driven.output().velocity_m_s if k > 2000 else np.inf)
        driven.step(float(steady_A + ac[k]))
        reference.step(float(steady_A))
    assert slowest > 0.03  # never near a reversal: the friction stays constant
    window = slice(n_total - n_window, n_total)
    bins = np.rint(freqs * n_window * tu).astype(int)
    hold = np.exp(-1j * np.pi * freqs * tu) * np.sinc(freqs * tu)
    s = 2j * np.pi * freqs
    lag = 1.0 / (1.0 + s / (2 * np.pi * p.current_bandwidth_hz))
    response = np.fft.rfft(angle[window])[bins] / (
        p.torque_constant_Nm_per_A * np.fft.rfft(ac[window])[bins] * hold * lag
    )
    inverse = 1.0 / response
    design = np.vstack(
        [np.concatenate([(s**2).real, (s**2).imag]), np.concatenate([s.real, s.imag])]
    )
    j, b = np.linalg.lstsq(design.T, np.concatenate([inverse.real, inverse.imag]), rcond=None)[0]
    print(f"J {j:.4e} kg m^2, B {b:.4f} N m s/rad")
    assert_allclose([j, b], [2.6e-3, 0.070], rtol=0.10)


def test_first_axial_mode_is_within_100_200_hz() -> None:
    p = contact_params()
    assert 100.0 <= p.first_axial_mode_hz <= 200.0
    # the loaded stiffness of the contact plant is the default plant's
    assert_allclose(p.stiffness_N_per_m, ElasticBallScrewParams().stiffness_N_per_m, rtol=0)


def test_d_r_before_a_fast_stop_follows_eq_8(fast: bn.PlantTrace) -> None:
    fit = bn.sigma_fit(fast, FAST_STOP)
    print(f"sigma {fit.sigma_m2_per_rad * 1e6:.4f} mm^2/rad over {fit.z_m.size} samples")
    assert fit.z_m.size >= 20
    assert PAPER_SIGMA / 2 <= fit.sigma_m2_per_rad <= 2 * PAPER_SIGMA
    # and it is a 1 / z law: d_r grows tenfold from z = 150 to 15 um
    near = fit.d_r_m_per_rad[fit.z_m < 20e-6].mean()
    far = fit.d_r_m_per_rad[fit.z_m > 120e-6].mean()
    assert near > 8 * far > 0.0


def test_d_r_before_a_slow_stop_stays_within_the_counts(tmp_path: Path) -> None:
    # 004 Fig. 11: before a slow stop d_r "almost remains constant"; here it
    # stays inside what the encoder and scale counts allow over the window.
    trace = bn.run_trace(bare("slow_reversal_contact_gms", tmp_path))
    dr = deformation_ratio(
        trace.encoder_rad,
        trace.scale_m,
        window_samples=10,
        lead_m_per_rad=trace.lead_m_per_rad,
        min_rotation_rad=1e-3,
    )
    bound = (100e-9 + trace.lead_m_per_rad * 2 * math.pi / 2**20) / 1e-3
    for stop in (1000, 3000):
        seg = slice(stop - 400, stop)
        valid = dr.valid[seg]
        assert valid.sum() > 300
        assert np.abs(dr.d_r_m_per_rad[seg][valid]).max() <= bound


def test_nut_friction_reverses_before_a_fast_stop_and_after_a_slow_one(
    fast: bn.PlantTrace, slow_loop: bn.PlantTrace
) -> None:
    # 004 Sect. III-B: at a high deceleration the load changes flank (Pattern
    # I -> II) before the stop and T_f reverses with it; at a low one after it.
    before = fast.nut_Nm[FAST_STOP - 200 : FAST_STOP - 20]
    crossed = np.nonzero(np.diff(np.sign(before)))[0]
    assert crossed.size == 1
    assert fast.nut_Nm[FAST_STOP - 200] > 0.09 and fast.nut_Nm[FAST_STOP - 20] < -0.09
    # the bearings and the guide reverse only with the motion
    assert fast.bearing_Nm[FAST_STOP - 20] > 0.09 and fast.guide_N[FAST_STOP - 20] > 110.0
    stop = 20000  # friction_id: the reference reverses at 10 s
    window = slow_loop.nut_Nm[stop - 8000 : stop + 8000]
    crossings = np.nonzero(np.diff(np.sign(window)))[0] - 8000
    assert crossings.size == 1 and crossings[0] > 0


def test_gms_is_worse_at_the_fast_reversal_than_at_the_slow_one() -> None:
    # 004 Fig. 6: the GMS model, identified on slow reversals, loses at the fast one.
    errors = {}
    for name in ("slow_reversal_contact_gms", "fast_reversal_contact_gms"):
        trace = bn.run_trace(CONFIG / f"{name}.yaml")
        errors[name] = np.abs(trace.error_m[len(trace.error_m) // 2 :]).max()
    print({k: f"{v * 1e6:.3f} um" for k, v in errors.items()})
    assert errors["fast_reversal_contact_gms"] > 1.1 * errors["slow_reversal_contact_gms"]
