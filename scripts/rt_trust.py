#!/usr/bin/env python3
"""Realtime a user can trust (issue 30): the acceptance table, as a markdown table.

For every shipped scenario (or those named) a short realtime copy (``--seconds``
simulated, separate processes, recorder on) through ``python -m servo_axis run``,
quiet and with ``--hogs`` CPU-bound processes at the default priority beside it;
for each: the exit code, the misses against the floor of a bare rclpy pair at the
same period measured in the same invocation with the same hogs (``python -m
servo_axis floor``), the wall time and whether the run
ended by itself (not stopped by this script's time limit). Then three runs of
``ptc_nominal`` under the same loads: the stall (SIGSTOP of the feedback for
0.3 s mid-run: does the loop close again after it, the misses, what was skipped),
the SIGTERM (time from SIGTERM to the runner until every process of the run is
gone), and ``xy_circle`` is one of the scenarios (two axes). With ``--reps N``
each scenario runs N times per load, each repeat after a floor of its own; the
misses and the floors' misses are summed over the repeats before their ratio
(a 2 s run at 1 ms expects about 7 misses of the floor: one run's ratio is noise).

Run it on a quiet machine (it is the measurement, not a test)::

    .venv/bin/python scripts/rt_trust.py                   # every scenario, quiet and 2 hogs
    .venv/bin/python scripts/rt_trust.py ptc_nominal --hogs 0 --no-floor   # a quick look
    .venv/bin/python scripts/rt_trust.py ptc_friction ptc_nominal --hogs 0 --reps 5 --no-extra
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

from benchmark import measure_floor, prepared  # noqa: E402

#: Roles whose processes a run starts (pgrep by the run's parameter file).
ROLES = ("plant", "feedback", "feedforward", "identifier", "learning", "recorder")
#: The SIGSTOP of the feedback in the stall run, s.
STALL_S = 0.3


def start_hogs(n: int) -> list[subprocess.Popen[bytes]]:
    """``n`` CPU-bound processes at the default priority (unpinned)."""
    return [
        subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True)
        for _ in range(n)
    ]


def stop_hogs(hogs: list[subprocess.Popen[bytes]]) -> None:
    for h in hogs:
        h.kill()
        h.wait()


def run_pids(run_dir: Path) -> list[int]:
    """Every live process of the run in ``run_dir`` (its axes' too)."""
    pids = []
    for role in ROLES:
        out = subprocess.run(
            ["pgrep", "-f", f"servo_axis.nodes.{role} .*{run_dir}/"],
            capture_output=True, text=True, check=False,
        )  # fmt: skip
        pids += [int(p) for p in out.stdout.split()]
    return pids


def plant_clock_running(run_dir: Path) -> int | None:
    """The pid of a plant of the run whose realtime clock thread runs, else None."""
    for pid in run_pids(run_dir):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
            if b"servo_axis.nodes.plant" not in cmd:
                continue
            for task in Path(f"/proc/{pid}/task").iterdir():
                if (task / "comm").read_text().strip() == "plant-clock":
                    return pid
        except OSError:
            continue
    return None


def role_pid(run_dir: Path, role: str) -> int | None:
    out = subprocess.run(
        ["pgrep", "-f", f"servo_axis.nodes.{role} .*{run_dir}/"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    pids = [int(p) for p in out.stdout.split()]
    return pids[0] if pids else None


def wait_for_clock(run_dir: Path, proc: subprocess.Popen[str], timeout_s: float = 120.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and proc.poll() is None:
        if plant_clock_running(run_dir) is not None:
            return True
        time.sleep(0.05)
    return False


def run(
    scenario: Path,
    run_dir: Path,
    domain: int,
    simulated_s: float,
    floor: Path | None,
    during: Callable[[subprocess.Popen[str], Path], dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """One run through the command line; what ``during`` measured while it ran."""
    cmd = [sys.executable, "-m", "servo_axis", "run", str(scenario), "--out", str(run_dir),
           "--domain-id", str(domain), "--no-plots"]  # fmt: skip
    if floor is not None:
        cmd += ["--floor", str(floor)]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    extra = during(proc, run_dir) if during is not None else {}
    limit = 3 * simulated_s + 120.0  # beyond the runner's own overtime bound
    ended = True
    try:
        _, err = proc.communicate(timeout=max(1.0, limit - (time.monotonic() - t0)))
    except subprocess.TimeoutExpired:
        ended = False
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate()
    wall = time.monotonic() - t0
    for pid in run_pids(run_dir):  # nothing of the run may be left
        extra["left_behind"] = extra.get("left_behind", 0) + 1
        os.kill(pid, signal.SIGKILL)
    summary_path = run_dir / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    return {"code": proc.returncode, "wall_s": wall, "ended": ended, "summary": summary,
            "stderr": err[-400:], **extra}  # fmt: skip


def realtime_blocks(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """The ``realtime`` block of each axis of a summary."""
    if "realtime" in summary:
        return [summary["realtime"]]
    return [a["realtime"] for a in summary.get("axes", {}).values() if "realtime" in a]


def pooled_floor(floors: list[dict[int, dict]]) -> dict[int, dict]:
    """The floor's misses and ticks summed over repeats, by period in us, with their ``miss_pct``."""
    out: dict[int, dict] = {}
    for floor in floors:
        for period, f in floor.items():
            o = out.setdefault(period, {"misses": 0, "ticks": 0})
            o["misses"] += f["misses"]
            o["ticks"] += f["ticks"]
    for o in out.values():
        o["miss_pct"] = 100 * o["misses"] / max(o["ticks"], 1)
    return out


def misses_text(summaries: list[dict[str, Any]], floor: dict[int, dict]) -> tuple[str, str]:
    """``misses/ticks`` summed over the repeats (each run's misses in brackets when more
    than one), and their ratio to the floor's at the same period (pooled over its repeats)."""
    per_axis: dict[int, list[dict[str, Any]]] = {}
    for summary in summaries:
        for i, rt in enumerate(realtime_blocks(summary)):
            per_axis.setdefault(i, []).append(rt)
    if not per_axis:
        return "-", "-"
    parts, ratios = [], []
    for blocks in per_axis.values():
        misses, ticks = sum(b["misses"] for b in blocks), sum(b["ticks"] for b in blocks)
        each = f" ({' '.join(str(b['misses']) for b in blocks)})" if len(blocks) > 1 else ""
        parts.append(f"{misses}/{ticks}{each}")
        f = floor.get(round(blocks[0]["period_ns"] / 1000))
        if f is not None:
            expected = f["miss_pct"] / 100 * ticks
            ratios.append(f"{misses / max(expected, 1.0):.2f}x ({f['miss_pct']:.2f} %)")
    return ", ".join(parts), ", ".join(ratios) or "-"


def stall_during(proc: subprocess.Popen[str], run_dir: Path) -> dict[str, Any]:
    if not wait_for_clock(run_dir, proc):
        return {"stall": "the clock never started"}
    time.sleep(0.8)
    feedback = role_pid(run_dir, "feedback")
    if feedback is None:
        return {"stall": "no feedback"}
    os.kill(feedback, signal.SIGSTOP)
    time.sleep(STALL_S)
    os.kill(feedback, signal.SIGCONT)
    return {"stall": "done"}


def sigterm_during(proc: subprocess.Popen[str], run_dir: Path) -> dict[str, Any]:
    if not wait_for_clock(run_dir, proc):
        return {"gone_s": None}
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    t0 = time.monotonic()
    while run_pids(run_dir) and time.monotonic() - t0 < 30.0:
        time.sleep(0.02)
    return {"gone_s": time.monotonic() - t0 if not run_pids(run_dir) else None}


def loop_closed_again(run_dir: Path, summary: dict[str, Any]) -> str:
    """Whether the feedback answered to the end after the stall (its last command's step)."""
    from servo_axis.recording.deserialize import read_messages

    topics = [t for t in summary.get("message_counts", {}) if t.endswith("/command")]
    rt = summary.get("realtime")
    if not topics or rt is None:
        return "-"
    steps = sorted(
        (m.message.header.stamp.sec * 10**9 + m.message.header.stamp.nanosec) // rt["period_ns"]
        for m in read_messages(run_dir / "bag", topics=topics)
    )
    gaps = max((b - a for a, b in itertools.pairwise(steps)), default=0)
    last_ok = bool(steps) and steps[-1] == rt["ticks"] - 1
    return f"{'yes' if last_ok else 'NO'} (last {steps[-1] if steps else '-'}, max gap {gaps})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", help="scenario names (default: every shipped one)")
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated s of each copy")
    parser.add_argument("--hogs", type=int, nargs="+", default=[0, 2], help="loads to measure")
    parser.add_argument("--no-floor", action="store_true", help="skip the floor (servo_axis floor)")
    parser.add_argument("--domain-id", type=int, default=77)
    parser.add_argument("--no-extra", action="store_true", help="no stall and SIGTERM runs")
    parser.add_argument(
        "--reps", type=int, default=1,
        help="runs of each scenario (and floors) per load; misses are pooled over them",
    )  # fmt: skip
    args = parser.parse_args()
    if args.reps < 1:
        parser.error(f"--reps: expected at least 1, got {args.reps}")
    names = args.scenarios or sorted(p.stem for p in (REPO / "config").glob("*.yaml"))
    tmp = Path(tempfile.mkdtemp(prefix="rt_trust_"))
    rows = ["| scenario | load | exit | misses (each run) | vs floor | mean wall s "
            "| ended by itself |",
            "|---|---|---|---|---|---|---|"]  # fmt: skip
    extra = ["| run | load | exit | misses | skipped (states / answers) | loop closed again "
             "| gone after SIGTERM |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for hogs_n in args.hogs:
        load = "quiet" if hogs_n == 0 else f"{hogs_n} hogs"
        hogs = start_hogs(hogs_n)
        try:
            copies = {n: prepared(REPO / "config" / f"{n}.yaml", tmp, args.seconds,
                                  mode="realtime") for n in names}  # fmt: skip
            periods = sorted({
                round(float(d["/**"]["ros__parameters"].get("control_period_s", 1e-3)) * 1e6)
                for _, d in copies.values()
            })  # fmt: skip
            floors, results = [], {name: [] for name in copies}
            for rep in range(args.reps):
                # The floor and the runs alternate, so that a drift of the host
                # weighs on both alike.
                floor = {} if args.no_floor else measure_floor(periods, 5000, args.domain_id)
                floors.append(floor)
                floor_file = None
                if floor:
                    floor_file = tmp / f"floor_{hogs_n}_{rep}.jsonl"
                    floor_file.write_text("".join(json.dumps(r) + "\n" for r in floor.values()))
                for name, (path, _) in copies.items():
                    run_dir = tmp / f"{name}_{hogs_n}_{rep}"
                    r = run(path, run_dir, args.domain_id, args.seconds, floor_file)
                    results[name].append(r)
                    print(f"{name} {load} run {rep + 1}: exit {r['code']}, "
                          f"{misses_text([r['summary']], floor)[0]} misses", flush=True)  # fmt: skip
            pooled = pooled_floor(floors)
            for name, rs in results.items():
                misses, ratio = misses_text([r["summary"] for r in rs], pooled)
                left = sum(r.get("left_behind", 0) for r in rs)
                stopped = sum(not r["ended"] for r in rs)
                ended = "yes" if not stopped else f"NO ({stopped} stopped by the script)"
                if left:
                    ended += f", {left} process(es) left behind"
                codes = ",".join(str(r["code"]) for r in rs)
                wall = sum(r["wall_s"] for r in rs) / len(rs)
                rows.append(f"| {name} | {load} | {codes} | {misses} | {ratio} "
                            f"| {wall:.1f} | {ended} |")  # fmt: skip
                print(rows[-1], flush=True)
            if args.no_extra:
                continue
            (tmp / "stall").mkdir(exist_ok=True)
            stall_copy, _ = prepared(REPO / "config" / "ptc_nominal.yaml", tmp / "stall", 3.0,
                                     mode="realtime", duration_s=3.0)  # fmt: skip
            r = run(stall_copy, tmp / f"stall_{hogs_n}", args.domain_id, 3.0, None, stall_during)
            rt = r["summary"].get("realtime", {})
            extra.append(
                f"| stall {STALL_S} s of the feedback | {load} | {r['code']} "
                f"| {rt.get('misses', '-')}/{rt.get('ticks', '-')} "
                f"| {rt.get('states_skipped', '-')} / {rt.get('answers_skipped', '-')} "
                f"| {loop_closed_again(tmp / f'stall_{hogs_n}', r['summary'])} | - |"
            )
            print(extra[-1], flush=True)
            (tmp / "term").mkdir(exist_ok=True)
            long_copy, _ = prepared(REPO / "config" / "ptc_nominal.yaml", tmp / "term", 30.0,
                                    mode="realtime", duration_s=30.0)  # fmt: skip
            r = run(long_copy, tmp / f"term_{hogs_n}", args.domain_id, 30.0, None, sigterm_during)
            gone = "NOT within 30 s" if r["gone_s"] is None else f"{r['gone_s']:.2f} s"
            extra.append(f"| SIGTERM to the runner | {load} | {r['code']} | - | - | - | {gone} |")
            print(extra[-1], flush=True)
        finally:
            stop_hogs(hogs)
    print("\n" + "\n".join(rows))
    if not args.no_extra:
        print("\n" + "\n".join(extra))
    print(f"\nrun directories: {tmp}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
