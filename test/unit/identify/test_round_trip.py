"""Round trip on every shipped plant model: measured (plain calls), identified, compared with the truth.

The ``measure_*`` scenarios hold an axis whose keys differ from the presets,
with encoder (and scale) quantisation and noise on. The runs are the
plain-call loops of :mod:`servo_axis.simulate`, which the node graph
reproduces bit for bit (the commands of docs/how-to/identify-your-axis.md
run the ball screw's through it: test/integration/test_docs_pages.py). Each
key is compared with the scenario's own value, the fitted response with the
true model's, the fitted scenario with the axis on a
held-out run, and the suite's controllers on both.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from servo_axis.core.sysid import fit as sysfit
from servo_axis.identify.data import Record, from_simulation
from servo_axis.identify.driver import IdentifyError, identify
from servo_axis.identify.writer import scenario_of
from servo_axis.params.scenario import find_scenario, load_scenario
from servo_axis.simulate import simulate

#: Relative tolerance of every identified key ("a few percent").
KEY_RTOL = 0.03


def _record(name: str) -> Record:
    return from_simulation(find_scenario(name))


def _plant(name: str) -> dict[str, Any]:
    return dict(load_scenario(find_scenario(name))["plant"]["ros__parameters"])


def _rms_error(scenario: dict[str, Any], tmp: Path, name: str) -> float:
    """RMS of reference - encoder (rad) of the plain-call loop of ``scenario``."""
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    traj = simulate(path)
    return float(np.sqrt(np.mean((traj.reference_rad - traj.encoder_rad) ** 2)))


def _controllers(
    base: dict[str, Any], kinds: dict[str, dict[str, Any]]
) -> dict[str, dict[str, Any]]:
    """``base`` with each controller's feedback and feedforward keys set."""
    out = {}
    for name, keys in kinds.items():
        s = copy.deepcopy(base)
        for section, values in keys.items():
            s[section]["ros__parameters"].update(values)
        out[name] = s
    return out


def _check_controllers(
    fitted: dict[str, Any], true: dict[str, Any], kinds: dict[str, dict[str, Any]], tmp: Path
) -> dict[str, tuple[float, float]]:
    """Each controller's RMS error on the fitted and on the true plant; within 2x of each other."""
    out = {}
    fit_runs = _controllers(fitted, kinds)
    true_runs = _controllers(true, kinds)
    for name in kinds:
        e_fit = _rms_error(fit_runs[name], tmp, f"fit_{name}")
        e_true = _rms_error(true_runs[name], tmp, f"true_{name}")
        out[name] = (e_fit, e_true)
        assert 0.5 <= e_fit / e_true <= 2.0, (name, e_fit, e_true)
    return out


# --------------------------------------------------------------------------- ball_screw


@pytest.fixture(scope="module")
def ball_screw() -> tuple[Any, dict[str, Record]]:
    runs = {
        n: _record(n)
        for n in (
            "measure_frf_ball_screw",
            "measure_reversal_ball_screw",
            "measure_small_reversals_ball_screw",
            "measure_sine_ball_screw",
        )
    }
    ident = identify(
        "ball_screw",
        [runs["measure_frf_ball_screw"]],
        friction=[runs["measure_reversal_ball_screw"], runs["measure_small_reversals_ball_screw"]],
        validation=runs["measure_sine_ball_screw"],
    )
    return ident, runs


