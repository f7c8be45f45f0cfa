"""Scenario files: layout checks and the per-axis view of a multi-axis scenario."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from servo_axis.bringup import axes_of, axis_view, load_scenario
from servo_axis.core.errors import ConfigError


def write(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_axis_sections_merge_into_the_common_ones_for_their_axis(tmp_path: Path) -> None:
    data = {
        "/**": {"ros__parameters": {"axis": "x", "scenario": {"name": "xy"}}},
        "plant": {"ros__parameters": {"sim_step_s": 1e-5}},
        "feedforward": {
            "ros__parameters": {
                "reference": {"kind": "sine", "amplitude_m": 0.01, "phase_rad": 0.0},
                "friction_table": {"enabled": True, "file": "table.csv"},
            }
        },
        "/y/feedforward": {"ros__parameters": {"reference": {"phase_rad": 1.5}}},
        "/y/feedback": {"ros__parameters": {"bandwidth_hz": 30.0}},
        "/x/plant": {"ros__parameters": {"sim_step_s": 2e-5}},
    }
    scenario = load_scenario(write(tmp_path, data))
    assert axes_of(scenario) == ["x", "y"]
    y = axis_view(scenario, "y", tmp_path)
    assert y["/**"]["ros__parameters"]["axis"] == "y"
    assert y["/**"]["ros__parameters"]["scenario"]["name"] == "xy/y"
    # Nested keys merge; the axis's value wins; the rest is the common one.
    assert y["feedforward"]["ros__parameters"]["reference"] == {
        "kind": "sine",
        "amplitude_m": 0.01,
        "phase_rad": 1.5,
    }
    assert y["feedforward"]["ros__parameters"]["friction_table"]["file"] == str(
        tmp_path / "table.csv"
    )
    assert y["feedback"]["ros__parameters"] == {"bandwidth_hz": 30.0}  # axis-only section
    assert y["plant"]["ros__parameters"]["sim_step_s"] == 1e-5
    x = axis_view(scenario, "x", tmp_path)
    assert x["plant"]["ros__parameters"]["sim_step_s"] == 2e-5
    assert "feedback" not in x
    assert not [k for k in x if k.startswith("/") and k != "/**"]
    # The common sections themselves are left as they were.
    assert scenario["feedforward"]["ros__parameters"]["reference"]["phase_rad"] == 0.0


@pytest.mark.parametrize("key", ["/x/controller", "x/plant", "/x/y/plant", "/**/plant"])
def test_a_section_that_is_no_node_or_axis_is_refused_by_name(tmp_path: Path, key: str) -> None:
    data = {"plant": {"ros__parameters": {}}, key: {"ros__parameters": {}}}
    with pytest.raises(ConfigError, match=re.escape(f"unknown section '{key}'")):
        load_scenario(write(tmp_path, data))


def test_a_multi_axis_scenario_refuses_composed_and_namespace_before_starting(
    tmp_path: Path,
) -> None:
    from servo_axis.bringup import run_scenario

    config = Path(__file__).resolve().parents[2] / "config" / "xy_circle.yaml"
    for options in ({"composed": True}, {"namespace": "/a"}):
        out = tmp_path / "run"
        with pytest.raises(ConfigError, match="multi-axis scenario runs as separate processes"):
            run_scenario(config, out_dir=out, progress=None, **options)
        assert not out.exists()  # nothing was started or written


def test_compare_refuses_a_multi_axis_run_and_a_wrong_label_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    from servo_axis.__main__ import main

    xy = tmp_path / "xy"
    xy.mkdir()
    (xy / "summary.json").write_text(json.dumps({"axes": {"x": {}, "y": {}}}))
    assert main(["compare", str(xy)]) == 2
    assert f"compare its axes: {xy / 'x'}, {xy / 'y'}" in capsys.readouterr().err
    one = tmp_path / "one"
    one.mkdir()
    (one / "summary.json").write_text(json.dumps({"tracking_error": {"cycles": []}}))
    assert main(["compare", str(one), "--labels", "Q,Q~5"]) == 2
    assert "--labels: expected 1 comma-separated labels, got 2" in capsys.readouterr().err
