#!/usr/bin/env python3
"""Realtime deadline misses of commits (or environment variants), alternated in one invocation.

A shared host's realtime figures drift from minute to minute (the bare
pair of ``python -m servo_axis floor`` missed 6 to 246 of 2000 deadlines within ten
minutes), so commits are compared only run by run, back to back: each
repetition runs a realtime copy of the scenario (``--seconds`` simulated,
separate processes, recorder on, ``python -m servo_axis run``) once with
every variant, and with ``--floor`` the bare pair first. A variant is
``REV`` (a commit, a branch, ``HEAD``) or ``REV@NAME=VALUE@...`` (the same
with environment variables set). Each commit gets a worktree under
``--work`` and a copy of this checkout's ``.venv`` made of hard links,
into which the commit is installed (``pip install --no-deps -e``, a few
seconds): the dependencies are this checkout's, the code and the entry
points the commit's. Printed: one line per run, then the misses of each
variant and their median.

    .venv/bin/python scripts/rt_ab.py ptc_friction 5bf2293 HEAD --reps 6 --floor
    .venv/bin/python scripts/rt_ab.py ptc_nominal HEAD HEAD@RMW_FASTRTPS_PUBLICATION_MODE=SYNCHRONOUS

Run it on a quiet machine: it is a measurement, not a test. The worktrees
and venvs stay under ``--work`` for the next invocation; ``rm -rf`` it and
``git worktree prune`` when done.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parents[1]


def git(*args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(REPO), *args], capture_output=True, text=True, check=True
    ).stdout.strip()


def commit_of(rev: str) -> str:
    """The short hash of ``rev``; SystemExit with one line if it names no commit."""
    try:
        return git("rev-parse", "--short", "--verify", "--end-of-options", f"{rev}^{{commit}}")
    except subprocess.CalledProcessError:
        raise SystemExit(f"rt_ab.py: variant {rev!r}: not a commit of {REPO}") from None


def prepare(rev: str, work: Path) -> tuple[Path, Path]:
    """``(python, checkout)`` of ``rev``: a worktree and a hard-linked venv with it installed."""
    commit = commit_of(rev)
    tree, venv = work / f"tree_{commit}", work / f"venv_{commit}"
    if not tree.is_dir():
        git("worktree", "add", "--detach", str(tree), commit)
    if not venv.is_dir():
        subprocess.run(["cp", "-al", str(REPO / ".venv"), str(venv)], check=True)
        subprocess.run(
            [str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-deps",
             "--no-build-isolation", "-e", str(tree)],
            check=True,
        )  # fmt: skip
    return venv / "bin" / "python", tree


def realtime_copy(checkout: Path, scenario: str, seconds: float, path: Path) -> Path:
    """The checkout's shipped ``scenario`` in mode realtime, ``seconds`` long, data files absolute."""
    config = checkout / "config"
    data: dict[str, Any] = yaml.safe_load((config / f"{scenario}.yaml").read_text())
    data["/**"]["ros__parameters"].update(mode="realtime", duration_s=seconds)
    ff = data.get("feedforward", {}).get("ros__parameters", {})
    for term in ("friction_table", "gms"):
        entry = ff.get(term, {})
        if entry.get("file") and not Path(entry["file"]).is_absolute():
            entry["file"] = str(config / entry["file"])
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def misses(run_dir: Path) -> int | None:
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    block = summary.get("realtime") or {}
    return block.get("misses")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", help="a shipped scenario (of each commit's config/)")
    parser.add_argument("variants", nargs="+", help="REV or REV@NAME=VALUE@...")
    parser.add_argument("--reps", type=int, default=5, help="repetitions (default 5)")
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated s (default 2)")
    parser.add_argument("--floor", action="store_true", help="the bare pair before each rep")
    parser.add_argument("--domain-id", type=int, default=205, help="ROS domain (default 205)")
    parser.add_argument(
        "--work", type=Path, default=Path("/tmp/servo_axis_rt_ab"), help="worktrees, venvs, runs"
    )
    args = parser.parse_args()
    if args.reps < 1 or not args.seconds > 0:
        parser.error(f"--reps {args.reps}, --seconds {args.seconds}: expected >= 1 and > 0")
    for variant in args.variants:
        rev, *assignments = variant.split("@")
        commit_of(rev)
        if any("=" not in a for a in assignments):
            parser.error(f"variant {variant!r}: expected REV or REV@NAME=VALUE@...")
    if not (REPO / "config" / f"{args.scenario}.yaml").is_file():
        parser.error(f"scenario {args.scenario!r}: not a shipped scenario (config/<name>.yaml)")
    args.work.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    prepared = {v: prepare(v.split("@")[0], args.work) for v in args.variants}
    got: dict[str, list[int | None]] = {v: [] for v in args.variants}
    floors: list[int] = []
    for rep in range(args.reps):
        if args.floor:
            done = subprocess.run(
                [sys.executable, "-m", "servo_axis", "floor", "--period-us", "1000",
                 "--ticks", "2000", "--executor", "events", "--json",
                 "--domain-id", str(args.domain_id + 1)],
                capture_output=True, text=True, check=False, env=env,
            )  # fmt: skip
            if done.returncode != 0:
                raise SystemExit(f"rt_ab.py: the floor failed: {done.stderr.strip()}")
            floor = json.loads(done.stdout.splitlines()[-1])["misses"]
            floors.append(floor)
            print(f"floor      rep {rep}: {floor} misses of 2000", flush=True)
        for variant, (python, checkout) in prepared.items():
            rev, *assignments = variant.split("@")
            tag = f"{commit_of(rev)}_{rep}_{time.time_ns()}"
            path = realtime_copy(checkout, args.scenario, args.seconds, args.work / f"{tag}.yaml")
            run_dir = args.work / tag
            started = time.monotonic()
            done = subprocess.run(
                [str(python), "-m", "servo_axis", "run", str(path), "--out", str(run_dir),
                 "--domain-id", str(args.domain_id), "--no-plots"],
                capture_output=True, text=True, check=False, cwd=str(checkout),
                env={**env, **dict(a.split("=", 1) for a in assignments)},
            )  # fmt: skip
            got[variant].append(misses(run_dir))
            print(
                f"{variant} rep {rep}: exit {done.returncode}, {got[variant][-1]} misses, "
                f"{time.monotonic() - started:.1f} s",
                flush=True,
            )
    print()
    if floors:
        print(f"floor: {floors}, median {statistics.median(floors)}")
    for variant, values in got.items():
        known = [v for v in values if v is not None]
        median = statistics.median(known) if known else None
        print(f"{variant}: {values}, median {median}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