def test_ball_screw_keys_round_trip(ball_screw: tuple[Any, dict[str, Record]]) -> None:
    ident, _ = ball_screw
    true = _plant("measure_frf_ball_screw")
    expect = {
        "inertia_kgm2": true["inertia_kgm2"],
        "damping_Nms_per_rad": true["damping_Nms_per_rad"],
        "dead_time_s": true["dead_time_s"],
        "friction.rolling_coulomb_Nm": true["friction"]["rolling_coulomb_Nm"],
        "friction.presliding_width_m": true["friction"]["presliding_width_m"],
    }
    for i, (f, z, a) in enumerate(
        zip(*(true["modes"][k] for k in ("frequency_hz", "zeta", "a")), strict=True)
    ):
        expect.update({f"modes.frequency_hz[{i}]": f, f"modes.zeta[{i}]": z, f"modes.a[{i}]": a})
    for key, value in expect.items():
        assert_allclose(ident.key(key).value, value, rtol=KEY_RTOL, err_msg=key)
    # The plant's Coulomb level is 0: found so, to a small fraction of the rolling level.
    assert (
        abs(ident.key("friction.coulomb_Nm").value) < 0.01 * expect["friction.rolling_coulomb_Nm"]
    )


def test_ball_screw_response_within_1_db_and_5_deg(
    ball_screw: tuple[Any, dict[str, Record]],
) -> None:
    ident, _ = ball_screw
    true = _plant("measure_frf_ball_screw")
    frf = ident.responses["encoder"]
    values = {
        "inertia_kgm2": true["inertia_kgm2"],
        "damping_Nms_per_rad": true["damping_Nms_per_rad"],
        "dead_time_s": true["dead_time_s"],
    }
    modes = list(zip(*(true["modes"][k] for k in ("frequency_hz", "zeta", "a")), strict=True))
    for i, (f, z, a) in enumerate(modes):
        values.update({f"modes.frequency_hz[{i}]": f, f"modes.zeta[{i}]": z, f"modes.a[{i}]": a})
    exact = sysfit.rigid_modes_response(
        values, frf.frequency_hz, modes=len(modes), control_period_s=5e-4
    )
    upto = frf.frequency_hz <= 2.0 * modes[0][0]
    ratio = ident.fitted["encoder"][upto] / exact[upto]
    # Against the true response: far inside the 1 dB / 5 deg of the issue.
    assert np.max(np.abs(20 * np.log10(np.abs(ratio)))) < 0.1
    assert np.max(np.abs(np.degrees(np.angle(ratio)))) < 0.5
    # Against the measurement, on its well-measured lines of the whole band (issue 41:
    # the claim's range stopped at twice the first mode, short of the 430 Hz one).
    fit = ident.bode["encoder"]
    assert fit.db < 1.0 and fit.deg < 5.0
    rel = frf.std / np.abs(frf.response)
    good = (frf.coherence >= 0.9) & (rel <= 0.02)  # independently of well_measured
    assert fit.lines == int(good.sum()) and (fit.from_hz, fit.to_hz) == (
        frf.frequency_hz[good].min(),
        frf.frequency_hz[good].max(),
    )
    assert fit.from_hz == 2.0 and fit.to_hz > 2.5 * modes[0][0]
    misfit = ident.fitted["encoder"][good] / frf.response[good]
    assert_allclose(fit.db, np.max(np.abs(20 * np.log10(np.abs(misfit)))), rtol=1e-12)
    assert_allclose(fit.deg, np.max(np.abs(np.degrees(np.angle(misfit)))), rtol=1e-12)
    # The second mode's lines are too spread for the claim: said, with how the fit meets them.
    second = ident.key("modes.frequency_hz[1]").value
    assert second > fit.to_hz
    note = next(n for n in ident.notes if n.startswith("Bode encoder: the fitted mode(s)"))
    beyond = (frf.coherence >= 0.9) & (frf.frequency_hz > fit.to_hz)
    sigmas = np.abs(ident.fitted["encoder"][beyond] / frf.response[beyond] - 1) / rel[beyond]
    assert f"at {second:.4g} Hz lie outside the lines of the claim" in note
    assert (
        f"within {np.max(sigmas):.2g} standard deviations of each of the {beyond.sum()} lines"
        in note
    )
    assert np.max(sigmas) < 4.0  # the fit is as good there as the measurement


