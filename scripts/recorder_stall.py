"""How long a run stalls when its recorder stops for a while (SIGSTOP) mid-run.

Runs a scenario (``duration_s`` set to ``--duration``) through ``python -m
servo_axis run``; once the plant has connected and ``--after`` seconds have
passed, stops the recorder process with SIGSTOP for ``--stop`` seconds and
continues it. The plant waits for the recorder (flow control), so the run's
stepping time (``wall_time_s`` of ``summary.json``) grows by at least the
stop. What comes on top is the repair of what was lost while the recorder
did not read: a sample dropped from a full shared-memory port is sent again
only after the writer's next heartbeat. Prints each run's stepping time and
the excess over the mean of ``--plain`` runs without a stop::

    .venv/bin/python scripts/recorder_stall.py --runs 10 --stop 1.0

Run on purpose, not by the tests.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

CONFIG = Path(__file__).resolve().parents[1] / "config"


def one_run(scenario: Path, out: Path, domain: int, stop_s: float, after_s: float) -> float:
    """The run's stepping time (s); the recorder stopped for ``stop_s`` once connected."""
    cmd = [sys.executable, "-m", "servo_axis", "run", str(scenario), "--out", str(out)]
    cmd += ["--domain-id", str(domain), "--no-plots"]
    proc = subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    plant_log = out / "logs" / "plant.log"
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline and proc.poll() is None:
        if plant_log.exists() and "connected" in plant_log.read_text():
            break
        time.sleep(0.01)
    if stop_s > 0:
        time.sleep(after_s)
        found = subprocess.run(
            ["pgrep", "-f", f"servo_axis.nodes.recorder.*{out}"],
            capture_output=True,
            text=True,
            check=False,
        ).stdout.split()
        if not found:
            raise RuntimeError(f"{out}: no recorder process to stop")
        pid = int(found[0])
        os.kill(pid, signal.SIGSTOP)
        time.sleep(stop_s)
        os.kill(pid, signal.SIGCONT)
    code = proc.wait(timeout=120)
    if code != 0:
        raise RuntimeError(f"{out}: the run exited {code}")
    return float(json.loads((out / "summary.json").read_text())["wall_time_s"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="ptc_nominal")
    parser.add_argument("--duration", type=float, default=5.0, help="simulated seconds")
    parser.add_argument("--runs", type=int, default=10, help="runs with a stop")
    parser.add_argument("--plain", type=int, default=2, help="runs without a stop")
    parser.add_argument("--stop", type=float, default=1.0, help="seconds the recorder stops")
    parser.add_argument("--after", type=float, default=0.2, help="seconds after connecting")
    parser.add_argument("--domain-id", type=int, default=150)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="servo_axis_stall_") as tmp:
        data = yaml.safe_load((CONFIG / f"{args.scenario}.yaml").read_text())
        data["/**"]["ros__parameters"]["duration_s"] = args.duration
        scenario = Path(tmp) / f"{args.scenario}.yaml"
        scenario.write_text(yaml.safe_dump(data))
        plain = [
            one_run(scenario, Path(tmp) / f"plain{i}", args.domain_id, 0.0, 0.0)
            for i in range(args.plain)
        ]
        base = statistics.fmean(plain)
        print(f"without a stop: {', '.join(f'{w:.2f}' for w in plain)} s (mean {base:.2f} s)")
        excess = []
        for i in range(args.runs):
            wall = one_run(scenario, Path(tmp) / f"run{i}", args.domain_id, args.stop, args.after)
            excess.append(wall - base - args.stop)
            print(f"run {i + 1:>2}: {wall:.2f} s, {excess[-1]:+.2f} s beyond the stop", flush=True)
    stalled = sum(e > 0.5 for e in excess)
    print(
        f"{args.scenario}, recorder stopped {args.stop} s: {stalled} of {args.runs} runs "
        f"stalled more than 0.5 s beyond the stop (max {max(excess):+.2f} s)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
