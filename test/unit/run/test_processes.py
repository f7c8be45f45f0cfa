"""How the runner places and stops a run's processes (``run.processes``): stop order, cores.

The recorder is stopped only once every other node has exited: they wait at
their end until their last samples are acknowledged, and the recorder then
writes what is still on its way. Plain Python processes stand in for the
nodes: each notes when SIGINT came and when it exited.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from host_load import RunQueueWait, process_waits_ns, said
from servo_axis.run.processes import Proc, start_process, stop_nodes

# Notes "<role> sigint <t> <w>" and, after `linger` seconds, "<role> exit <t> <w>":
# the time and how long its threads have waited for a CPU so far (ns,
# test/host_load.py), which a busy host adds to when the note is made.
STANDIN = """
import os, signal, sys, time
role, notes, linger = sys.argv[1], sys.argv[2], float(sys.argv[3])
def waited():
    total = 0
    for tid in os.listdir("/proc/self/task"):
        try:
            total += int(open(f"/proc/self/task/{tid}/schedstat").read().split()[1])
        except (OSError, IndexError):
            pass
    return total
def on_sigint(*_):
    with open(notes, "a") as f:
        f.write(f"{role} sigint {time.monotonic()} {waited()}\\n")
    time.sleep(linger)
    with open(notes, "a") as f:
        f.write(f"{role} exit {time.monotonic()} {waited()}\\n")
    sys.exit(0)
signal.signal(signal.SIGINT, on_sigint)
print("ready", flush=True)
while True:
    time.sleep(0.01)
"""


def start(
    role: str, notes: Path, tmp_path: Path, linger_s: float, ignore_sigint: bool = False
) -> Proc:
    code = STANDIN
    if ignore_sigint:
        code = code.replace("on_sigint)", "signal.SIG_IGN)")
    env = {**os.environ, "SERVO_AXIS_PIN": "0"}
    proc = start_process(
        role, ["-c", code, role, str(notes), str(linger_s)], env, tmp_path / f"{role}.log"
    )
    deadline = time.monotonic() + 20
    while "ready" not in (tmp_path / f"{role}.log").read_text():
        assert time.monotonic() < deadline, f"{role} did not start"
        time.sleep(0.01)
    return proc


def events(notes: Path) -> dict[tuple[str, str], float]:
    """When each stand-in noted each event (monotonic s)."""
    return {(role, what): t for (role, what), (t, _) in noted(notes).items()}


def noted(notes: Path) -> dict[tuple[str, str], tuple[float, int]]:
    """When each stand-in noted each event (s) and its threads' CPU wait by then (ns)."""
    out = {}
    for line in notes.read_text().splitlines():
        role, what, t, wait = line.split()
        out[(role, what)] = (float(t), int(wait))
    return out


def waits_ns(procs: list[Proc]) -> dict[str, int]:
    """Each live stand-in's threads' CPU wait so far (ns)."""
    return {p.role: process_waits_ns(p.popen.pid) for p in procs}


@pytest.fixture
def notes(tmp_path: Path) -> Path:
    return tmp_path / "notes.txt"


def test_the_recorder_is_interrupted_only_after_every_other_node_exited(
    tmp_path: Path, notes: Path
) -> None:
    procs = [
        start("recorder", notes, tmp_path, 0.05),
        start("plant", notes, tmp_path, 0.3),
        start("feedback", notes, tmp_path, 0.5),
    ]
    codes = stop_nodes(procs)
    assert codes == {"recorder": 0, "plant": 0, "feedback": 0}
    got = events(notes)
    # The others were interrupted together, before either exited ...
    assert got[("plant", "sigint")] < got[("feedback", "exit")]
    assert got[("feedback", "sigint")] < got[("plant", "exit")]
    # ... and the recorder after both had.
    assert got[("recorder", "sigint")] >= max(got[("plant", "exit")], got[("feedback", "exit")])


def test_a_node_that_ignores_sigint_delays_the_recorder_by_the_timeout_only(
    tmp_path: Path, notes: Path
) -> None:
    procs = [
        start("recorder", notes, tmp_path, 0.0),
        start("plant", notes, tmp_path, 0.0, ignore_sigint=True),
    ]
    before = waits_ns(procs)
    host = RunQueueWait()
    started = time.monotonic()
    codes = stop_nodes(procs, timeout_s=0.5)
    assert codes["plant"] < 0  # killed
    assert codes["recorder"] == 0
    t, wait_ns = noted(notes)[("recorder", "sigint")]
    # After the timeout, and later only by what a busy host kept this
    # process and the recorder waiting (it needs the CPU to make its note).
    wait = host.seconds() + (wait_ns - before["recorder"]) * 1e-9
    assert 0.45 <= t - started < 3.0 + wait, said(t - started, 3.0, wait)


def test_a_run_stopped_by_a_signal_has_every_process_gone_within_the_total(
    tmp_path: Path, notes: Path
) -> None:
    """With ``total_s`` the others get 60 % of it and the recorder the rest (at least 1 s)."""
    procs = [
        start("recorder", notes, tmp_path, 0.0),
        start("plant", notes, tmp_path, 0.0, ignore_sigint=True),
    ]
    before = waits_ns(procs)
    host = RunQueueWait()
    started = time.monotonic()
    codes = stop_nodes(procs, timeout_s=30.0, total_s=2.0)
    elapsed, self_wait = time.monotonic() - started, host.seconds()
    assert codes["plant"] < 0 and codes["recorder"] == 0
    # 60 % of the total, then the recorder's second (it exits at once): the
    # product's SIGKILLs hold every process within 2.2 s; 0.3 s for the
    # reaping, and a busy host adds what it kept this process and the
    # recorder waiting (the killed plant needs little CPU to go).
    (t, sigint_ns), (_, exit_ns) = (noted(notes)[("recorder", what)] for what in ("sigint", "exit"))
    wait = self_wait + (exit_ns - before["recorder"]) * 1e-9
    assert elapsed < 2.5 + wait, said(elapsed, 2.5, wait)
    wait = self_wait + (sigint_ns - before["recorder"]) * 1e-9
    assert 1.15 <= t - started < 1.6 + wait, said(t - started, 1.6, wait)


@pytest.mark.parametrize("cores", [[0, 1], [2, 5, 7]])
def test_cores_are_shared_out_by_time_mode(cores: list[int]) -> None:
    from servo_axis.run.processes import cpu_set

    rest = set(cores[1:])
    # Lockstep: the pair takes turns on the first core, the others get the rest.
    for role in ("plant", "feedback"):
        assert cpu_set(role, cpus=cores) == {cores[0]}
    for role in ("feedforward", "learning", "identifier", "recorder", "composed", "live"):
        assert cpu_set(role, cpus=cores) == rest
    # Realtime: the plant's core is shared only with the nodes that answer
    # nothing within a period; the feedback is on the others.
    for role in ("plant", "identifier", "learning"):
        assert cpu_set(role, realtime=True, cpus=cores) == {cores[0]}
    for role in ("feedback", "feedforward", "recorder", "composed", "live"):
        assert cpu_set(role, realtime=True, cpus=cores) == rest
    # One core: nothing to share out.
    assert cpu_set("plant", cpus=cores[:1]) is None
    assert cpu_set("feedback", realtime=True, cpus=cores[:1]) is None
