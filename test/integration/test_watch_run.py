"""The watcher of the docs (``examples/watch_run.py``) shows a run and ends quietly on Ctrl-C.

Its first version, in the README, printed a ``KeyboardInterrupt`` traceback
from ``wait_for_service`` when stopped before the run's plant was there. Here
it gets SIGINT twice: once while it waits for a plant (no run), once while it
follows a run, after it has printed the plant's parameter descriptors. Both
times: exit 0, nothing on stderr.
"""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
WATCHER = REPO / "examples" / "watch_run.py"


def start(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:
        return subprocess.Popen(args, stdout=out, stderr=subprocess.PIPE, start_new_session=True)


def wait_for(log: Path, text: str, proc: subprocess.Popen[bytes], timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while text not in log.read_text(errors="replace"):
        assert proc.poll() is None, (proc.returncode, log.read_text())
        assert time.monotonic() < deadline, f"no {text!r} in:\n{log.read_text()[-2000:]}"
        time.sleep(0.1)


def interrupt(proc: subprocess.Popen[bytes]) -> tuple[int, str]:
    """SIGINT to its process group, as Ctrl-C in a terminal; its exit code and stderr."""
    os.killpg(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode, err.decode(errors="replace")


def test_the_watcher_follows_a_run_and_ends_quietly_on_ctrl_c(ros_env: int, tmp_path: Path) -> None:
    watcher = [sys.executable, str(WATCHER), "--ros-args", "-r", "__ns:=/x"]
    log = tmp_path / "waiting.log"
    proc = start(watcher, log)
    wait_for(log, "waiting for /x/plant/describe_parameters ...", proc, 60)
    code, err = interrupt(proc)
    assert (code, err) == (0, ""), err

    scenario = yaml.safe_load((REPO / "config" / "ptc_nominal.yaml").read_text())
    scenario["/**"]["ros__parameters"]["duration_s"] = 120.0  # stopped long before its end
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(scenario))
    run = start(
        [sys.executable, "-m", "servo_axis", "run", str(path), "--out", str(tmp_path / "run"),
         "--domain-id", str(ros_env), "--no-plots"],
        tmp_path / "run.log",
    )  # fmt: skip
    try:
        # The watcher the run's header names, as a user pastes it (no ros2 CLI needed).
        wait_for(tmp_path / "run.log", "watch it: ", run, 60)
        line = next(
            ln for ln in (tmp_path / "run.log").read_text().splitlines() if "watch it: " in ln
        )
        words = shlex.split(line.removeprefix("watch it: ").split("  (")[0])
        env = dict(os.environ) | dict(w.split("=", 1) for w in words[:2])
        assert env["ROS_DOMAIN_ID"] == str(ros_env) and words[2] == "python", words
        log = tmp_path / "watching.log"
        with log.open("wb") as out:
            proc = subprocess.Popen(
                [sys.executable, *words[3:]],
                stdout=out,
                stderr=subprocess.PIPE,
                start_new_session=True,
                env=env,
            )
        wait_for(log, "read-only: True", proc, 120)
        wait_for(log, "state [", proc, 60)
        text = log.read_text()
        assert "duration_s | " in text and "length of the run" in text, text[-2000:]
        code, err = interrupt(proc)
        assert (code, err) == (0, ""), err
    finally:
        code, err = interrupt(run)
    assert code == 130, err
