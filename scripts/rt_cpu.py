#!/usr/bin/env python3
"""CPU time of each node process of a realtime (or lockstep) run, per simulated second.

Runs ``python -m servo_axis run`` on each scenario with ``mode: realtime``
(separate processes, recorder on, as the benchmark's realtime cells), reads
every node process's user + system time from ``/proc/<pid>/stat`` until it
exits, and prints, per scenario, the CPU seconds each node used from the
plant's first step to its end, divided by the simulated seconds, next to
the run's deadline misses. A sum near the number of cores means the host
is saturated: misses then come from the work itself, not from the
scheduler's latency (compare with ``scripts/benchmark.py --quick``).

    .venv/bin/python scripts/rt_cpu.py [--duration 2] [--repeat 1] [SCENARIO ...]

``--lockstep`` runs the scenarios in lockstep instead and prints each
node's CPU in us per step: on a 2-core host the plant and the feedback
share one core and the other nodes the other, so the busier core's sum
bounds the steps per second.

    .venv/bin/python scripts/rt_cpu.py --lockstep --duration 4 dlpid_tilt_lpf2
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import yaml

from servo_axis.params.scenario import load_scenario, scenario_dir
from servo_axis.run.processes import pids_of

ROLES = ("plant", "feedback", "feedforward", "learning", "identifier", "recorder")
DEFAULT = ("ptc_nominal", "rptc_detailed", "fast_reversal_sigmoid", "dlpid_tilt_lpf2")


def node_pids(run_dir: Path) -> dict[str, int]:
    """The run's node processes by role."""
    return {role: pids[0] for role in ROLES if (pids := pids_of(run_dir, role))}


def cpu_s(pid: int) -> float | None:
    """User + system CPU seconds of ``pid`` so far (None once it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(name: str, duration_s: float, work: Path, domain: int, mode: str = "realtime") -> dict:
    """One run of ``name``: CPU s per simulated s by role, misses, steps, wall time."""
    data = load_scenario(scenario_dir() / f"{name}.yaml")
    common = data["/**"]["ros__parameters"]
    common["mode"] = mode
    common["duration_s"] = duration_s
    work.mkdir(parents=True, exist_ok=True)
    scenario = work / f"{name}_rt.yaml"
    scenario.write_text(yaml.safe_dump(data, sort_keys=False))
    run_dir = work / f"{name}_run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "servo_axis", "run", str(scenario), "--out", str(run_dir),
         "--domain-id", str(domain), "--no-plots"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    last: dict[str, float] = {}
    at_start: dict[str, float] | None = None
    pids: dict[str, int] = {}
    plant_log = run_dir / "logs" / "plant.log"
    while proc.poll() is None:
        if at_start is None:  # every node has started once the plant runs
            pids.update(node_pids(run_dir))
        for role, pid in pids.items():
            used = cpu_s(pid)
            if used is not None:
                last[role] = used
        if at_start is None and plant_log.exists() and "connected" in plant_log.read_text():
            at_start = dict(last)
        time.sleep(0.05)
    stderr = proc.stderr.read() if proc.stderr else ""
    summary_path = run_dir / "summary.json"
    if not summary_path.exists():
        raise RuntimeError(f"{name}: exit {proc.returncode}: {stderr.strip()[-300:]}")
    summary = json.loads(summary_path.read_text())
    realtime = summary.get("realtime") or {}
    start = at_start or {}
    return {
        "cpu": {r: (v - start.get(r, 0.0)) / duration_s for r, v in last.items()},
        "misses": realtime.get("misses"),
        "ticks": realtime.get("ticks"),
        "exit": proc.returncode,
        "period_s": summary["control_period_s"],
        "realtime_factor": summary.get("realtime_factor"),
    }


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("scenarios", nargs="*", default=list(DEFAULT))
    parser.add_argument("--duration", type=float, default=2.0, help="simulated s per run")
    parser.add_argument("--repeat", type=int, default=1, help="runs per scenario")
    parser.add_argument("--domain-id", type=int, default=97)
    parser.add_argument("--lockstep", action="store_true", help="us per step in lockstep")
    args = parser.parse_args()
    if args.lockstep:
        return lockstep_table(args)
    print(
        f"CPU s per simulated s of each node, realtime, separate processes, recorder on; "
        f"{os.cpu_count()} cores, {time.strftime('%Y-%m-%d %H:%M')}, "
        f"{args.duration:g} simulated s per run\n"
    )
    print(
        "| scenario | plant | feedback | feedforward | learning | identifier | recorder "
        "| sum | misses |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, r in runs(args, "realtime"):
        cells = [f"{r['cpu'][role]:.2f}" if role in r["cpu"] else "-" for role in ROLES]
        share = r["misses"] / r["ticks"] if r["ticks"] else float("nan")
        print(
            f"| {name} | {' | '.join(cells)} | {sum(r['cpu'].values()):.2f} "
            f"| {r['misses']} of {r['ticks']} ({100 * share:.2f} %) |",
            flush=True,
        )
    return 0


def runs(args: argparse.Namespace, mode: str) -> Iterator[tuple[str, dict]]:
    """``(scenario, measure(...))`` for each scenario and repeat, in a temporary directory."""
    with tempfile.TemporaryDirectory(prefix="servo_axis_rt_cpu_") as tmp:
        for name in args.scenarios:
            for k in range(args.repeat):
                yield name, measure(name, args.duration, Path(tmp) / f"{k}", args.domain_id, mode)


def lockstep_table(args: argparse.Namespace) -> int:
    """The ``--lockstep`` table: CPU us per step of each node and the two cores' sums."""
    print(
        f"CPU us per step of each node, lockstep, separate processes, recorder on; "
        f"{os.cpu_count()} cores, {time.strftime('%Y-%m-%d %H:%M')}, "
        f"{args.duration:g} simulated s per run (from the plant's start to its exit)\n"
    )
    print(
        "| scenario | plant | feedback | feedforward | learning | identifier | recorder "
        "| plant + feedback | others | x real time |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, r in runs(args, "lockstep"):
        us = {role: v * r["period_s"] * 1e6 for role, v in r["cpu"].items()}
        cells = [f"{us[role]:.0f}" if role in us else "-" for role in ROLES]
        pair = sum(v for role, v in us.items() if role in ("plant", "feedback"))
        others = sum(us.values()) - pair
        print(
            f"| {name} | {' | '.join(cells)} | {pair:.0f} | {others:.0f} "
            f"| {r['realtime_factor']:.2f}x |",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
