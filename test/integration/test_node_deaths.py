"""The node-death policy (docs/explanation/reliability.md) under ``python -m servo_axis run``.

Each test starts the default learning scenario through the user's entry
point, SIGKILLs one node once the plant is running, and checks what the
the table promises: the learning unit is restarted and the axis runs
on; a dead feedforward generator trips the feedback to zero current and the
run ends safely with the exit code of a fault; a dead plant, feedback or
recorder stops the run, every process is reaped and the bag reads back. In
every case ``summary.json`` says what happened. The measured times are
printed (``pytest -s``) for docs/explanation/reliability.md.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml
from run_support import pids_of, shm_left_behind, shm_mapped_by, shm_names

from host_load import RunQueueWait, said
from servo_axis.analysis.health import EXIT_FAILED, EXIT_FAULT, EXIT_NOT_DETERMINISTIC
from servo_axis.nodes.runtime import LIVELINESS_LEASE_S
from servo_axis.recording.deserialize import read_messages
from servo_axis.run.fastdds import RESTART_PARTICIPANT_IDS

pytestmark = pytest.mark.integration

SCENARIO = "rptc_friction_table"  # 3 s, 6 learning cycles of 0.5 s
STEPS = 3000
#: Wall time after the plant's "connected" line at which the node is killed.
KILL_AFTER_S = 0.4


@dataclass
class Killed:
    code: int
    run_dir: Path
    stderr: str
    killed_at: float
    ended_at: float
    trip_seen_at: float | None
    restart_seen_at: float | None
    shm_before: set[str]
    #: Seconds the feedback's and this test's threads waited for a CPU from the kill to the trip.
    trip_wait_s: float = 0.0
    #: The shared-memory files the killed node mapped (what it may leave behind).
    killed_shm: frozenset[str] = frozenset()

    @property
    def summary(self) -> dict:
        return json.loads((self.run_dir / "summary.json").read_text())


def run_and_kill(role: str, tmp_path: Path, domain: int) -> Killed:
    """Run the scenario, SIGKILL ``role`` once the plant runs, follow what happens."""
    run_dir = tmp_path / "run"
    shm_before = shm_names()
    proc = subprocess.Popen(
        [sys.executable, "-m", "servo_axis", "run", SCENARIO, "--out", str(run_dir),
         "--domain-id", str(domain), "--no-plots"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "ROS_DOMAIN_ID": str(domain)},
    )  # fmt: skip
    try:
        plant_log = run_dir / "logs" / "plant.log"
        deadline = time.monotonic() + 60
        while not (plant_log.exists() and "connected" in plant_log.read_text(errors="replace")):
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "the plant never started"
            time.sleep(0.02)
        if role != "learning":
            time.sleep(KILL_AFTER_S)
        else:
            # As soon as it has learned a cycle (and saved it), not after a
            # fixed time: a loaded machine may not have reached the first
            # cycle's end 0.4 s after the start, and a fast one had reached
            # step 2,200 of 3,000, which left the restarted unit no whole
            # cycle to learn before the end (it late-joins mid-cycle).
            memory = run_dir / "learning_memory.json"
            while not memory.exists():
                assert proc.poll() is None and time.monotonic() < deadline + 60, "no memory"
                time.sleep(0.01)
        (pid,) = pids_of(run_dir, role)
        # The trip's way: the feedback's threads and this loop's, which sees it.
        host = RunQueueWait(os.getpid(), *pids_of(run_dir, "feedback"))
        killed_shm = frozenset(shm_mapped_by([pid]))
        os.kill(pid, signal.SIGKILL)
        killed_at = time.monotonic()
        trip_seen = restart_seen = None
        trip_wait = 0.0
        fb_report = run_dir / "logs" / "feedback.health.json"
        restart_log = run_dir / "logs" / f"{role}.restart1.log"
        while proc.poll() is None:
            now = time.monotonic()
            if trip_seen is None and fb_report.exists():
                try:
                    if json.loads(fb_report.read_text())["fallbacks"]:
                        trip_seen, trip_wait = now, host.seconds()
                except (json.JSONDecodeError, KeyError):
                    pass
            if restart_seen is None and restart_log.exists():
                restart_seen = now
            assert now - killed_at < 120, "the run did not end"
            time.sleep(0.01)
        ended_at = time.monotonic()
        stderr = proc.stderr.read() if proc.stderr else ""
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        if proc.stderr:
            proc.stderr.close()
    return Killed(
        proc.returncode,
        run_dir,
        stderr,
        killed_at,
        ended_at,
        trip_seen,
        restart_seen,
        shm_before,
        trip_wait,
        killed_shm,
    )


def _assert_reaped_and_readable(k: Killed) -> None:
    for role in ("plant", "feedback", "feedforward", "learning", "recorder"):
        assert pids_of(k.run_dir, role) == [], f"{role} left running"
    # The killed participant's Fast DDS shared-memory files are gone too
    # (only its own: others' runs on the host may leave theirs meanwhile).
    left = shm_left_behind(k.shm_before, set(k.killed_shm))
    assert not left, left
    from rosbags.rosbag2 import Reader

    with Reader(k.run_dir / "bag") as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts["/x/state"] > 0
        n = sum(1 for _ in reader.messages())
    assert n == sum(counts.values())


def _report(role: str, k: Killed, what: str) -> None:
    print(
        f"\n[death table] {role}: exit {k.code}; killed -> run ended {k.ended_at - k.killed_at:.2f} s; "
        + what
    )


@pytest.mark.shm
def test_killed_learning_unit_is_restarted_and_the_axis_runs_on(
    ros_env: int, tmp_path: Path
) -> None:
    k = run_and_kill("learning", tmp_path, ros_env)
    assert k.code == EXIT_NOT_DETERMINISTIC, k.stderr
    assert "NOT the deterministic one" in k.stderr
    health = k.summary["health"]
    assert health["outcome"] == "complete" and not health["deterministic"]
    (death,) = health["deaths"]
    assert death["role"] == "learning" and death["action"] == "restarted"
    assert death["exit_code"] == -signal.SIGKILL
    assert k.summary["steps"] == STEPS  # the axis ran to the end
    restart_log = (k.run_dir / "logs" / "learning.restart1.log").read_text()
    assert "resumed" in restart_log  # from its memory file
    # Under a participant id of its own, not the dead one's (whose receive
    # segment the others still write into).
    profile = (k.run_dir / "logs" / "learning.restart1.fastdds.xml").read_text()
    restart_id = int(re.search(r"<participantID>(\d+)</participantID>", profile).group(1))
    assert restart_id in RESTART_PARTICIPANT_IDS
    # The restarted unit learned on from what it resumed: its count of learned
    # cycles grew past the one in its memory, and the last cycle's error is
    # below the first's (how far below depends on how many cycle boundaries
    # fell back on the last correction while it came back, a wall-clock
    # matter: about half on a quiet machine, 0.6-1.0 under load).
    resumed = int(re.search(r"resumed (\d+) learned cycles", restart_log).group(1))
    stats = [
        m.message.data for m in read_messages(k.run_dir / "bag", topics=["/x/learning/cycle_stats"])
    ]
    assert stats and stats[-1][3] > resumed, (resumed, stats[-1])
    cycles = k.summary["tracking_error"]["cycles"]
    assert cycles[-1]["max_m"] < cycles[0]["max_m"]
    _assert_reaped_and_readable(k)
    assert k.restart_seen_at is not None
    _report("learning", k, f"killed -> restarted {k.restart_seen_at - k.killed_at:.2f} s")


@pytest.mark.realtime
def test_killed_feedforward_trips_the_feedback_and_the_run_ends_safely(
    ros_env: int, tmp_path: Path
) -> None:
    from rosbags.highlevel import AnyReader

    k = run_and_kill("feedforward", tmp_path, ros_env)
    assert k.code == EXIT_FAULT, k.stderr
    s = k.summary
    # The plant ran to the end on zero current (the summary's steps are the
    # ones with a reference too: those before the feedforward died).
    assert s["message_counts"]["/x/state"] == STEPS
    assert s["message_counts"]["/x/command"] == STEPS
    assert 0 < s["steps"] < STEPS
    (fault,) = s["faults"]
    assert fault["name"] == "input_timeout"
    health = s["health"]
    assert health["deaths"][0]["role"] == "feedforward"
    assert health["deaths"][0]["action"] == "ran on"
    with AnyReader([k.run_dir / "bag"]) as reader:
        conns = [c for c in reader.connections if c.topic == "/x/command"]
        current = np.array(
            [reader.deserialize(raw, c.msgtype).effort[0] for c, _, raw in reader.messages(conns)]
        )
    assert current.size == STEPS
    np.testing.assert_array_equal(current[fault["step"] + 1 :], 0.0)
    _assert_reaped_and_readable(k)
    assert k.trip_seen_at is not None
    trip_s = k.trip_seen_at - k.killed_at
    params = yaml.safe_load((k.run_dir / "params.yaml").read_text())
    timeout = params["/**/feedback"]["ros__parameters"]["input_timeout_s"]
    # docs/explanation/reliability.md: the liveliness lease + input_timeout_s (the time a gone peer gets
    # to come back) + one watchdog period (input_timeout_s / 10); the margin
    # covers the lease's detection (measured 0.3-1 s) and this test's polling,
    # and a busy host adds what it kept the threads on the way waiting.
    bound = LIVELINESS_LEASE_S + timeout + timeout / 10
    assert trip_s < bound + 1.0 + k.trip_wait_s, said(trip_s, bound + 1.0, k.trip_wait_s)
    _report(
        "feedforward",
        k,
        f"killed -> trip {trip_s:.2f} s (bound {bound:.2f} s + detection; "
        f"{k.trip_wait_s:.2f} s waiting for a CPU)",
    )


@pytest.mark.shm
@pytest.mark.parametrize("role", ["plant", "feedback", "recorder"])
def test_killed_plant_feedback_or_recorder_stops_the_run_and_keeps_the_bag(
    role: str, ros_env: int, tmp_path: Path
) -> None:
    k = run_and_kill(role, tmp_path, ros_env)
    assert k.code == EXIT_FAILED, k.stderr
    assert f"{role} exited" in k.stderr
    health = k.summary["health"]
    assert health["outcome"] == "failed"
    assert health["reasons"][0].startswith(f"stopped: {role} exited")
    assert health["deaths"][0]["role"] == role
    assert health["bag_recovered"] == (role == "recorder")
    assert 0 < k.summary["steps"] < STEPS
    _assert_reaped_and_readable(k)
    _report(role, k, f"bag holds {k.summary['steps']} of {STEPS} steps")
