"""Realtime a user can trust (issue 30), through ``python -m servo_axis run``.

One realtime run (``ptc_nominal``, 3 s simulated) that several assertions
share: which threads of the pair run at which policy, and a 0.3 s SIGSTOP
of the feedback mid-run after which the loop closes again. Then a run
stopped by SIGTERM to the runner and one whose runner is SIGKILLed: every
process of the run is gone within a few seconds.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from servo_axis.nodes.feedback import ANSWER_GAP
from servo_axis.nodes.plant import LOOP_OPEN_S
from servo_axis.nodes.realtime import thread_policies
from servo_axis.params.scenario import load_scenario
from servo_axis.recording.deserialize import read_messages
from servo_axis.run.processes import pids_of

pytestmark = [pytest.mark.integration, pytest.mark.realtime]

CONFIG = Path(__file__).resolve().parents[2] / "config"
ROLES = ("plant", "feedback", "feedforward", "recorder")


def realtime_copy(dst: Path, seconds: float) -> Path:
    data = load_scenario(CONFIG / "ptc_nominal.yaml")
    data["/**"]["ros__parameters"].update(mode="realtime", duration_s=seconds)
    dst.write_text(yaml.safe_dump(data, sort_keys=False))
    return dst


def start_run(scenario: Path, run_dir: Path, domain: int) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "servo_axis", "run", str(scenario), "--out", str(run_dir),
         "--domain-id", str(domain), "--no-plots"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "ROS_DOMAIN_ID": str(domain)},
    )  # fmt: skip


def clock_running(pid: int) -> bool:
    """The plant's clock thread exists (it is named, :class:`~servo_axis.nodes.realtime.ClockThread`)."""
    return any("plant-clock" in names for names in thread_policies(pid).values())


