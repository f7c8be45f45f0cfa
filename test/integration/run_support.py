"""Helpers of the integration tests: the processes of a run, shortened paper-001 scenarios."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from servo_axis.params.scenario import load_scenario
from servo_axis.run.processes import pids_of

CONFIG = Path(__file__).resolve().parents[2] / "config"
#: Trials of 0.5 s; Ref. 1 for trials 1-5, Ref. 2 from trial 6; 7 trials.
TRIAL_S = 0.5
SWITCH = 6
TRIALS = 7


def short_trials(law: str, path: Path) -> Path:
    """``pilc_ref_change_<law>`` with trials of 0.5 s and the switch at trial 6, written to ``path``."""
    data = load_scenario(CONFIG / f"pilc_ref_change_{law}.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = TRIAL_S * TRIALS
    ff = data["feedforward"]["ros__parameters"]
    ff["reference"].update(
        trial_s=TRIAL_S,
        amplitudes_m=[0.002, 0.003],
        move_times_s=[0.35, 0.3],
        start_times_s=[0.05, 0.1],
        first_trials=[1, SWITCH],
    )
    ff["learning"]["cycle_s"] = TRIAL_S
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def run_and_kill(
    path: Path,
    run_dir: Path,
    domain: int,
    role: str,
    memory: Path,
    ready: Callable[[dict[str, Any]], bool],
    what: str,
    timeout_s: float = 60.0,
) -> tuple[int, str]:
    """``python -m servo_axis run`` with ``role`` SIGKILLed once its ``memory`` file says ``ready``.

    Returns the run's exit code and its standard error; the run is always
    reaped. ``what`` names what never happened if the kill never came.
    """
    proc = subprocess.Popen(
        [sys.executable, "-m", "servo_axis", "run", str(path), "--out", str(run_dir),
         "--domain-id", str(domain), "--no-plots"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "ROS_DOMAIN_ID": str(domain)},
    )  # fmt: skip
    try:
        deadline = time.monotonic() + timeout_s
        while True:
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, what
            try:
                if ready(json.loads(memory.read_text())):
                    break
            except (OSError, ValueError, KeyError, TypeError):
                pass  # not written yet, or being replaced
            time.sleep(0.005)
        (pid,) = pids_of(run_dir, role)
        os.kill(pid, signal.SIGKILL)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, stderr


def shm_names() -> set[str]:
    """The names in /dev/shm now."""
    return {p.name for p in Path("/dev/shm").iterdir()}


def shm_mapped_by(pids: list[int] | None = None) -> set[str]:
    """The /dev/shm names that ``pids`` (None: every process) map now."""
    paths = [Path(f"/proc/{pid}/maps") for pid in pids] if pids is not None else None
    mapped: set[str] = set()
    for maps in paths if paths is not None else Path("/proc").glob("[0-9]*/maps"):
        try:
            text = maps.read_text()
        except OSError:
            continue
        mapped.update(line.rsplit("/", 1)[-1] for line in text.splitlines() if "/dev/shm/" in line)
    return mapped


def _segment(name: str) -> str:
    if name.startswith("sem.") and name.endswith("_mutex"):
        return name[len("sem.") : -len("_mutex")]
    return name.removesuffix("_el")


def shm_left_behind(before: set[str], ours: set[str] | None = None) -> set[str]:
    """Fast DDS shared-memory files made since ``before`` that no live process holds.

    A file another process of the machine maps (a run of someone else's on
    the same host) is not left behind: only an orphan is. A segment's lock
    file (``_el``) and a port's semaphore count as held when their segment is.
    With ``ours`` (what the run's processes mapped, :func:`shm_mapped_by`
    before a kill) only their files count: on a host others use too, their
    SIGKILLed participants' orphans appear meanwhile (measured: a port
    segment of domain 122 during a run in 221; the ``fastrtps_port70xx``
    segments are every domain's).
    """
    new = {n for n in shm_names() - before if "fastrtps" in n}
    if ours is not None:
        new = {n for n in new if _segment(n) in {_segment(o) for o in ours}}
    if not new:
        return set()
    mapped = shm_mapped_by()
    return {n for n in new if n not in mapped and _segment(n) not in mapped}


def cpu_hogs() -> int:
    """CPU-bound jobs beside a test's runs: two, or one where another pytest-xdist worker
    runs tests at the same time (scripts/test.sh: two workers on a 2-core host), whose
    runs keep the other core busy (two hogs as well took 90 s of CPU from its tests)."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    return 2 if workers <= 1 else 1
