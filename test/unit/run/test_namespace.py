"""A single-axis run's namespace and the run header (no ROS)."""

from __future__ import annotations

from pathlib import Path

import pytest

from servo_axis.core.errors import ParameterFileError
from servo_axis.params.run_params import single_axis_namespace
from servo_axis.params.scenario import load_scenario
from servo_axis.run.processes import discovery_settings, run_header

CONFIG = Path(__file__).resolve().parents[3] / "config"


def test_the_default_namespace_is_the_axis_and_the_option_overrides_it() -> None:
    ptc = load_scenario(CONFIG / "ptc_nominal.yaml")  # axis: x
    tilt = load_scenario(CONFIG / "dlpid_tilt_pid.yaml")  # axis: tilt
    assert single_axis_namespace(ptc) == "/x"
    assert single_axis_namespace(tilt) == "/tilt"
    assert single_axis_namespace(ptc, "/bench") == "/bench"
    assert single_axis_namespace(ptc, "/") == ""  # the root: no remap


def test_an_axis_that_cannot_name_a_namespace_is_refused_naming_the_key() -> None:
    data = load_scenario(CONFIG / "ptc_nominal.yaml")
    data["/**"]["ros__parameters"]["axis"] = "x-1"
    with pytest.raises(ParameterFileError, match=r"parameter 'axis': 'x-1' cannot name"):
        single_axis_namespace(data)
    assert single_axis_namespace(data, "/x1") == "/x1"  # unless --namespace is given


def test_the_header_names_domain_namespace_and_discovery(tmp_path: Path) -> None:
    settings = discovery_settings(tmp_path)
    lines = run_header(42, ["/x"], settings)
    assert len(lines) == 3
    assert lines[0].startswith("ROS 2: ROS_DOMAIN_ID=42, namespace /x (nodes /x/plant")
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST" in lines[1]
    assert (
        f"FASTRTPS_DEFAULT_PROFILES_FILE={settings['FASTRTPS_DEFAULT_PROFILES_FILE']}" in lines[1]
    )
    assert "FASTDDS_BUILTIN_TRANSPORTS=UDPv4 + shared memory" in lines[1]
    assert lines[2].startswith(
        "watch it: ROS_DOMAIN_ID=42 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST "
        "python -m servo_axis.examples.watch_run --ros-args -r __ns:=/x  "
    )
    assert lines[2].endswith("docs/how-to/watch-a-run.md)") and "README" not in lines[2]
    root = run_header(7, [""], settings)
    assert "namespace / (nodes /plant" in root[0] and "-r __ns:=/  " in root[2]
    assert "namespaces /x, /y" in run_header(7, ["/x", "/y"], settings)[0]
