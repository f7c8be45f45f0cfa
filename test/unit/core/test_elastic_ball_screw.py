"""The elastic ball-screw plant of paper 004 against analytic results."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from servo_axis.core.errors import ConfigError
from servo_axis.core.models.base import PlantOutput
from servo_axis.core.models.elastic_ball_screw import (
    OUTPUT_FIELDS,
    ElasticBallScrewParams,
    ElasticBallScrewPlant,
    linearised_response,
    mode_warning,
    spring_energy_J,
)
from servo_axis.core.sensors import SensorParams

IDEAL = SensorParams(resolution=0.0)
#: No friction, ideal sensors: the linear part and the spring alone.
FRICTIONLESS = ElasticBallScrewParams(
    nut_friction_Nm=0.0, guide_friction_N=0.0, encoder=IDEAL, scale=IDEAL
)


def lumped_stiffness(p: ElasticBallScrewParams) -> float:
    """1 / (1/k_a + R^2/k_t), written out here rather than read from the model."""
    return 1.0 / (
        1.0 / p.axial_stiffness_N_per_m + p.lead_m_per_rad**2 / p.torsional_stiffness_Nm_per_rad
    )


def spring_law(delta: float, p: ElasticBallScrewParams) -> float:
    k = lumped_stiffness(p)
    g = p.contact_zone_m
    return k * delta - (1.0 - p.contact_stiffness_ratio) * k * g * math.tanh(delta / g)


def test_energy_is_conserved_without_losses() -> None:
    # No damping, no friction, an ideal current loop: the work of the motor
    # torque K_T i (th - th_0) is the kinetic energy plus the spring's.
    p = dataclasses.replace(
        FRICTIONLESS,
        motor_damping_Nms_per_rad=0.0,
        table_damping_Ns_per_m=0.0,
        screw_damping_Ns_per_m=0.0,
        current_bandwidth_hz=0.0,
    )
    plant = ElasticBallScrewPlant(p)
    current = 0.4
    for _ in range(400):
        plant.step(current)
    out = plant.output()
    kinetic = 0.5 * p.motor_inertia_kgm2 * out.velocity_rad_s**2
    kinetic += 0.5 * p.table_mass_kg * out.velocity_m_s**2
    potential = spring_energy_J(plant.deformation_m, p)
    work = p.torque_constant_Nm_per_A * current * out.angle_rad
    assert potential > 1e-6 * work  # far above the tolerance: the spring term counts
    assert_allclose(kinetic + potential, work, rtol=1e-9)


def test_spring_energy_is_the_integral_of_the_force() -> None:
    p = ElasticBallScrewParams()
    for delta in (-5e-6, -0.3e-6, 0.7e-6, 3e-6):
        integral, _ = __import__("scipy.integrate", fromlist=["quad"]).quad(
            spring_law, 0.0, delta, args=(p,), epsabs=1e-15
        )
        assert_allclose(spring_energy_J(delta, p), integral, rtol=1e-9)


def test_steady_deflection_under_the_guide_viscosity() -> None:
    # A constant current drives the axis to a constant velocity w with
    # K_T i = (B_m + C_t R^2) w; the screw then carries F = C_t R w, and the
    # deformation is the root of the spring law at F.
    p = FRICTIONLESS
    current = 2.0
    plant = ElasticBallScrewPlant(p)
    for _ in range(4000):  # 2 s, 50 time constants J_n / B_n
        plant.step(current)
    r = p.lead_m_per_rad
    w = (
        p.torque_constant_Nm_per_A
        * current
        / (p.motor_damping_Nms_per_rad + p.table_damping_Ns_per_m * r * r)
    )
    force = p.table_damping_Ns_per_m * r * w
    expected = brentq(lambda d: spring_law(d, p) - force, -1e-3, 1e-3, xtol=1e-18)
    assert_allclose(plant.output().velocity_rad_s, w, rtol=1e-9)
    assert_allclose(plant.deformation_m, expected, rtol=1e-7)
    assert expected > 2 * p.contact_zone_m  # out of the soft zone: k_h sets it


def test_linear_spring_static_deflection_is_force_over_stiffness() -> None:
    p = dataclasses.replace(FRICTIONLESS, contact_zone_m=0.0)
    plant = ElasticBallScrewPlant(p)
    for _ in range(4000):
        plant.step(-0.3)
    force = p.table_damping_Ns_per_m * plant.output().velocity_m_s
    assert_allclose(plant.deformation_m, force / lumped_stiffness(p), rtol=1e-7)


def _measured_response(p: ElasticBallScrewParams, freqs: list[float]) -> np.ndarray:
    """Torque -> motor angle of the simulated plant at ``freqs``, from a multisine."""
    tu = p.control_period_s
    n_total, n_window = 8000, 4000  # 4 s, the last 2 s analysed (whole periods)
    t = np.arange(n_total) * tu
    amps = [0.3 / len(freqs)] * len(freqs)
    current = sum(a * np.sin(2 * np.pi * f * t) for a, f in zip(amps, freqs, strict=True))
    plant = ElasticBallScrewPlant(p)
    angle = np.empty(n_total)
    for k in range(n_total):
        angle[k] = plant.output().angle_rad
        plant.step(float(current[k]))
    window = slice(n_total - n_window, n_total)
    spec_u = np.fft.rfft(current[window])
    spec_y = np.fft.rfft(angle[window])
    bins = [round(f * n_window * tu) for f in freqs]
    # The current is held over a period (ZOH): its average over the sample
    # that follows is what drives the axis; undo the half-sample delay.
    hold = [np.exp(-1j * np.pi * f * tu) * np.sinc(f * tu) for f in freqs]
    torque = p.torque_constant_Nm_per_A * spec_u[bins] * np.array(hold)
    return spec_y[bins] / torque


def test_low_frequency_response_matches_the_rigid_nominal_model() -> None:
    # 004 eq. (1): P = 1 / (J_n s^2 + B_n s), J_n = 2.6e-3, B_n = 0.070: the
    # issue asks for 10 %.
    p = dataclasses.replace(FRICTIONLESS, contact_zone_m=0.0)
    freqs = [1.0, 2.0, 5.0, 10.0, 20.0]
    measured = _measured_response(p, freqs)
    s = 2j * np.pi * np.array(freqs)
    nominal = 1.0 / (2.6e-3 * s**2 + 0.070 * s)
    rel = np.abs(measured / nominal - 1.0)
    assert np.all(rel < 0.10), rel
    # and to the independent two-inertia response (current loop at 1 kHz)
    lag = 1.0 / (1.0 + s / (2 * np.pi * p.current_bandwidth_hz))
    angle, _ = linearised_response(freqs, p)
    assert_allclose(measured, angle * lag, rtol=2e-3)


def test_first_axial_mode_is_the_resonance_of_the_two_inertia_model() -> None:
    p = ElasticBallScrewParams()
    assert 100.0 <= p.first_axial_mode_hz <= 200.0
    # Independent: the resonance of torque -> motor angle, undamped, is where
    # det [[J s^2 + R^2 k, -R k], [-R k, M s^2 + k]] = 0 besides s = 0.
    k = lumped_stiffness(p)
    j, m, r = p.motor_inertia_kgm2, p.table_mass_kg, p.lead_m_per_rad
    w = math.sqrt(k * (j + m * r * r) / (j * m))
    assert_allclose(p.first_axial_mode_hz, w / (2 * math.pi), rtol=1e-12)
    lossless = dataclasses.replace(
        p, motor_damping_Nms_per_rad=0.0, table_damping_Ns_per_m=0.0, screw_damping_Ns_per_m=0.0
    )
    freqs = np.linspace(50.0, 300.0, 250001)
    angle, _ = linearised_response(freqs, lossless)
    peak = freqs[np.argmax(np.abs(angle))]
    assert_allclose(peak, p.first_axial_mode_hz, atol=2e-3)
    assert mode_warning(p) is None
    soft = dataclasses.replace(p, axial_stiffness_N_per_m=2e7)
    warning = mode_warning(soft)
    assert warning is not None and "axial_stiffness_N_per_m" in warning


def test_rigid_body_of_the_defaults_is_the_nominal_model_of_eq_1() -> None:
    p = ElasticBallScrewParams()
    assert_allclose(p.rigid_inertia_kgm2, 2.6e-3, rtol=1e-3)
    assert_allclose(p.rigid_damping_Nms_per_rad, 0.070, rtol=1e-3)
    assert p.table_mass_kg == 273.0 and p.lead_m_per_rad == 1.91e-3


def test_friction_holds_the_axis_below_its_level_and_lets_go_above() -> None:
    # Pre-sliding: a torque below the total rolling friction moves the axis
    # by less than the pre-sliding width; well above it the axis runs away.
    p = ElasticBallScrewParams(encoder=IDEAL, scale=IDEAL)
    level_A = (p.nut_friction_Nm + p.guide_friction_N * p.lead_m_per_rad) / 0.715
    plant = ElasticBallScrewPlant(p)
    for _ in range(2000):
        plant.step(0.5 * level_A)
    out = plant.output()
    assert 0.0 < out.position_m < p.guide_presliding_m
    assert abs(out.velocity_m_s) < 1e-6
    plant.reset()
    for _ in range(2000):
        plant.step(2.0 * level_A)
    assert plant.output().position_m > 1e-3


def test_sensors_quantise_to_their_counts() -> None:
    plant = ElasticBallScrewPlant(ElasticBallScrewParams())
    for _ in range(300):
        out = plant.step(1.0)
    q_enc = 2 * math.pi / 2**20
    assert_allclose(out.encoder_rad / q_enc, round(out.encoder_rad / q_enc), atol=1e-6)
    assert_allclose(out.scale_m / 100e-9, round(out.scale_m / 100e-9), atol=1e-6)
    assert abs(out.encoder_rad - out.angle_rad) <= q_enc / 2
    assert abs(out.scale_m - out.position_m) <= 50e-9 + 1e-15


def test_the_outputs_are_plant_outputs_as_the_constructor_makes_them() -> None:
    # The plant fills each PlantOutput's __dict__ itself (its frozen __init__ is slow):
    # the result must be what the constructor makes of the same values.
    assert OUTPUT_FIELDS == tuple(f.name for f in dataclasses.fields(PlantOutput))
    plant = ElasticBallScrewPlant(ElasticBallScrewParams())
    for out in (plant.output(), plant.step(1.0), plant.step(-2.0)):
        values = {name: getattr(out, name) for name in OUTPUT_FIELDS}
        made = PlantOutput(**values)
        assert type(out) is PlantOutput
        assert out == made
        assert vars(out) == vars(made)
        assert list(vars(out)) == list(OUTPUT_FIELDS)
        assert repr(out) == repr(made)
        assert hash(out) == hash(made)
        with pytest.raises(dataclasses.FrozenInstanceError):
            out.step = 0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("field", "value", "expected"),
    [
        ("axial_stiffness_N_per_m", 0.0, "axial_stiffness_N_per_m: expected a value > 0"),
        ("axial_stiffness_N_per_m", -1e8, "axial_stiffness_N_per_m: expected a value > 0"),
        ("torsional_stiffness_Nm_per_rad", 0.0, "torsional_stiffness_Nm_per_rad"),
        ("contact_stiffness_ratio", 1.5, "contact_stiffness_ratio: expected a value in (0, 1]"),
        ("friction_elements", 0, "friction_elements: expected an integer in 1..200"),
        ("table_mass_kg", float("nan"), "table_mass_kg: expected a finite number"),
        ("sim_step_s", 0.3e-3, "control_period_s: expected a whole multiple"),
        ("sim_step_s", 0.5e-3, "sim_step_s: expected at most"),
    ],
)
def test_bad_parameters_are_refused_by_name(field: str, value: float, expected: str) -> None:
    with pytest.raises(ConfigError, match=expected.replace("(", r"\(").replace(")", r"\)")):
        ElasticBallScrewParams(**{field: value})
