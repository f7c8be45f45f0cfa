"""A run leaves the caller's environment as it was (the runner's own rclpy context included)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

from servo_axis.params.scenario import load_scenario
from servo_axis.run.runner import RunOptions, run_scenario

pytestmark = pytest.mark.integration

CONFIG = Path(__file__).resolve().parents[2] / "config"


def test_os_environ_is_the_same_before_and_after_a_run(
    ros_env: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The caller has other discovery settings, or none: the run's own must
    # not stay behind (ros_env put them there; take them out again).
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_env + 1))
    monkeypatch.setenv("FASTDDS_BUILTIN_TRANSPORTS", "DEFAULT")
    for name in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "FASTRTPS_DEFAULT_PROFILES_FILE"):
        monkeypatch.delenv(name)
    data = load_scenario(CONFIG / "ptc_nominal.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = 0.3
    scenario = tmp_path / "ptc_nominal.yaml"
    scenario.write_text(yaml.safe_dump(data))
    before = dict(os.environ)
    result = run_scenario(
        scenario,
        RunOptions(out_dir=tmp_path / "run", domain_id=ros_env, progress=None, plots=False),
    )
    assert dict(os.environ) == before
    assert result.summary.message_counts["/x/state"] == 300
    assert result.exit_codes == {
        "recorder": 0,
        "feedforward": 0,
        "feedback": 0,
        "plant": 0,
    }
