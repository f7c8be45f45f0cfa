"""``--set SECTION.KEY=VALUE``: parsed, typed as YAML, set where the file has the key, planned.

Through :func:`~servo_axis.params.run_plan.plan_run` (what ``run`` does before
it writes anything; the runs themselves are in test/integration/test_overrides.py).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from servo_axis.core.errors import ConfigError
from servo_axis.params.overrides import apply_overrides, parse_override
from servo_axis.params.run_plan import plan_run
from servo_axis.params.scenario import find_scenario, load_scenario


def sets(*texts: str) -> list[Any]:
    return [parse_override(t) for t in texts]


@pytest.mark.parametrize(
    ("text", "section", "key", "value"),
    [
        ("shared.duration_s=1", "/**", "duration_s", 1),
        ("/**.duration_s=1.5e-3", "/**", "duration_s", 1.5e-3),
        ("plant.friction.elements=8", "plant", "friction.elements", 8),
        ("feedforward.ptc.enabled=false", "feedforward", "ptc.enabled", False),
        ("plant.modes.frequency_hz=[180, 520.5]", "plant", "modes.frequency_hz", [180, 520.5]),
        ("feedback.sensor=scale", "feedback", "sensor", "scale"),
        ("feedback.sensor='1e3'", "feedback", "sensor", "1e3"),  # quoted: a string
        (
            "/x/feedforward.reference.amplitude_m=0.002",
            "/x/feedforward",
            "reference.amplitude_m",
            0.002,
        ),
        ("recorder.topics=a=b", "recorder", "topics", "a=b"),  # the first '=' splits
    ],
)
def test_an_override_is_its_section_its_dotted_key_and_a_yaml_value(
    text: str, section: str, key: str, value: Any
) -> None:
    o = parse_override(text)
    assert (o.text, o.section, o.key, o.value) == (text, section, key, value)
    assert type(o.value) is type(value)


def test_nan_is_yaml_nan() -> None:
    assert math.isnan(parse_override("feedback.bandwidth_hz=.nan").value)


def test_the_key_is_set_where_the_file_spells_it_else_nested() -> None:
    scenario = {
        "/**": {"ros__parameters": {"duration_s": 2.0}},
        "plant": {"ros__parameters": {"friction.elements": 4, "modes": {"zeta": [0.1]}}},
    }
    out = apply_overrides(
        scenario,
        sets(
            "plant.friction.elements=8",  # dotted in the file: replaced there
            "plant.modes.zeta=[0.2]",  # nested in the file
            "plant.disturbance.amplitude_Nm=0.5",  # not in the file: nested, as YAML would
            "shared.duration_s=1",
            "shared.duration_s=3",  # the last one wins
        ),
    )
    assert out["plant"]["ros__parameters"] == {
        "friction.elements": 8,
        "modes": {"zeta": [0.2]},
        "disturbance": {"amplitude_Nm": 0.5},
    }
    assert out["/**"]["ros__parameters"] == {"duration_s": 3}
    assert scenario["plant"]["ros__parameters"]["friction.elements"] == 4  # a copy was changed


def test_a_mapping_sets_each_of_its_keys() -> None:
    scenario = {"plant": {"ros__parameters": {}}, "feedback": {"ros__parameters": {}}}
    out = apply_overrides(scenario, sets("feedback.dob={enabled: true, cutoff_hz: 80}"))
    assert out["feedback"]["ros__parameters"] == {"dob": {"enabled": True, "cutoff_hz": 80}}


def test_the_plan_has_the_overrides_in_params_yaml_and_records_them(tmp_path: Path) -> None:
    path = find_scenario("ptc_nominal")
    texts = ("shared.duration_s=0.5", "feedback.bandwidth_hz=30", "plant.friction.elements=6")
    plan = plan_run(load_scenario(path), path, out_dir=tmp_path / "run", overrides=sets(*texts))
    assert plan.overrides == texts
    params = dict(plan.axes[0].params_file)
    assert params["/**"]["ros__parameters"]["duration_s"] == 0.5
    assert params["/**/feedback"]["ros__parameters"]["bandwidth_hz"] == 30
    assert params["/**/plant"]["ros__parameters"]["friction"]["elements"] == 6
    assert plan.steps == 500  # duration_s / control_period_s, from the override
    feedback = plan.axes[0].role("feedback")
    assert feedback is not None and feedback.values["bandwidth_hz"] == 30.0
    assert not (tmp_path / "run").exists()  # planning writes nothing


def test_a_per_axis_override_changes_that_axis_only(tmp_path: Path) -> None:
    path = find_scenario("xy_circle")
    scenario = load_scenario(path)
    plan = plan_run(
        scenario,
        path,
        out_dir=tmp_path / "run",
        overrides=sets("/x/feedback.bandwidth_hz=30", "feedback.use_feedforward=true"),
    )
    by_axis = {a.axis: a for a in plan.axes}
    bandwidth = {axis: a.role("feedback").values["bandwidth_hz"] for axis, a in by_axis.items()}
    common = scenario["feedback"]["ros__parameters"]["bandwidth_hz"]
    assert bandwidth == {"x": 30.0, "y": float(common)}
    # Each axis's scenario.yaml (written in its directory) is its view with the overrides.
    x_view = by_axis["x"].scenario
    assert x_view["feedback"]["ros__parameters"]["bandwidth_hz"] == 30
    assert yaml.safe_load(yaml.safe_dump(x_view)) == x_view


@pytest.mark.parametrize(
    ("text", "said"),
    [
        (
            "feedback.bandwith_hz=30",
            "--set feedback.bandwith_hz=30: unknown parameter 'bandwith_hz'",
        ),
        ("shared.duration_s=-1", "--set shared.duration_s=-1: parameter 'duration_s'"),
        ("learning.law=rptc", "the scenario has no 'learning' section"),
    ],
)
def test_the_plan_names_the_override_at_fault(tmp_path: Path, text: str, said: str) -> None:
    path = find_scenario("ptc_nominal")
    # A good override before the bad one: the bad one is named.
    with pytest.raises(ConfigError) as err:
        plan_run(
            load_scenario(path),
            path,
            out_dir=tmp_path / "run",
            overrides=sets("feedback.bandwidth_hz=30", text),
        )
    assert str(err.value).startswith(f"--set {text}: ") and said in str(err.value)


def test_sweep_set_overrides_every_point_but_the_swept_keys(tmp_path: Path) -> None:
    from servo_axis.sweep.spec import load_study

    study = tmp_path / "study.yaml"
    study.write_text(
        yaml.safe_dump(
            {
                "scenario": "ptc_nominal",
                "set": {"/**.duration_s": 0.5},
                "grid": {"feedback.bandwidth_hz": [30, 40]},
                "figures": ["tracking_error.all_samples.max_m"],
            }
        )
    )
    plain = load_study(study)
    given = load_study(study, sets("shared.duration_s=0.2", "feedback.bandwidth_hz=99"))
    assert [p["/**.duration_s"] for p in plain.points] == [0.5, 0.5]
    assert [p["/**.duration_s"] for p in given.points] == [0.2, 0.2]
    # The swept key keeps its points' values: the grid is what the study is about.
    assert [p["feedback.bandwidth_hz"] for p in given.points] == [30, 40]
    assert given.runs_fingerprint() != plain.runs_fingerprint()  # another study folder's
