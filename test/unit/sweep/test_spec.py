"""Study files: the points, the section of a key, the figures, the one-line errors; a point's row."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from servo_axis.__main__ import main
from servo_axis.params.resolve import node_values
from servo_axis.simulate import simulate
from servo_axis.sweep.point import run_point
from servo_axis.sweep.spec import StudyError, figure, load_study, scenario_for


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "study.yaml"
    path.write_text(text)
    return path


def test_a_grid_is_the_product_and_set_applies_to_every_point(tmp_path: Path) -> None:
    study = load_study(
        write(
            tmp_path,
            "scenario: pid_disturbance\nset: {/**.duration_s: 0.2}\n"
            "grid:\n  feedback.bandwidth_hz: [20, 40, 80]\n  disturbance.amplitude_Nm: [0.1, 0.2]\n"
            "figures: [tracking_error.all_samples.max_m]\n",
        )
    )
    assert study.name == "study" and study.backend == "plain"
    assert study.parameters == ("feedback.bandwidth_hz", "disturbance.amplitude_Nm")
    assert len(study.points) == 6
    assert study.points[5] == {
        "/**.duration_s": 0.2,
        "feedback.bandwidth_hz": 80,
        "disturbance.amplitude_Nm": 0.2,
    }


def test_a_key_names_its_section_or_is_found_in_the_one_that_has_it() -> None:
    data, _ = scenario_for(
        "ptc_friction_table",
        {"/**.duration_s": 0.3, "feedforward.learning.cycle_s": 0.5, "friction.elements": 4},
    )
    assert data["/**"]["ros__parameters"]["duration_s"] == 0.3
    assert node_values(data, "feedforward")["learning.cycle_s"] == 0.5
    assert node_values(data, "plant")["friction.elements"] == 4
    # The friction table's relative path is made absolute: the scenario may be written anywhere.
    table = Path(data["feedforward"]["ros__parameters"]["friction_table"]["file"])
    assert table.is_absolute() and table.is_file()


@pytest.mark.parametrize(
    ("body", "line"),
    [
        ("grid: {bandwidth_hzz: [1]}", "'bandwidth_hzz': in no section of the scenario"),
        (
            "grid: {feedback.bandwidth_hz: [-3]}",
            "'feedback.bandwidth_hz': parameter 'bandwidth_hz'",
        ),
        ("grid: {feedback.bandwidth_hz: 3}", "'grid.feedback.bandwidth_hz': expected a non-empty"),
        ("points: [{feedback.bandwdth_hz: 3}]", "'points[0].feedback.bandwdth_hz': unknown"),
        ("grid: {feedback.bandwidth_hz: [3]}\npoints: []", "'grid': give either"),
        ("grid: {feedback.bandwidth_hz: [3]}\nbackend: ray", "'backend': 'ray'"),
        ("grid: {feedback.bandwidth_hz: [3]}\nfigure: [x]", "'figure': unknown key"),
    ],
)
def test_a_bad_study_is_one_line_naming_the_key_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, line: str
) -> None:
    path = write(tmp_path, f"scenario: pid_disturbance\n{body}\nfigures: [a.b]\n")
    with pytest.raises(StudyError, match="^study .*" + line.replace("[", r"\[")[:30]):
        load_study(path)
    assert main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and line in err


def test_figures_are_paths_with_indices() -> None:
    summary = {"tracking_error": {"cycles": [{"rms_m": 1.0}, {"rms_m": 2.0}]}}
    assert figure(summary, "tracking_error.cycles[-1].rms_m") == 2.0
    assert figure(summary, "tracking_error.cycles[0].rms_m") == 1.0
    with pytest.raises(KeyError, match=r"no \[2\] at 'tracking_error\.cycles'"):
        figure(summary, "tracking_error.cycles[2].rms_m")


def test_a_plain_point_is_the_plain_loop_of_its_scenario(tmp_path: Path) -> None:
    overrides = {"/**.duration_s": 0.5, "feedback.bandwidth_hz": 30.0}
    row = run_point(
        3,
        "pid_disturbance",
        overrides,
        {"max": "tracking_error.all_samples.max_m", "bad": "tracking_error.nope"},
    )
    assert row["status"] == "failed" and "no 'nope'" in row["error"]
    row = run_point(3, "pid_disturbance", overrides, {"max": "tracking_error.all_samples.max_m"})
    assert row["status"] == "ok" and row["point"] == 3 and row["feedback.bandwidth_hz"] == 30.0
    data, _ = scenario_for("pid_disturbance", overrides)
    path = tmp_path / "s.yaml"
    import yaml

    path.write_text(yaml.safe_dump(data))
    traj = simulate(path)
    assert traj.encoder_rad.size == 500
    lead = data["/**"]["ros__parameters"]["lead_m_per_rad"]
    # pid_disturbance holds 0 with the encoder as its sensor: the error is -R * theta.
    np.testing.assert_allclose(row["max"], lead * np.max(np.abs(traj.encoder_rad)), rtol=1e-12)
    assert math.isfinite(row["wall_time_s"])