def wait_for_the_clock(run_dir: Path, proc: subprocess.Popen[str], timeout_s: float = 90.0) -> int:
    """The plant's pid once its realtime clock runs."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and proc.poll() is None:
        for pid in pids_of(run_dir, "plant"):
            if clock_running(pid):
                return pid
        time.sleep(0.05)
    proc.kill()
    raise AssertionError(f"the plant's clock never started: {proc.communicate()[1][-2000:]}")


def run_pids(run_dir: Path) -> list[int]:
    return [pid for role in ROLES for pid in pids_of(run_dir, role)]


def gone_within(run_dir: Path, seconds: float) -> float:
    """Seconds until no process of the run is left (fails after ``seconds``)."""
    t0 = time.monotonic()
    while run_pids(run_dir):
        if time.monotonic() - t0 > seconds:
            left = run_pids(run_dir)
            for pid in left:  # never leave them to the next test
                os.kill(pid, signal.SIGKILL)
            raise AssertionError(f"still running after {seconds} s: {left}")
        time.sleep(0.05)
    return time.monotonic() - t0


def fifo_permitted() -> bool:
    probe = "import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True).returncode == 0


def settled_policies(pids: dict[str, int], timeout_s: float = 30.0) -> dict[str, Any]:
    """The threads' policies of each role once its executor took its first sample.

    Each executor thread takes its realtime priority then (and sets the
    middleware's receive threads): where SCHED_FIFO is permitted, the policies
    are read once the plant's clock and executor and the others' executors
    are at it, with their receive threads, and two readings 0.1 s apart
    agree, not after a fixed time a slow host may not have made (0.3 s).
    """

    def read() -> dict[str, Any]:
        return {role: thread_policies(pid) for role, pid in pids.items()}

    def ready(policies: dict[str, Any]) -> bool:
        def fifo(role: str) -> list[str]:
            return policies[role].get("fifo", [])

        return all(
            len([n for n in fifo(role) if not n.startswith("dds.")])
            == (2 if role == "plant" else 1)
            and any(n.startswith("dds.") for n in fifo(role))
            for role in pids
        )

    policies = read()
    if not fifo_permitted():
        return policies  # nothing to wait for: every thread stays at the default
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(0.1)
        again = read()
        if ready(again) and again == policies:
            return again
        policies = again
    return policies  # as they are: the test says what is missing


@pytest.fixture(scope="module")
def stalled_run(module_ros_env: tuple[int, Path]) -> dict[str, Any]:
    """A realtime run whose feedback is stopped for 0.3 s mid-run; its threads' policies."""
    domain, tmp = module_ros_env
    run_dir = tmp / "run"
    proc = start_run(realtime_copy(tmp / "rt.yaml", 3.0), run_dir, domain)
    plant = wait_for_the_clock(run_dir, proc)
    (feedback,) = pids_of(run_dir, "feedback")
    (feedforward,) = pids_of(run_dir, "feedforward")
    policies = settled_policies({"plant": plant, "feedback": feedback, "feedforward": feedforward})
    time.sleep(0.5)
    os.kill(feedback, signal.SIGSTOP)
    stopped_at = time.monotonic()
    time.sleep(0.3)
    os.kill(feedback, signal.SIGCONT)
    stall_s = time.monotonic() - stopped_at
    try:
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    left = gone_within(run_dir, 5.0)
    summary = json.loads((run_dir / "summary.json").read_text())
    return {"code": proc.returncode, "stderr": err, "summary": summary, "run_dir": run_dir,
            "policies": policies, "stall_s": stall_s, "left_s": left}  # fmt: skip


def test_only_the_clock_the_executors_and_the_receive_threads_run_at_a_realtime_priority(
    stalled_run: dict[str, Any],
) -> None:
    plant, feedback = stalled_run["policies"]["plant"], stalled_run["policies"]["feedback"]
    feedforward = stalled_run["policies"]["feedforward"]
    for policies in (plant, feedback, feedforward):
        # The middleware's other threads (the asynchronous writer that spun in
        # issue 30 among them) stay at the default policy.
        other_dds = [n for n in policies.get("other", []) if n.startswith("dds.")]
        assert any(n.startswith("dds.asyn") for n in other_dds), policies
        if fifo_permitted():
            assert not [n for n in other_dds if re.fullmatch(r"dds\.(shm|udp)\.\d+", n)]
        fifo_dds = [n for n in policies.get("fifo", []) if n.startswith("dds.")]
        assert all(re.fullmatch(r"dds\.(shm|udp)\.\d+", n) for n in fifo_dds), policies
    if fifo_permitted():
        receive = [n for n in plant["fifo"] if n.startswith("dds.")]
        assert any(n.startswith("dds.shm.") for n in receive), plant
        assert "plant-clock" in plant["fifo"] and len(plant["fifo"]) == 2 + len(receive)
        receive = [n for n in feedback["fifo"] if n.startswith("dds.")]
        assert receive and len(feedback["fifo"]) == 1 + len(receive)  # and its executor
        # The feedforward the same, below the pair (test/unit/nodes/test_realtime.py).
        receive = [n for n in feedforward["fifo"] if n.startswith("dds.")]
        assert receive and len(feedforward["fifo"]) == 1 + len(receive)
    else:
        assert not {"fifo"} & (set(plant) | set(feedback) | set(feedforward))
    block = stalled_run["summary"]["realtime"]["scheduling"]
    assert set(block["threads"]) == set(plant)  # the summary says the same


def test_after_a_stall_of_the_feedback_the_loop_closes_again(stalled_run: dict[str, Any]) -> None:
    # The stall is this test's SIGSTOP .. SIGCONT: at least its 0.3 s sleep;
    # a busy host may make it longer, harmless while it stays well under the
    # 2 s without a command after which the plant ends the run (loop_open).
    stall_s = stalled_run["stall_s"]
    assert stall_s > 0.25
    if stall_s > LOOP_OPEN_S - 0.5:
        pytest.skip(
            f"this host held the test for {stall_s:.2f} s between SIGSTOP and SIGCONT of a "
            f"0.3 s stall, near the plant's {LOOP_OPEN_S} s loop_open limit"
        )
    summary = stalled_run["summary"]
    # A 0.3 s stall of a 3 s run is 10 % of its ticks missed: more than
    # realtime.max_miss_fraction (5 %), so exit 5 for that reason (or 4: the
    # loop tripped on a loaded host); the stall never ends the run (loop_open).
    assert stalled_run["code"] in (4, 5), stalled_run["stderr"][-3000:]
    reasons = summary["health"]["reasons"]
    assert not any("loop_open" in r or "clock_stalled" in r for r in reasons), reasons
    if stalled_run["code"] == 5:
        assert reasons[0].startswith("the loop was not closed: ") and "missed" in reasons[0]
    rt = summary["realtime"]
    assert rt["ticks"] == 3000
    # The stall cost at least its own length in missed deadlines ...
    assert rt["misses"] >= 0.25 / 1e-3 - 1
    # ... and the feedback answered again after it, to the end: never more than
    # ANSWER_GAP steps between two answers (a feedback behind its clock answers
    # only what the plant can still use), the last state answered.
    (topic,) = [t for t in summary["message_counts"] if t.endswith("/command")]
    steps = sorted(
        {
            (m.message.header.stamp.sec * 10**9 + m.message.header.stamp.nanosec) // rt["period_ns"]
            for m in read_messages(stalled_run["run_dir"] / "bag", topics=[topic])
        }
    )
    assert steps[-1] == rt["ticks"] - 1
    assert max(b - a for a, b in itertools.pairwise(steps)) <= ANSWER_GAP
    assert rt["states_skipped"] >= 0 and rt["answers_skipped"] >= 0
    assert "clock_slips" in rt


def test_sigterm_to_the_runner_ends_every_process_and_leaves_a_summary(
    ros_env: int, tmp_path: Path
) -> None:
    run_dir = tmp_path / "run"
    proc = start_run(realtime_copy(tmp_path / "rt.yaml", 30.0), run_dir, ros_env)
    wait_for_the_clock(run_dir, proc)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    t0 = time.monotonic()
    gone_within(run_dir, 5.0)
    print(f"every node gone {time.monotonic() - t0:.2f} s after SIGTERM")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err[-2000:]
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["health"]["outcome"] == "interrupted"
    (topic,) = [t for t in summary["message_counts"] if t.endswith("/state")]
    states = list(read_messages(run_dir / "bag", topics=[topic]))
    assert 0 < len(states) < 30_000


def test_a_sigkilled_runner_leaves_no_node_behind(ros_env: int, tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    proc = start_run(realtime_copy(tmp_path / "rt.yaml", 30.0), run_dir, ros_env)
    wait_for_the_clock(run_dir, proc)
    assert len(run_pids(run_dir)) == len(ROLES)
    proc.kill()
    proc.communicate(timeout=10)
    print(f"every node gone {gone_within(run_dir, 5.0):.2f} s after the runner's SIGKILL")
