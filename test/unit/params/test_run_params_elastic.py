"""The run's parameter file for paper 004: the deformation topic, the DOB and the GMS file's plant."""

from __future__ import annotations

import copy
import shutil
from pathlib import Path
from typing import Any

import pytest

from servo_axis.core.errors import ParameterFileError
from servo_axis.params.factories import build_terms, plant_model
from servo_axis.params.resolve import feedforward_values, node_values, plant_fingerprint
from servo_axis.params.run_params import handshake_overrides
from servo_axis.params.run_topics import recorder_topics
from servo_axis.params.scenario import load_scenario, roles_of

CONFIG = Path(__file__).resolve().parents[3] / "config"
BAG = Path("/tmp/run/bag")


def scenario(name: str) -> dict[str, Any]:
    data: dict[str, Any] = load_scenario(CONFIG / f"{name}.yaml")
    return data


def test_the_deformation_topic_is_recorded_and_counted_only_when_on() -> None:
    on = scenario("fast_reversal_sigmoid")
    topics, _ = recorder_topics(on, roles_of(on))
    assert "deformation" in topics
    rec = handshake_overrides(on, roles_of(on), BAG, CONFIG)["recorder"]
    assert rec["counted_topics"] == ["state", "command", "reference", "deformation"]
    off = copy.deepcopy(on)
    off["feedback"]["ros__parameters"]["deformation"]["enabled"] = False
    topics, _ = recorder_topics(off, roles_of(off))
    assert "deformation" not in topics
    rec = handshake_overrides(off, roles_of(off), BAG, CONFIG)["recorder"]
    assert rec["counted_topics"] == ["state", "command", "reference"]
    # paper 000's scenarios record what they did before
    assert (
        "deformation"
        not in recorder_topics(scenario("ptc_friction"), ["plant", "feedback", "feedforward"])[0]
    )


def test_the_feedforward_copies_the_dob_and_the_plant_from_their_sections() -> None:
    data = scenario("fast_reversal_gms")
    ff = handshake_overrides(data, roles_of(data), BAG, CONFIG)["feedforward"]
    assert ff["dob.enabled"] is True and ff["dob.cutoff_hz"] == 80.0
    assert ff["gms.plant"] == plant_fingerprint(data)
    assert ff["gms.file"] == str(CONFIG / "gms_elastic_ball_screw.txt")
    values = node_values(data, "feedforward")
    assert values["dob.enabled"] and values["gms.plant"].startswith("elastic_ball_screw:")
    # paper 000: no DOB in the feedback section, none copied
    assert node_values(scenario("ptc_friction_table"), "feedforward")["dob.enabled"] is False


def test_the_shipped_gms_file_belongs_to_the_plant_of_the_compensation_runs() -> None:
    fingerprints = {
        plant_fingerprint(scenario(name))
        for name in ("friction_id_elastic", "slow_reversal_gms", "fast_reversal_gms")
    }
    assert len(fingerprints) == 1
    terms = build_terms(
        feedforward_values(scenario("fast_reversal_gms"), CONFIG / "fast_reversal_gms.yaml")
    )
    assert len(terms) == 1  # the GMS term, wrapped to enter outside the DOB


def test_a_gms_file_of_another_plant_is_refused_by_name(tmp_path: Path) -> None:
    data = scenario("fast_reversal_gms")
    stiffer = copy.deepcopy(data)
    stiffer["plant"]["ros__parameters"]["axial_stiffness_N_per_m"] = 3.0e8
    shutil.copy(CONFIG / "gms_elastic_ball_screw.txt", tmp_path / "gms.txt")
    stiffer["feedforward"]["ros__parameters"]["gms"]["file"] = "gms.txt"
    values = feedforward_values(stiffer, tmp_path / "scenario.yaml")
    with pytest.raises(ParameterFileError, match=r"parameter 'gms.file': .* identified on plant"):
        build_terms(values)


def test_a_mode_outside_100_200_hz_is_a_warning_not_an_error() -> None:
    data = scenario("fast_reversal_gms")
    data["plant"]["ros__parameters"]["axial_stiffness_N_per_m"] = 2.0e7
    values = node_values(data, "plant")  # accepted
    (warning,) = plant_model("elastic_ball_screw").warnings(values)
    assert "first axial mode" in warning and "outside the 100-200 Hz" in warning
    assert (
        plant_model("elastic_ball_screw").warnings(
            node_values(scenario("fast_reversal_gms"), "plant")
        )
        == []
    )


@pytest.mark.parametrize(
    ("section", "key", "value", "message"),
    [
        ("feedback", "deformation.window_samples", 0, "parameter 'deformation.window_samples'"),
        ("feedforward", "sigmoid.sigma_m2_per_rad", 0.0, "parameter 'sigmoid.sigma_m2_per_rad'"),
        ("feedforward", "sigmoid.gamma_m_per_rad", -1.0, "parameter 'sigmoid.gamma_m_per_rad'"),
        ("plant", "axial_stiffness_N_per_m", 0.0, "parameter 'axial_stiffness_N_per_m'"),
        ("plant", "torsional_stiffness_Nm_per_rad", -5.0, "parameter 'torsional_stiffness"),
        ("plant", "sim_step_s", 0.0003, "parameter 'control_period_s': expected a whole multiple"),
        ("feedback", "dob.sensor", "tacho", "parameter 'dob.sensor'"),
    ],
)
def test_bad_values_are_refused_by_name(section: str, key: str, value: Any, message: str) -> None:
    data = scenario("fast_reversal_sigmoid")
    params = data[section]["ros__parameters"]
    head, _, tail = key.partition(".")
    if tail:
        params.setdefault(head, {})[tail] = value
    else:
        params[key] = value
    with pytest.raises(ParameterFileError, match=message.replace("(", r"\(")):
        node_values(data, section)


def test_the_recorder_is_told_the_plants_scheduled_topics() -> None:
    data = scenario("fast_reversal_sigmoid")
    rec = handshake_overrides(data, roles_of(data), BAG, CONFIG)["recorder"]
    assert rec["final_topics"] == ["/clock", "plant/status"]
    assert rec["final_every_steps"] == [10, 50]
    data["plant"]["ros__parameters"].update(clock_every_steps=7, publish_clock=False)
    rec = handshake_overrides(data, roles_of(data), BAG, CONFIG)["recorder"]
    assert rec["final_topics"] == ["plant/status"] and rec["final_every_steps"] == [50]
    data["/**"]["ros__parameters"]["mode"] = "realtime"  # a last status of its own: not counted
    assert "final_topics" not in handshake_overrides(data, roles_of(data), BAG, CONFIG)["recorder"]


def test_a_scheduled_topic_without_its_period_is_refused_by_name() -> None:
    from servo_axis.params.factories import checked_values

    given = {"output_dir": "/tmp/bag", "final_topics": ["/clock", "plant/status"],
             "final_every_steps": [10]}  # fmt: skip
    with pytest.raises(ParameterFileError, match=r"parameter 'final_every_steps': expected one"):
        checked_values("recorder", given)
    given["final_every_steps"] = [10, 0]
    with pytest.raises(ParameterFileError, match=r"parameter 'final_every_steps'"):
        checked_values("recorder", given)
