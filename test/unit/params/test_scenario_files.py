"""Scenario files: layout checks, the per-axis view, finding shipped scenarios by name."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from servo_axis.core.errors import ConfigError
from servo_axis.params.scenario import (
    axes_of,
    axis_view,
    find_scenario,
    load_scenario,
    safe_load_text,
    scenario_dir,
    scenario_names,
    shared,
)

CONFIG = Path(__file__).resolve().parents[3] / "config"


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


@pytest.mark.parametrize(
    ("shared", "hint"),
    [
        ({"duraton_s": 1.0}, "did you mean 'duration_s'?"),
        ({"bandwidth_hz": 40.0}, "the shared keys: mode, control_period_s, duration_s"),
        ({"nominal": {"inertia_kg": 0.01}}, "did you mean 'nominal.inertia_kgm2'?"),
    ],
)
def test_an_unknown_shared_key_is_named_with_its_section(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], shared: dict, hint: str
) -> None:
    """It was `unknown parameter 'duraton_s' for node 'plant'`: the first node checked,
    not the `/**` section the key is in."""
    from servo_axis.__main__ import main

    data = yaml.safe_load((CONFIG / "ptc_nominal.yaml").read_text())
    data["/**"]["ros__parameters"].update(shared)
    path = write(tmp_path, data)
    key = next(iter(shared)) + ("." + next(iter(shared["nominal"])) if "nominal" in shared else "")
    line = f"unknown parameter '{key}' in the shared section '/**', which every node reads ("
    with pytest.raises(ConfigError, match=re.escape(line + hint)):
        load_scenario(path)
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and line in err and "for node" not in err
    assert not out.exists()


def test_a_multi_axis_scenario_refuses_composed_and_namespace_before_starting(
    tmp_path: Path,
) -> None:
    from servo_axis.run.runner import RunOptions, run_scenario

    for options in ({"composed": True}, {"namespace": "/a"}):
        out = tmp_path / "run"
        with pytest.raises(ConfigError, match="multi-axis scenario runs as separate processes"):
            run_scenario(
                CONFIG / "xy_circle.yaml", RunOptions(out_dir=out, progress=None, **options)
            )
        assert not out.exists()  # nothing was started or written
    # The same by name.
    with pytest.raises(ConfigError, match="multi-axis scenario runs as separate processes"):
        run_scenario(
            "xy_circle", RunOptions(out_dir=tmp_path / "by_name", progress=None, composed=True)
        )
    assert not (tmp_path / "by_name").exists()


def test_compare_refuses_a_multi_axis_run_and_a_wrong_label_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from servo_axis.__main__ import main
    from servo_axis.analysis.summary import AxesSummary, ErrorStats, RunSummary, TrackingError

    none = ErrorStats(rms_m=0.0, max_m=0.0)
    axis = RunSummary(
        scenario="s",
        description="",
        scenario_file="s.yaml",
        processes="separate processes",
        time_mode="lockstep",
        control_period_s=1e-3,
        steps=0,
        sim_time_s=0.0,
        wall_time_s=1.0,
        steps_per_s=0.0,
        realtime_factor=0.0,
        message_counts={},
        faults=(),
        ptc=True,
        friction_table=False,
        reference_period_s=None,
        tracking_error=TrackingError(all_samples=none, reference_instants=none),
    )
    xy = tmp_path / "xy"
    xy.mkdir()
    both = AxesSummary(scenario="xy", description="", wall_time_s=1.0, axes={"x": axis, "y": axis})
    (xy / "summary.json").write_text(both.to_json())
    assert main(["compare", str(xy)]) == 2
    assert f"compare its axes: {xy / 'x'}, {xy / 'y'}" in capsys.readouterr().err
    one = tmp_path / "one"
    one.mkdir()
    (one / "summary.json").write_text(axis.to_json())
    assert main(["compare", str(one), "--labels", "Q,Q~5"]) == 2
    assert "--labels: expected 1 comma-separated labels, got 2" in capsys.readouterr().err


def test_shipped_scenarios_are_found_by_name_or_path(tmp_path: Path) -> None:
    shipped = scenario_dir() / "rptc_detailed.yaml"
    assert find_scenario("rptc_detailed") == shipped
    assert find_scenario("rptc_detailed.yaml") == shipped
    # A path is taken as it is, also one outside the shipped folder.
    assert find_scenario(CONFIG / "ptc_nominal.yaml") == CONFIG / "ptc_nominal.yaml"
    own = tmp_path / "rptc_detailed.yaml"
    own.write_text(shipped.read_text())
    assert find_scenario(str(own)) == own
    # config/ of the source tree is the shipped folder.
    assert sorted(p.stem for p in CONFIG.glob("*.yaml")) == scenario_names()
    assert {"ptc_nominal", "rptc_friction_table", "xy_circle"} <= set(scenario_names())


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        (
            "ptc_nominl",
            "'ptc_nominl': neither a file nor a shipped scenario; did you mean 'ptc_nominal'",
        ),
        ("RPTC_Detailed", "did you mean 'rptc_detailed'"),
        ("ptc", "did you mean 'ptc_friction' or 'ptc_friction_table' or 'ptc_nominal'?"),
        (
            "no_such_scenario",
            f"`python -m servo_axis list` shows the {len(scenario_names())} shipped ones",
        ),
        (
            "elsewhere/rptc_detailed.yaml",
            "elsewhere/rptc_detailed.yaml: no such file (no directory elsewhere); the shipped "
            "scenario rptc_detailed is named by its name alone",
        ),
    ],
)
def test_a_bad_scenario_name_gets_the_closest_names(name: str, expected: str) -> None:
    with pytest.raises(ConfigError) as err:
        find_scenario(name)
    assert expected in str(err.value)
    # Not all 42 names: the closest, or where to see them.
    assert sum(shipped in str(err.value) for shipped in scenario_names()) <= 3


def test_cli_list_shows_every_shipped_scenario() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "servo_axis", "list"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    # The scenarios first, then a blank line and the installed extensions.
    scenarios, _, extensions = done.stdout.partition("\n\n")
    listed = {line.split()[0] for line in scenarios.splitlines() if line.strip()}
    assert listed == set(scenario_names())
    assert "plant models (selected by plant.model" in extensions
    for name in ("ball_screw", "tilting_table", "friction_table", "rptc", "pilc_bfft", "dlpid"):
        assert f"\n  {name} " in extensions
    # One column for the descriptions, at least two spaces after the longest name
    # (fast_reversal_contact_sigmoid_stage, 35 characters).
    width = max(len(name) for name in scenario_names()) + 2
    rows = [line for line in scenarios.splitlines() if line.strip()]
    for name, row in zip(scenario_names(), rows, strict=True):
        description = shared(load_scenario(find_scenario(name)))["scenario"]["description"]
        assert row == f"{name:<{width}}{description}"
    # The extensions' descriptions and keys in one column too.
    entries = [ln for ln in extensions.splitlines() if ln.startswith("  ")]
    columns = {len(ln) - len(ln[2:].split("  ", 1)[1].lstrip()) for ln in entries if "  " in ln[2:]}
    assert len(columns) == 1, columns


@pytest.mark.parametrize(
    "path",
    sorted(CONFIG.glob("*.yaml"))
    + sorted((CONFIG.parent / "src" / "servo_axis" / "studies").glob("*.yaml")),
    ids=lambda p: p.name,
)
def test_the_fast_parser_reads_every_shipped_file_as_pyyaml_does(path: Path) -> None:
    text = path.read_text()
    assert safe_load_text(text) == yaml.safe_load(text)


@pytest.mark.parametrize(
    "text",
    [
        "a: 1\n b: 2\n",  # a mapping value where none may be
        "a: [1, 2\n",  # an unclosed flow sequence
        "a: !!python/object:os.system ls\n",  # a tag the safe loader refuses
        "\ta: 1\n",  # a tab
        "a: 1\na: 2\n",  # PyYAML takes the last; libyaml too
        "x: 1e3\ny: .inf\nz: 0x1F\nw: 2026-11-26\nv: ~\n",  # YAML 1.1 scalars
    ],
)
def test_the_fast_parser_gives_pyyaml_s_values_and_errors(text: str) -> None:
    try:
        expected: object = yaml.safe_load(text)
    except yaml.YAMLError as err:
        expected = f"{type(err).__name__}: {err}"
    try:
        got: object = safe_load_text(text)
    except yaml.YAMLError as err:
        got = f"{type(err).__name__}: {err}"
    assert got == expected
