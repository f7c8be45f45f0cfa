#!/usr/bin/env python3
"""Repeat one scenario many times and count the runs whose bags are identical.

Each run goes through the entry point a user calls (``python -m servo_axis
run``, separate processes unless ``--composed``). With ``--extra-participant``
a stranger joins the run's ROS domain for the whole run: a participant with
a subscription on every topic of the table (what ``ros2 topic echo`` would
add), so that the nodes' handshakes see more subscribers than the run
started. With ``--cpu-load N``, N busy processes compete for the cores. The
payload hashes of every recorded topic (read with rosbags) are compared with
the first run's, and each run's exit code is printed::

    .venv/bin/python scripts/determinism.py --runs 50 --extra-participant --cpu-load 2

prints ``identical: 50 of 50 runs (exit codes {0: 50})``; exit 1 if any run
differs or exits non-zero. ``--keep-different DIR`` keeps the first run and
every differing one (bag, logs, summary) in ``DIR`` to look into.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

from scenario_hashes import bag_hashes, run_dirs_with_bags  # noqa: E402
from servo_axis import numerics  # noqa: E402

STRANGER = """
import sys, rclpy
from rclpy.executors import ExternalShutdownException
from servo_axis import numerics
from servo_axis.nodes.base import MESSAGE_CLASSES, QOS
from servo_axis.wire.topics import TOPICS
rclpy.init()
node = rclpy.create_node("echo_stranger")
for t in TOPICS:
    node.create_subscription(MESSAGE_CLASSES[t.type_name], t.name, lambda m: None, QOS[t.qos])
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
finally:
    rclpy.try_shutdown()
"""


def _busy() -> None:
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))
    while True:
        pass


def one_run(scenario: str, out: Path, domain: int, composed: bool, stranger: bool) -> int:
    from servo_axis.run.processes import ros_environment

    env = ros_environment(domain, out.parent / f"{out.name}-ros-log")
    Path(env["ROS_LOG_DIR"]).mkdir(parents=True, exist_ok=True)
    extra = None
    started = time.time()  # epoch, for the shared-memory clean-up
    if stranger:
        extra = subprocess.Popen(
            [sys.executable, "-c", STRANGER], env=env, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )  # fmt: skip
    try:
        cmd = [sys.executable, "-m", "servo_axis", "run", scenario, "--out", str(out),
               "--domain-id", str(domain), "--no-plots"]  # fmt: skip
        if composed:
            cmd.append("--composed")
        return subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, check=False).returncode
    finally:
        if extra is not None:
            extra.send_signal(signal.SIGINT)
            try:
                extra.wait(10)
            except subprocess.TimeoutExpired:
                # Under CPU load its shutdown can outlast the wait; killed, it
                # leaves its shared-memory files (and its peers') behind.
                extra.kill()
                extra.wait()
                from servo_axis.run.fastdds import clean_stale_shm

                clean_stale_shm(since=started)


def log_tails(run_dir: Path, lines: int = 4) -> str:
    """The last ``lines`` lines of each node's log in ``run_dir`` (what a failed run said)."""
    out = []
    for log in sorted(run_dir.glob("**/logs/*.log")):
        if log.name.startswith("python_"):  # rcl's own copy of the same lines
            continue
        tail = log.read_text(errors="replace").splitlines()[-lines:]
        out.append(f"  {log.relative_to(run_dir)}:")
        out.extend(f"    {line}" for line in tail or ["(empty)"])
    return "\n".join(out) or f"  no node logs under {run_dir}"


def _count(entry: tuple[int, str] | None) -> str:
    """The message count of a topic's ``(count, sha256)``, or ``none`` if the first run had none."""
    return "none" if entry is None else str(entry[0])


def main(argv: list[str] | None = None) -> int:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="rptc_friction_table")
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--composed", action="store_true")
    parser.add_argument("--extra-participant", action="store_true")
    parser.add_argument("--cpu-load", type=int, default=0, help="busy processes during the runs")
    parser.add_argument("--domain-id", type=int, default=60)
    parser.add_argument(
        "--keep-different",
        type=Path,
        default=None,
        help="copy the first run and each differing run (bag, logs, summary) into this folder",
    )
    args = parser.parse_args(argv)

    load = [multiprocessing.Process(target=_busy, daemon=True) for _ in range(args.cpu_load)]
    for p in load:
        p.start()
    codes: Counter[int] = Counter()
    reference = None
    identical = 0
    t0 = time.monotonic()
    try:
        with tempfile.TemporaryDirectory(prefix="servo_axis_determinism_") as tmp:
            for i in range(args.runs):
                out = Path(tmp) / f"run{i}"
                code = one_run(
                    args.scenario, out, args.domain_id, args.composed, args.extra_participant
                )
                codes[code] += 1
                hashes = {str(b.relative_to(out)): bag_hashes(b) for b in run_dirs_with_bags(out)}
                if reference is None:
                    reference = hashes
                same = hashes == reference and bool(hashes)
                identical += same
                # The message counts say whether a topic differs in what was
                # recorded or in how many (a repeat, a loss).
                diff = sorted(
                    f"{bag}:{topic} ({_count((reference or {}).get(bag, {}).get(topic))} -> "
                    f"{value[0]} messages)"
                    for bag, per_topic in hashes.items()
                    for topic, value in per_topic.items()
                    if (reference or {}).get(bag, {}).get(topic) != value
                )
                if args.keep_different is not None and (i == 0 or not same):
                    shutil.copytree(out, args.keep_different / out.name, dirs_exist_ok=True)
                print(
                    f"run {i + 1:>3}: exit {code}, "
                    + ("identical" if same else f"DIFFERENT ({', '.join(diff) or 'no bag'})"),
                    flush=True,
                )
                if code != 0:
                    print(log_tails(out), flush=True)
    finally:
        for p in load:
            p.terminate()
            p.join()
    print(
        f"identical: {identical} of {args.runs} runs (exit codes {dict(codes)}), "
        f"{time.monotonic() - t0:.0f} s; scenario {args.scenario}, "
        f"{'composed' if args.composed else 'separate processes'}, "
        f"extra participant {'yes' if args.extra_participant else 'no'}, "
        f"cpu load {args.cpu_load}"
    )
    return 0 if identical == args.runs and set(codes) == {0} else 1


if __name__ == "__main__":
    raise SystemExit(main())
