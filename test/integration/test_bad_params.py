"""Bad parameters through the real entry points: exit 2, the key named, nothing started.

``python -m servo_axis run`` checks every node section (each key, and what
depends on several keys) before it writes or starts anything; a node
started alone with a missing or broken parameter file says so in one line.
Every process is started in its own session in the test's ROS domain
(localhost discovery, temporary ROS_LOG_DIR) and killed if still alive.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from servo_axis.params.scenario import load_scenario
from servo_axis.run.processes import ros_environment

pytestmark = pytest.mark.integration

CONFIG = Path(__file__).resolve().parents[2] / "config"


def run_reaped(args: list[str], env: dict[str, str], timeout: float = 60.0) -> tuple[int, str]:
    """Exit code and stderr of ``python args``; the process group is killed if it outlives us."""
    proc = subprocess.Popen(
        [sys.executable, *args],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        _, err = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    return proc.returncode, err


def scenario_with(src: str, tmp_path: Path, section: str, key: str, value: Any) -> Path:
    """The shipped scenario ``src`` with ``key`` (dotted) of ``section`` set to ``value``."""
    data = load_scenario(CONFIG / f"{src}.yaml")
    node = data.setdefault(section, {"ros__parameters": {}})["ros__parameters"]
    *parents, last = key.split(".")
    for part in parents:
        node = node.setdefault(part, {})
    node[last] = value
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


NAN = float("nan")

# (scenario, section, key, value, the key named in the error) from issue 7.
BRINGUP_CASES = [
    pytest.param("ptc_nominal", "plant", "duration_s", NAN, "duration_s", id="plant-duration-nan"),
    pytest.param(
        "ptc_nominal", "recorder", "duration_s", NAN, "duration_s", id="recorder-duration-nan"
    ),
    pytest.param(
        "ptc_nominal", "feedback", "input_timeout_s", NAN, "input_timeout_s", id="input-timeout-nan"
    ),
    pytest.param(
        "rptc_ideal",
        "feedforward",
        "learning.timeout_s",
        NAN,
        "learning.timeout_s",
        id="learning-timeout-nan",
    ),
    pytest.param(
        "ptc_nominal", "recorder", "control_period_s", 0, "control_period_s", id="recorder-period-0"
    ),
    pytest.param(
        "rptc_ideal",
        "/**",
        "control_period_s",
        -0.001,
        "control_period_s",
        id="period-negative",
    ),
    pytest.param(
        "ptc_nominal",
        "plant",
        "command_timeout_s",
        NAN,
        "command_timeout_s",
        id="command-timeout-nan",
    ),
    pytest.param(
        "rptc_ideal", "learning", "lead_m_per_rad", NAN, "lead_m_per_rad", id="learning-lead-nan"
    ),
    pytest.param(
        "ptc_nominal",
        "feedback",
        "nominal.inertia_kgm2",
        0.0,
        "nominal.inertia_kgm2",
        id="nominal-inertia-0",
    ),
    # What only the nodes' builders used to find, after the others had started.
    pytest.param(
        "ptc_nominal", "plant", "sim_step_s", 0.0003, "control_period_s", id="sim-step-not-whole"
    ),
    pytest.param(
        "ptc_nominal",
        "feedback",
        "dob",
        {"enabled": True, "cutoff_hz": 600.0},
        "dob.cutoff_hz",
        id="dob-above-nyquist",
    ),
    pytest.param("rptc_ideal", "learning", "n", 20, "n, nq", id="learning-filter-too-long"),
]


@pytest.mark.parametrize(("src", "section", "key", "value", "named"), BRINGUP_CASES)
def test_the_bringup_refuses_before_it_starts_anything(
    ros_env: int, tmp_path: Path, src: str, section: str, key: str, value: Any, named: str
) -> None:
    bad = scenario_with(src, tmp_path, section, key, value)
    out = tmp_path / "run"
    code, err = run_reaped(
        ["-m", "servo_axis", "run", str(bad), "--out", str(out), "--domain-id", str(ros_env)],
        ros_environment(ros_env, tmp_path / "ros_log"),
    )
    assert code == 2, err
    assert f"parameter '{named}'" in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    # Nothing written: the logs/ and params.yaml of the run come before any start.
    assert not out.exists() or not any(out.iterdir())


def test_a_period_negative_is_not_blamed_on_another_key(ros_env: int, tmp_path: Path) -> None:
    bad = scenario_with("rptc_ideal", tmp_path, "/**", "control_period_s", -0.001)
    code, err = run_reaped(
        ["-m", "servo_axis", "run", str(bad), "--out", str(tmp_path / "run")],
        ros_environment(ros_env, tmp_path / "ros_log"),
    )
    assert code == 2
    for other in ("period_s", "cycle_s", "duration_s"):
        assert f"parameter '{other}'" not in err


BROKEN_YAML = "plant:\n  ros__parameters:\n    duration_s: [1.0, 2.0\n"
# Valid YAML that rcl refuses (a list of mixed types).
RCL_REFUSES = "/**:\n  ros__parameters:\n    duration_s: [1.0, 'a']\n"


@pytest.mark.parametrize("role", ["plant", "feedback", "feedforward", "learning", "recorder"])
def test_a_node_alone_with_a_missing_params_file(ros_env: int, tmp_path: Path, role: str) -> None:
    missing = tmp_path / "missing.yaml"
    code, err = run_reaped(
        ["-m", f"servo_axis.nodes.{role}", "--ros-args", "--params-file", str(missing)],
        ros_environment(ros_env, tmp_path / "ros_log"),
    )
    assert code == 2, err
    assert err.strip().splitlines() == [
        f"{role}: parameter file {missing}: cannot read it: No such file or directory"
    ]


@pytest.mark.parametrize(
    ("role", "text", "expected"),
    [
        ("plant", BROKEN_YAML, "not valid YAML"),
        ("learning", BROKEN_YAML, "not valid YAML"),
        ("feedback", RCL_REFUSES, "Sequence should be of same type"),
    ],
)
def test_a_node_alone_with_a_broken_params_file(
    ros_env: int, tmp_path: Path, role: str, text: str, expected: str
) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text(text)
    code, err = run_reaped(
        ["-m", f"servo_axis.nodes.{role}", "--ros-args", "--params-file", str(broken)],
        ros_environment(ros_env, tmp_path / "ros_log"),
    )
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{role}: ")
    assert str(broken) in lines[0] and expected in lines[0]
    assert "Traceback" not in err and "[ERROR]" not in err


def test_a_node_alone_refuses_nan_naming_the_key(ros_env: int, tmp_path: Path) -> None:
    bad = scenario_with("ptc_nominal", tmp_path, "recorder", "duration_s", NAN)
    code, err = run_reaped(
        [
            "-m",
            "servo_axis.nodes.recorder",
            "--ros-args",
            "--params-file",
            str(bad),
            "-p",
            f"output_dir:={tmp_path / 'bag'}",
        ],
        ros_environment(ros_env, tmp_path / "ros_log"),
    )
    assert code == 2, err
    assert err.strip().splitlines() == [
        "recorder: parameter 'duration_s': expected a finite number, got nan"
    ]
    assert not (tmp_path / "bag").exists()
