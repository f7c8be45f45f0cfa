"""Ctrl-C on ``python -m servo_axis sweep``: one clean message, the table so far, a resume.

The terminal sends SIGINT to the whole foreground process group: the client
and the LocalCluster's worker processes alike. The study here has a short
point 0 and long points after it on one worker; once point 0 is in the
manifest, SIGINT goes to the group. Expected: exit 130, no traceback,
``results.csv`` with point 0 ``ok`` and the rest ``not run``, a line naming
the command that resumes, and a manifest holding point 0 only.
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

STUDY = """\
name: interrupted
scenario: pid_disturbance
points:
  - {/**.duration_s: 0.2, feedback.bandwidth_hz: 30.0}
  - {/**.duration_s: 400.0, feedback.bandwidth_hz: 40.0}
  - {/**.duration_s: 400.0, feedback.bandwidth_hz: 50.0}
figures: {max: tracking_error.all_samples.max_m}
"""


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _signal_state(pid: int) -> str:
    """The process's ignored, caught and blocked signals (hex masks), and each
    thread's blocked ones where SIGINT is among them, from /proc."""
    lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    masks = [
        ln for ln in lines if ln.startswith(("SigIgn", "SigCgt", "SigBlk", "SigPnd", "ShdPnd"))
    ]
    blocking = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError):
            for ln in (task / "status").read_text().splitlines():
                if ln.startswith("SigBlk") and int(ln.split()[1], 16) & (1 << (signal.SIGINT - 1)):
                    blocking.append(task.name)
    return f"{'; '.join(masks)}; threads blocking SIGINT: {blocking or 'none'}"


def test_ctrl_c_writes_the_table_so_far_and_says_how_to_resume(tmp_path: Path) -> None:
    study = tmp_path / "interrupted.yaml"
    study.write_text(STUDY)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "servo_axis", "sweep", str(study), "--out", str(out)]
    proc = subprocess.Popen(
        [*command, "--workers", "1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        # With SIGINT at its default, as a terminal's foreground job has it: a suite
        # started in the background (`scripts/test.sh &`, nohup) hands its children
        # SIGINT ignored, and Python then keeps it ignored (the client ran on).
        preexec_fn=_default_sigint,
    )
    try:
        deadline = time.monotonic() + 120
        manifest = out / "manifest.json"
        while not (manifest.is_file() and "0" in json.loads(manifest.read_text())["rows"]):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "point 0 never finished"
            time.sleep(0.2)
        # How the client took SIGINT when it was sent (it had it ignored when the
        # suite ran in the background, and ran on to exit 0).
        signals_then = _signal_state(proc.pid)
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, f"{stderr}\nat SIGINT: {signals_then}\n{stdout}"
    assert "Traceback" not in stderr and "Traceback" not in stdout, stderr
    assert "CancelledError" not in stderr, stderr
    lines = [line for line in stderr.replace("\r", "\n").splitlines() if line.strip()]
    assert lines[-1] == "interrupted"
    assert lines[-2] == (
        f"study interrupted: interrupted with 1 of 3 points finished ({manifest}, "
        f"{out / 'results.csv'}); the same command resumes: "
        f"python -m servo_axis sweep {study} --out {out}"
    )
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == ["ok", "not run", "not run"]
    assert float(rows[0]["max"]) > 0
    # The manifest holds the finished point only: the command resumes from there
    # (test/unit/sweep/test_resume.py: a second call runs only the points it lacks).
    assert list(json.loads(manifest.read_text())["rows"]) == ["0"]