def test_the_report_draws_the_bode_in_db_and_deg_with_error_bars_and_the_residual(
    ball_screw: tuple[Any, dict[str, Record]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """issue 41 item 4 (its Bode part), issue 43: the figures' axes from matplotlib's objects."""
    import matplotlib.pyplot as plt

    from servo_axis.identify.report import summary_text, write_report

    ident, runs = ball_screw
    kept: list[Any] = []
    monkeypatch.setattr(plt, "close", kept.append)
    write_report(tmp_path, ident)
    monkeypatch.undo()
    bode, _friction, validation = kept
    mag, ph, res_db, res_deg, coh = bode.axes
    assert [a.get_ylabel() for a in bode.axes] == [
        "|P| (dB re 1 rad/(N m))", "phase (deg)", "fit / measured (dB)",
        "fit - measured (deg)", "coherence",
    ]  # fmt: skip
    assert coh.get_xlabel() == "frequency (Hz)"
    assert "within 0." in mag.get_title() and "dB" in mag.get_title()
    frf = ident.responses["encoder"]
    rel = frf.std / np.abs(frf.response)
    good = (frf.coherence >= 0.9) & (rel <= 0.02)
    # The compared lines (the second errorbar of each panel): dB and deg, error bars of
    # one standard deviation to first order, 20 log10(e) std/|P| dB and std/|P| rad.
    for panel, value, spread in (
        (mag, 20 * np.log10(np.abs(frf.response)), 20 / np.log(10) * rel),
        (
            res_db,
            20 * np.log10(np.abs(ident.fitted["encoder"] / frf.response)),
            20 / np.log(10) * rel,
        ),
        (res_deg, np.degrees(np.angle(ident.fitted["encoder"] / frf.response)), np.degrees(rel)),
    ):
        line, _caps, (bars,) = panel.containers[1]
        assert_allclose(line.get_xdata(), frf.frequency_hz[good])
        assert_allclose(line.get_ydata(), value[good], rtol=1e-12, atol=1e-9)
        half = np.array([abs(seg[1, 1] - seg[0, 1]) / 2 for seg in bars.get_segments()])
        assert_allclose(half, spread[good], rtol=1e-9)
    fitted = next(x for x in mag.get_lines() if x.get_label() == "fitted model")
    assert_allclose(fitted.get_ydata(), 20 * np.log10(np.abs(ident.fitted["encoder"])))
    # The phase measured and fitted on one branch: never 360 deg apart.
    measured_phase = ph.containers[1][0].get_ydata()
    fitted_phase = next(x for x in ph.get_lines() if x.get_label() == "fitted model").get_ydata()
    assert np.max(np.abs(measured_phase - fitted_phase[good])) < 180.0
    # The validation: the tracking error at the table in um, from the held-out run's own
    # arrays (semi-closed loop: r - encoder at the motor, times the lead).
    (ax,) = validation.axes
    assert ax.get_ylabel() == "tracking error (um)"
    held_out = runs["measure_sine_ball_screw"]
    lead = held_out.lead_m_per_rad
    error_m = lead * (held_out.reference_rad - held_out.encoder_rad)
    measured = ax.get_lines()[0].get_ydata()
    assert_allclose(measured, 1e6 * error_m, rtol=1e-9, atol=1e-9)
    v = ident.validation
    assert v is not None and v.unit == "m"
    assert_allclose(v.rms_error_measured, np.sqrt(np.mean(error_m**2)), rtol=1e-12)
    line = next(x for x in summary_text(ident).splitlines() if x.startswith("validation"))
    assert f"RMS tracking error measured {1e6 * v.rms_error_measured:.4g} um" in line
    for fig in kept:
        plt.close(fig)


def test_ball_screw_validation_and_controllers(
    ball_screw: tuple[Any, dict[str, Record]], tmp_path: Path
) -> None:
    ident, runs = ball_screw
    v = ident.validation
    assert v is not None
    assert v.nrmse_error < 0.05 and v.nrmse_position < 1e-4
    assert_allclose(v.rms_error_fitted, v.rms_error_measured, rtol=0.05)
    held_out = runs["measure_sine_ball_screw"]
    fitted = scenario_of(ident, held_out, name="fitted")
    kinds = {
        "pid": {"feedback": {"use_feedforward": False}, "feedforward": {"ptc": {"enabled": False}}},
        "pid_ptc": {},
        "pid_ptc_dob": {"feedback": {"dob": {"enabled": True, "cutoff_hz": 80.0}}},
    }
    _check_controllers(fitted, held_out.scenario, kinds, tmp_path)


def test_modes_beyond_the_band_are_named_not_hidden(tmp_path: Path) -> None:
    """The preset's three modes at T_u = 0.5 ms, band to 450 Hz: 520 and 1100 Hz cannot be had."""
    scenario = load_scenario(find_scenario("measure_frf_ball_screw"))
    plant = scenario["plant"]["ros__parameters"]
    plant["modes"] = {
        "frequency_hz": [180.0, 520.0, 1100.0],
        "zeta": [0.05, 0.03, 0.02],
        "a": [0.3, -0.2, 0.1],
    }
    path = tmp_path / "preset_modes.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    ident = identify("ball_screw", [from_simulation(path)])
    note = next(n for n in ident.notes if n.startswith("modes.*"))
    assert "520, 1100 Hz" in note and "above the excitation band (max 450 Hz" in note
    assert "Nyquist 1000 Hz" in note
    # What is in the band still comes out.
    assert_allclose(ident.key("modes.frequency_hz[0]").value, 180.0, rtol=KEY_RTOL)
    assert_allclose(ident.key("inertia_kgm2").value, plant["inertia_kgm2"], rtol=KEY_RTOL)


# --------------------------------------------------------------------------- elastic_ball_screw


@pytest.fixture(scope="module")
def elastic() -> tuple[Any, dict[str, Record]]:
    runs = {
        n: _record(n)
        for n in (
            "measure_frf_elastic_ball_screw",
            "measure_reversal_elastic_ball_screw",
            "measure_sine_elastic_ball_screw",
        )
    }
    ident = identify(
        "elastic_ball_screw",
        [runs["measure_frf_elastic_ball_screw"]],
        friction=[runs["measure_reversal_elastic_ball_screw"]],
        validation=runs["measure_sine_elastic_ball_screw"],
    )
    return ident, runs


def test_elastic_keys_round_trip(elastic: tuple[Any, dict[str, Record]]) -> None:
    ident, _ = elastic
    true = _plant("measure_frf_elastic_ball_screw")
    r = 0.00191
    series = 1.0 / (
        1.0 / true["axial_stiffness_N_per_m"] + r * r / true["torsional_stiffness_Nm_per_rad"]
    )
    expect = {
        k: true[k]
        for k in (
            "motor_inertia_kgm2",
            "motor_damping_Nms_per_rad",
            "table_mass_kg",
            "table_damping_Ns_per_m",
            "screw_damping_Ns_per_m",
            "current_bandwidth_hz",
            "axial_stiffness_N_per_m",
            "nut_friction_Nm",
            "guide_friction_N",
            "nut_presliding_m",
            "guide_presliding_m",
        )
    }
    expect["series_stiffness_N_per_m"] = series
    for key, value in expect.items():
        assert_allclose(ident.key(key).value, value, rtol=KEY_RTOL, err_msg=key)
    # Where the data cannot split a pair, the report says so.
    assert any(n.startswith("axial_stiffness_N_per_m, torsional") for n in ident.notes)


def test_elastic_responses_and_validation(
    elastic: tuple[Any, dict[str, Record]], tmp_path: Path
) -> None:
    ident, runs = elastic
    true = _plant("measure_frf_elastic_ball_screw")
    r = 0.00191
    values = {
        "motor_inertia_kgm2": true["motor_inertia_kgm2"],
        "motor_damping_Nms_per_rad": true["motor_damping_Nms_per_rad"],
        "table_mass_kg": true["table_mass_kg"],
        "table_damping_Ns_per_m": true["table_damping_Ns_per_m"],
        "stiffness_N_per_m": 1.0
        / (1.0 / true["axial_stiffness_N_per_m"] + r * r / true["torsional_stiffness_Nm_per_rad"]),
        "screw_damping_Ns_per_m": true["screw_damping_Ns_per_m"],
        "current_bandwidth_hz": true["current_bandwidth_hz"],
    }
    f = ident.responses["encoder"].frequency_hz
    exact = sysfit.two_inertia_response(values, f, lead_m_per_rad=r, control_period_s=5e-4)
    from servo_axis.core.sysid.models import axial_mode_hz

    mode = axial_mode_hz(
        motor_inertia_kgm2=values["motor_inertia_kgm2"],
        table_mass_kg=values["table_mass_kg"],
        stiffness_N_per_m=values["stiffness_N_per_m"],
        lead_m_per_rad=r,
    )
    for i, sensor in enumerate(("encoder", "scale")):
        fit = ident.bode[sensor]
        assert fit.db < 1.0 and fit.deg < 5.0, sensor
        # The claim over every well-measured line of the band, the axial mode's among them.
        assert fit.from_hz == 2.0 and fit.to_hz > mode, sensor
        upto = f <= 2.0 * mode
        ratio = ident.fitted[sensor][upto] / exact[i][upto]
        assert np.max(np.abs(20 * np.log10(np.abs(ratio)))) < 0.1, sensor
        assert np.max(np.abs(np.degrees(np.angle(ratio)))) < 0.5, sensor
    v = ident.validation
    assert v is not None and v.nrmse_error < 0.05
    held_out = runs["measure_sine_elastic_ball_screw"]
    fitted = scenario_of(ident, held_out, name="fitted")
    kinds = {
        "pid_ptc": {},
        "pid_ptc_dob": {
            "feedback": {"dob": {"enabled": True, "cutoff_hz": 80.0, "sensor": "encoder"}}
        },
    }
    _check_controllers(fitted, held_out.scenario, kinds, tmp_path)


# --------------------------------------------------------------------------- tilting_table


@pytest.fixture(scope="module")
def tilting() -> tuple[Any, dict[str, Record]]:
    runs = {n: _record(n) for n in ("measure_tilting_table", "measure_sine_tilting_table")}
    ident = identify(
        "tilting_table",
        [runs["measure_tilting_table"]],
        validation=runs["measure_sine_tilting_table"],
    )
    return ident, runs


def test_tilting_table_round_trip(tilting: tuple[Any, dict[str, Record]], tmp_path: Path) -> None:
    ident, runs = tilting
    true = _plant("measure_tilting_table")
    for key in ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm", "coulomb_Nm"):
        k = ident.key(key)
        assert_allclose(k.value, true[key], rtol=KEY_RTOL, err_msg=key)
        assert abs(k.value - true[key]) < 4 * k.std, key
    v = ident.validation
    assert v is not None and v.nrmse_error < 0.05
    # A rotary table's tracking error in rad: r - y of the held-out run itself.
    held_out = runs["measure_sine_tilting_table"]
    assert v.unit == "rad"
    error_rad = held_out.reference_rad - held_out.encoder_rad
    assert_allclose(v.rms_error_measured, np.sqrt(np.mean(error_rad**2)), rtol=1e-12)
    from servo_axis.identify.report import summary_text

    assert f"measured {v.rms_error_measured:.4g} rad, fitted" in summary_text(ident)
    fitted = scenario_of(ident, held_out, name="fitted")
    kinds = {
        "pid": {"feedforward": {"ptc": {"enabled": False}}},
        "pid_ptc": {},
        "pid_ptc_mnc": {"feedforward": {"mnc": {"enabled": True}}},
    }
    _check_controllers(fitted, held_out.scenario, kinds, tmp_path)


# --------------------------------------------------------------------------- bad input


def test_bad_input_is_one_clear_error(
    ball_screw: tuple[Any, dict[str, Record]], tilting: tuple[Any, dict[str, Record]]
) -> None:
    _, bs = ball_screw
    _, tt = tilting
    with pytest.raises(
        IdentifyError, match=r"no excitation \(feedforward excitation.enabled is false\)"
    ):
        identify("ball_screw", [bs["measure_sine_ball_screw"]])
    with pytest.raises(IdentifyError, match="no linear scale in the data"):
        identify("elastic_ball_screw", [tt["measure_tilting_table"]])
    with pytest.raises(IdentifyError, match="the data do not determine"):
        identify("elastic_ball_screw", [bs["measure_frf_ball_screw"]])
    with pytest.raises(IdentifyError, match=r"--friction .*: an excitation run"):
        identify(
            "ball_screw", [bs["measure_frf_ball_screw"]], friction=[bs["measure_frf_ball_screw"]]
        )


def test_steps_are_another_held_out_run(ball_screw: tuple[Any, dict[str, Record]]) -> None:
    ident, _ = ball_screw
    from servo_axis.identify.driver import validate

    v = validate(ident, _record("measure_steps_ball_screw"))
    assert v.nrmse_error < 0.05
    assert_allclose(v.rms_error_fitted, v.rms_error_measured, rtol=0.05)


def test_the_recorded_feedforward_is_the_excitation(
    ball_screw: tuple[Any, dict[str, Record]],
) -> None:
    """With PTC off the feedforward torque (the bag's `reference` effort) is the test torque."""
    _, runs = ball_screw
    rec = runs["measure_frf_ball_screw"]
    exc = rec.excitation()
    assert exc is not None
    assert_allclose(rec.feedforward_Nm, exc.torque_Nm(rec.step), rtol=1e-12, atol=1e-15)
    first, stop = exc.window
    assert np.abs(rec.feedforward_Nm[first:stop]).max() == pytest.approx(1.5, rel=1e-12)


@pytest.mark.parametrize("signal", ["chirp", "prbs"])
def test_chirp_and_prbs_identify_the_rigid_body_and_the_first_mode(
    signal: str, tmp_path: Path
) -> None:
    scenario = load_scenario(find_scenario("measure_frf_ball_screw"))
    scenario["feedforward"]["ros__parameters"]["excitation"]["signal"] = signal
    path = tmp_path / f"{signal}.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    ident = identify("ball_screw", [from_simulation(path)])
    true = scenario["plant"]["ros__parameters"]
    assert_allclose(ident.key("inertia_kgm2").value, true["inertia_kgm2"], rtol=KEY_RTOL)
    assert_allclose(ident.key("damping_Nms_per_rad").value, true["damping_Nms_per_rad"], rtol=0.1)
    assert_allclose(
        ident.key("modes.frequency_hz[0]").value, true["modes"]["frequency_hz"][0], rtol=KEY_RTOL
    )


def test_a_study_point_gets_the_identification_errors(
    ball_screw: tuple[Any, dict[str, Record]],
) -> None:
    from servo_axis.identify.study import sysid_block

    _, runs = ball_screw
    rec = runs["measure_frf_ball_screw"]
    block = sysid_block(rec.scenario, rec.scenario_path, rec)
    assert block is not None and block["identified"]
    assert block["missing"] == [] and block["spurious_hz"] == []
    assert block["max_key_error"] < KEY_RTOL
    assert block["keys"]["inertia_kgm2"] < 1e-3
    assert block["keys"]["modes_frequency_hz_0"] < 1e-3
    assert block["bode_db"] < 1.0 and block["bode_deg"] < 5.0
    held_out = runs["measure_sine_ball_screw"]
    assert sysid_block(held_out.scenario, held_out.scenario_path, held_out) is None
