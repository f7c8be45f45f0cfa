"""``identify`` on a run of the node graph: the same fit as the plain calls, a scenario that runs, bad input.

One short excitation (``measure_frf_ball_screw`` with periods of 0.5 s, 1
to settle and 3 averaged: 3 s) through ``python -m servo_axis run``, in a
run made 4 s long whose processes are all SIGKILLed (the runner and its
nodes, as a crash loses a run) once the excitation is recorded: it leaves
no ``summary.json`` and an unfinished bag, ``summary`` says to run ``bag
recover``, which makes the bag readable and writes the summary of what was
recorded. ``identify`` on that directory must give exactly what the
plain-call loop of the 3 s scenario gives (the node graph reproduces it bit
for bit, the recovered bag holds every sample of the excitation), the same
once the scenario file has moved and been edited, the scenario it writes
must run through the node graph as it is, and bad input must be one line
and exit 2.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from numpy.testing import assert_allclose
from run_support import CONFIG

from servo_axis.__main__ import main
from servo_axis.analysis.summary import RunSummary, load_summary
from servo_axis.identify.data import from_simulation
from servo_axis.identify.driver import identify
from servo_axis.params.scenario import load_scenario
from servo_axis.recording.reader import read_raw
from servo_axis.run.fastdds import clean_stale_shm
from servo_axis.run.processes import ros_environment
from servo_axis.run.progress import ProgressWatcher

pytestmark = pytest.mark.integration


def _cli(domain: int, tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "servo_axis", *args],
        env=ros_environment(domain, tmp_path / "ros_log"),
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def _run_killed_after(scenario: Path, run: Path, domain: int, steps: int, logs: Path) -> None:
    """``run scenario --out run``, every process of it SIGKILLed once ``steps`` are written.

    The recorder acknowledges the steps it has written on ``recorder/progress``
    and flushes every 0.25 s. Once ``steps`` are acknowledged the plant is
    stopped (SIGSTOP: in lockstep no step is taken without it, however fast
    the machine, so the run cannot reach its end first), 0.6 s later they
    are all on disk, and the runner and its nodes are SIGKILLed at once.
    """
    started = time.time()
    command = ["run", str(scenario), "--out", str(run), "--domain-id", str(domain), "--no-plots"]
    runner = subprocess.Popen(
        [sys.executable, "-m", "servo_axis", *command],
        env=ros_environment(domain, logs),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    watcher = ProgressWatcher("/x", domain_id=domain)
    try:
        deadline = time.monotonic() + 240
        while watcher.steps < steps:
            assert runner.poll() is None and time.monotonic() < deadline, "the run did not go on"
            watcher.spin(0.05)
        (plant,) = _processes("servo_axis.nodes.plant", str(run))
        os.kill(plant, signal.SIGSTOP)
        flushed = time.monotonic() + 0.6
        while time.monotonic() < flushed:
            watcher.spin(0.05)
    finally:
        watcher.close()
        os.killpg(runner.pid, signal.SIGKILL)  # the runner; its nodes by PR_SET_PDEATHSIG
        runner.communicate(timeout=60)
    for _ in range(100):
        if not _processes(str(run)):
            break
        time.sleep(0.1)
    else:
        raise AssertionError("node processes outlived their SIGKILLed runner")
    clean_stale_shm(since=started)  # what the SIGKILLed participants left in /dev/shm


def _processes(*texts: str) -> list[int]:
    """PIDs of live processes whose command line holds every one of ``texts``."""
    found = []
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            line = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (proc / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if state != "Z" and all(t in line for t in texts):
            found.append(int(proc.name))
    return found


def test_identify_a_node_graph_run(
    ros_env: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = load_scenario(CONFIG / "measure_frf_ball_screw.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = 3.0
    data["feedforward"]["ros__parameters"]["excitation"].update(
        period_s=0.5, periods=3, settle_periods=1, start_s=1.0
    )
    scenario = tmp_path / "frf_short.yaml"  # the plain-call loop's: the excitation, 3 s
    scenario.write_text(yaml.safe_dump(data, sort_keys=False))
    data["/**"]["ros__parameters"]["duration_s"] = 4.0
    scenario = tmp_path / "frf.yaml"  # the run's: killed once it has recorded 3.05 s of 4
    scenario.write_text(yaml.safe_dump(data, sort_keys=False))
    run = tmp_path / "frf"
    _run_killed_after(scenario, run, ros_env, 6100, tmp_path / "ros_log")

    # Killed with its nodes: no summary, and summary says what to do.
    assert not (run / "summary.json").exists()
    capsys.readouterr()
    assert main(["summary", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"python -m servo_axis bag recover {run / 'bag'}" in err
    assert main(["bag", "recover", str(run / "bag")]) == 0
    said = capsys.readouterr().out.splitlines()
    assert said[0].startswith(f"{run / 'bag'}: recovered ") and len(said) == 2
    assert said[1].startswith(f"{run}: summary.json written, of the ")
    # The summary of what was recorded: every state in the bag, and why it ends there.
    states = sum(1 for m in read_raw(run / "bag") if m.topic == "/x/state")
    summary = load_summary(run)
    assert isinstance(summary, RunSummary) and summary.health is not None
    # (the excitation ends at step 6000: 1 s + (1 + 3) x 0.5 s at T_u = 0.5 ms)
    assert 6100 <= summary.steps == states < 8000 and summary.sim_time_s == states * 5e-4
    assert summary.health.outcome == "failed" and summary.health.bag_recovered
    assert f"{states} of its 8000 steps were recorded" in summary.health.reasons[0]
    assert summary.scenario_file == str(scenario)
    assert main(["summary", str(run)]) == 0
    assert "this summary was made after the run" in capsys.readouterr().out

    out = tmp_path / "fitted.yaml"
    code = main(
        [
            "identify",
            str(run),
            "--model",
            "ball_screw",
            "--out",
            str(out),
            "--report",
            str(tmp_path / "report"),
        ]
    )
    assert code == 0, capsys.readouterr().err
    # The fit of the recorded run is the fit of the plain-call loop, key for key.
    plain = identify("ball_screw", [from_simulation(tmp_path / "frf_short.yaml")])
    written = yaml.safe_load(out.read_text())["plant"]["ros__parameters"]
    assert_allclose(written["inertia_kgm2"], plain.key("inertia_kgm2").value, rtol=1e-12)
    assert_allclose(
        written["modes"]["frequency_hz"][0], plain.key("modes.frequency_hz[0]").value, rtol=1e-12
    )
    truth = data["plant"]["ros__parameters"]
    assert_allclose(written["inertia_kgm2"], truth["inertia_kgm2"], rtol=0.03)
    assert_allclose(written["modes"]["frequency_hz"], truth["modes"]["frequency_hz"], rtol=0.03)
    for name in ("report.md", "bode_encoder.png"):
        assert (tmp_path / "report" / name).is_file()

    # The run directory is all identify needs: the scenario file moved, and one
    # edited in its place (another excitation, another plant) change nothing.
    scenario.rename(tmp_path / "moved.yaml")
    edited = load_scenario(tmp_path / "moved.yaml")
    edited["feedforward"]["ros__parameters"]["excitation"]["settle_periods"] = 2
    edited["plant"]["ros__parameters"]["current_limit_A"] = 12.3  # a key the fit copies
    scenario.write_text(yaml.safe_dump(edited, sort_keys=False))
    (tmp_path / "after_the_move").mkdir()
    again_out = tmp_path / "after_the_move" / out.name  # the name is the file's stem
    assert main(["identify", str(run), "--model", "ball_screw", "--out", str(again_out)]) == 0
    assert yaml.safe_load(again_out.read_text()) == yaml.safe_load(out.read_text())

    def fitted(path: Path) -> list[str]:  # the header's "key = value +- error (source)" lines
        return [s for s in path.read_text().splitlines() if s.startswith("#   ") and " = " in s]

    assert len(fitted(out)) > 3 and fitted(again_out) == fitted(out)

    # The written scenario runs as it is (the excitation off: the measurement's move).
    again = tmp_path / "again"
    done = _cli(
        ros_env,
        tmp_path,
        "run",
        str(out),
        "--out",
        str(again),
        "--domain-id",
        str(ros_env),
        "--no-plots",
    )
    assert done.returncode == 0, done.stderr[-3000:]

    # Bad input: one line on stderr, exit 2.
    bad = {
        "no excitation": (str(again), "ball_screw"),
        "the data do not determine": (str(run), "elastic_ball_screw"),
        "not a run directory": (str(tmp_path / "missing"), "ball_screw"),
    }
    capsys.readouterr()
    for words, (run_dir, model) in bad.items():
        code = main(["identify", run_dir, "--model", model, "--out", str(tmp_path / "x.yaml")])
        err = capsys.readouterr().err
        assert code == 2, (words, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], (words, err)
    assert not (tmp_path / "x.yaml").exists()
