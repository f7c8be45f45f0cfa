"""``run SCENARIO --set ...`` records what the scenario file with those keys edited records.

Two runs through ``python -m servo_axis run`` (composed: one process each,
the same bag as separate ones), each in the test's ROS domain
(localhost discovery, temporary ROS_LOG_DIR): the shipped ``ptc_nominal``
with three overrides (a shared key, a node key, a nested key the file does
not have), and a copy of its file with the same three keys edited. Their
bags hold the same payloads on every topic (read with rosbags; lockstep is
deterministic), so an override that were ignored or set elsewhere would show;
their ``params.yaml`` are the same but for the run directory, and only the
first run's summary records the overrides.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from servo_axis.params.scenario import find_scenario, load_scenario
from servo_axis.run.processes import ros_environment

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

from scenario_hashes import bag_hashes  # noqa: E402

OVERRIDES = (
    "shared.duration_s=0.3",
    "feedback.bandwidth_hz=30",
    "plant.friction.rolling_coulomb_Nm=1.5",  # not in ptc_nominal's file: nested under plant
)


def run(args: list[str], domain: int, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    argv = ["-m", "servo_axis", "run", *args, "--composed", "--domain-id", str(domain)]
    return subprocess.run(
        [sys.executable, *argv, "--no-plots"],
        env=ros_environment(domain, tmp_path / "ros_log"),
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )


def test_set_gives_the_bag_of_the_edited_file(ros_env: int, tmp_path: Path) -> None:
    edited = load_scenario(find_scenario("ptc_nominal"))
    edited["/**"]["ros__parameters"]["duration_s"] = 0.3
    edited["feedback"]["ros__parameters"]["bandwidth_hz"] = 30
    edited["plant"]["ros__parameters"]["friction"] = {"rolling_coulomb_Nm": 1.5}
    path = tmp_path / "ptc_nominal.yaml"
    path.write_text(yaml.safe_dump(edited, sort_keys=False))

    sets = [a for o in OVERRIDES for a in ("--set", o)]
    by_set = run(["ptc_nominal", "--out", str(tmp_path / "set"), *sets], ros_env, tmp_path)
    by_file = run([str(path), "--out", str(tmp_path / "file")], ros_env, tmp_path)
    assert by_set.returncode == 0, by_set.stderr
    assert by_file.returncode == 0, by_file.stderr

    hashes = bag_hashes(tmp_path / "set" / "bag")
    assert hashes == bag_hashes(tmp_path / "file" / "bag")
    assert hashes["/x/state"][0] == 300  # 0.3 s at 1 ms: the shared override took

    def params(run_dir: Path) -> dict[str, object]:
        text = (run_dir / "params.yaml").read_text().replace(str(run_dir), "<run>")
        return dict(yaml.safe_load(text))

    recorded = params(tmp_path / "set")
    assert recorded == params(tmp_path / "file")
    plant = recorded["/**/plant"]["ros__parameters"]  # type: ignore[index]
    assert plant["friction"] == {"rolling_coulomb_Nm": 1.5}
    assert recorded["/**/feedback"]["ros__parameters"]["bandwidth_hz"] == 30  # type: ignore[index]

    summary = json.loads((tmp_path / "set" / "summary.json").read_text())
    assert summary["overrides"] == list(OVERRIDES)
    assert "overrides" not in json.loads((tmp_path / "file" / "summary.json").read_text())
    assert f"overrides         --set {OVERRIDES[0]} --set {OVERRIDES[1]}" in by_set.stdout
