"""A study on a real dask cluster survives a killed worker and equals a serial run.

Starts ``dask scheduler`` and two ``dask worker`` processes (one thread
each, no nanny: the process started is the worker) on 127.0.0.1, runs a
20-point study of ``pid_disturbance`` (20 s of simulated time per point,
about 0.25 s each: long enough that the worker dies with points still to
do) through ``python -m servo_axis sweep --scheduler``, SIGKILLs one
worker once a few points are done, and checks that every point is in the
table with the same figures as a serial, in-process run of the
same points (:func:`servo_axis.sweep.point.run_point`, no dask). Every
process is reaped.
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from servo_axis.sweep.point import run_point
from servo_axis.sweep.spec import load_study

pytestmark = pytest.mark.integration

DASK = str(Path(sys.executable).with_name("dask"))
STUDY = """\
name: dask_kill
scenario: pid_disturbance
set:
  /**.duration_s: 20.0
grid:
  feedback.bandwidth_hz: [20.0, 25.0, 30.0, 35.0, 40.0]
  disturbance.amplitude_Nm: [0.25, 0.5, 0.75, 1.0]
figures:
  max: tracking_error.all_samples.max_m
  rms_last: tracking_error.cycles[-1].rms_m
"""


def _reap(procs: list[subprocess.Popen[bytes]]) -> None:
    """The workers killed, then the scheduler stopped.

    A worker told to stop (SIGTERM) once the scheduler stops too hangs in
    its own close (``CancelledError`` in ``rpc.close``, distributed of requirements.lock) and held
    every run of this test 15 s at the end; nothing of it is under test.
    """
    scheduler, *workers = procs
    for p in workers:
        if p.poll() is None:
            p.kill()
        p.wait(timeout=5)
    if scheduler.poll() is None:
        scheduler.send_signal(signal.SIGTERM)
    try:
        scheduler.wait(timeout=15)
    except subprocess.TimeoutExpired:
        scheduler.kill()
        scheduler.wait(timeout=5)


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """``(scheduler address, [scheduler, worker 1, worker 2])`` on 127.0.0.1."""
    sched_file = tmp_path / "scheduler.json"
    logs = tmp_path / "logs"
    logs.mkdir()
    procs: list[subprocess.Popen[bytes]] = []
    # A worker the test kills leaves its point's temporary folder behind: here, not in /tmp.
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "TMPDIR": str(tmp_path / "tmp")}

    def start(name: str, *args: str) -> subprocess.Popen[bytes]:
        with (logs / f"{name}.log").open("wb") as log:
            p = subprocess.Popen([DASK, *args], stdout=log, stderr=subprocess.STDOUT, env=env)
        procs.append(p)
        return p

    try:
        start(
            "scheduler",
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--no-dashboard",
            "--scheduler-file",
            str(sched_file),
        )
        deadline = time.monotonic() + 60
        while not sched_file.is_file() or not sched_file.read_text().strip():
            assert time.monotonic() < deadline, (logs / "scheduler.log").read_text()
            assert procs[0].poll() is None, (logs / "scheduler.log").read_text()
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        for i in (1, 2):
            start(
                f"worker{i}",
                "worker",
                "--scheduler-file",
                str(sched_file),
                "--host",
                "127.0.0.1",
                "--nthreads",
                "1",
                "--no-nanny",
                "--no-dashboard",
                "--name",
                f"w{i}",
            )
        from dask.distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address, procs
    finally:
        _reap(procs)


def test_a_killed_worker_loses_no_point_and_the_table_equals_a_serial_run(
    tmp_path: Path, cluster: tuple[str, list[subprocess.Popen[bytes]]]
) -> None:
    address, procs = cluster
    study_file = tmp_path / "dask_kill.yaml"
    study_file.write_text(STUDY)
    out = tmp_path / "out"
    t0 = time.perf_counter()
    sweep = subprocess.Popen(
        [sys.executable, "-m", "servo_axis", "sweep", str(study_file), "--out", str(out),
         "--scheduler", address, "--no-plots"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )  # fmt: skip
    try:
        manifest = out / "manifest.json"
        done_at_kill = 0
        deadline = time.monotonic() + 120
        while sweep.poll() is None and time.monotonic() < deadline:
            if manifest.is_file():
                try:
                    done_at_kill = len(json.loads(manifest.read_text())["rows"])
                except (json.JSONDecodeError, KeyError):
                    done_at_kill = 0
                if done_at_kill >= 3:
                    break
            time.sleep(0.05)
        assert sweep.poll() is None, "the study ended before a worker could be killed"
        os.kill(procs[1].pid, signal.SIGKILL)
        killed_at = time.perf_counter() - t0
        _, stderr = sweep.communicate(timeout=300)
    finally:
        if sweep.poll() is None:
            sweep.kill()
            sweep.wait()
    wall = time.perf_counter() - t0
    assert procs[1].wait(timeout=10) == -signal.SIGKILL
    assert sweep.returncode == 0, stderr.decode()[-2000:]
    assert 3 <= done_at_kill < 20

    with (out / "results.csv").open() as f:
        table = list(csv.DictReader(f))
    assert [int(r["point"]) for r in table] == list(range(20))
    assert all(r["status"] == "ok" for r in table), [r["error"] for r in table]

    import pyarrow.parquet as pq

    parquet = pq.read_table(out / "results.parquet").to_pylist()
    study = load_study(study_file)
    t1 = time.perf_counter()
    serial = [run_point(i, study.scenario, p, study.figures) for i, p in enumerate(study.points)]
    serial_s = time.perf_counter() - t1
    for got, want, text in zip(parquet, serial, table, strict=True):
        assert want["status"] == "ok", want["error"]
        for key in ("point", "feedback.bandwidth_hz", "disturbance.amplitude_Nm"):
            assert got[key] == want[key]
        for key in ("max", "rms_last"):
            assert math.isfinite(want[key]) and want[key] > 0
            # Bit for bit: the same loops, the same numbers on every worker.
            assert got[key] == want[key], (got["point"], key)
            assert float(text[key]) == want[key]
    # A figure that could differ: the error grows with the disturbance.
    maxima = np.array([r["max"] for r in serial]).reshape(5, 4)
    assert np.all(np.diff(maxima, axis=1) > 0)
    np.testing.assert_allclose(maxima[:, 1] / maxima[:, 0], 2.0, rtol=1e-6)
    print(
        f"\n20 points on 2 workers: killed one at {killed_at:.1f} s with {done_at_kill} done, "
        f"study done in {wall:.1f} s (scheduler client incl.); serial in-process {serial_s:.1f} s"
    )
