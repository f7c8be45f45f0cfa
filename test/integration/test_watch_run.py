"""The watcher of the docs (``examples/watch_run.py``) shows a run and ends quietly on Ctrl-C.

Its first version, in the README, printed a ``KeyboardInterrupt`` traceback
from ``wait_for_service`` when stopped before the run's plant was there. Here
it gets SIGINT while it waits for a plant (no run): exit 0, nothing on
stderr. Following a run, stopped by Ctrl-C after it has printed the plant's
parameter descriptors: the how-to's commands (docs/how-to/watch-a-run.md,
test_docs_pages.py).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

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


def test_the_watcher_waiting_for_a_run_ends_quietly_on_ctrl_c(ros_env: int, tmp_path: Path) -> None:
    watcher = [sys.executable, str(WATCHER), "--ros-args", "-r", "__ns:=/x"]
    log = tmp_path / "waiting.log"
    proc = start(watcher, log)
    wait_for(log, "waiting for /x/plant/describe_parameters ...", proc, 60)
    code, err = interrupt(proc)
    assert (code, err) == (0, ""), err
