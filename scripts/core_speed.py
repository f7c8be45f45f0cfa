#!/usr/bin/env python3
"""Speed of the core-only loop (plain calls, no ROS) for every shipped scenario.

Each scenario runs through the function of :mod:`servo_axis.simulate` that
reproduces its node graph: ``simulate_identification`` with an identifier
section, ``simulate_learning`` with a learning law (RPTC's cycles or an ILC's
trials), and ``simulate`` otherwise.
A multi-axis scenario runs once per axis (``xy_circle/x``, ``xy_circle/y``).
Before the timed run, a run of a few steps builds everything once (and
compiles what is compiled); its time is the ``first s`` column. The table:

    scenario | T_u ms | steps | wall s | steps/s | x real time | first s

``x real time`` is simulated time over wall time (``steps * T_u / wall``).
``--profile N`` adds a cProfile of the N slowest (by x real time) to stderr.

    .venv/bin/python scripts/core_speed.py [--steps 2000] [--only NAME ...] [--profile 3]

It runs in the portable numeric environment (servo_axis.numerics), as a
lockstep run does; ``SERVO_AXIS_NUMERICS=native`` measures the host's fastest paths.
"""

from __future__ import annotations

import os

# Before numpy loads: the suite's small matrices run fastest on one BLAS thread.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import cProfile
import io
import pstats
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from servo_axis import numerics
from servo_axis.params import factories, resolve
from servo_axis.params.scenario import (
    axes_of,
    axis_view,
    dump_params,
    load_scenario,
    scenario_dir,
    scenario_names,
)


def runner(path: Path) -> tuple[str, Callable[..., object]]:
    """The plain-call loop that reproduces the scenario's node graph, and its name."""
    from servo_axis.simulate import simulate, simulate_identification, simulate_learning

    scenario = load_scenario(path)
    if "identifier" in scenario:
        return "identification", simulate_identification
    if "learning" in scenario:
        return "learning", simulate_learning
    return "loop", simulate


def cases(names: list[str], work: Path) -> list[tuple[str, tuple[Path, str]]]:
    """``(label, (scenario file, note))`` per scenario, one per axis of a multi-axis one."""
    out = []
    for name in names:
        path = scenario_dir() / f"{name}.yaml"
        scenario = load_scenario(path)
        axes = axes_of(scenario)
        if not axes:
            out.append((name, (path, "")))
            continue
        for axis in axes:
            view = axis_view(scenario, axis, path.parent)
            axis_path = work / f"{name}_{axis}.yaml"
            axis_path.write_text(dump_params(view))
            out.append((f"{name}/{axis}", (axis_path, "")))
    return out


def main() -> int:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--only", nargs="*", help="scenario names (default: every shipped one)")
    parser.add_argument("--steps", type=int, default=None, help="cap the steps of each run")
    parser.add_argument("--repeat", type=int, default=1, help="timed runs per case (best kept)")
    parser.add_argument("--profile", type=int, default=0, help="profile the N slowest cases")
    args = parser.parse_args()
    names = args.only or scenario_names()
    work = Path(tempfile.mkdtemp(prefix="servo_axis_core_speed_"))
    rows = []
    header = (
        f"| {'scenario':<28} | {'loop':<14} | {'T_u ms':>6} | {'steps':>6} | {'wall s':>7} "
        f"| {'steps/s':>9} | {'x real time':>11} | {'first s':>7} |"
    )
    print(header)
    print("|" + "|".join("-" * (len(c)) for c in header.split("|")[1:-1]) + "|", flush=True)
    for label, (path, note) in cases(names, work):
        kind, fn = runner(path)
        kind += note
        pv = resolve.node_values(load_scenario(path), "plant")
        period = pv["control_period_s"]
        steps = factories.run_steps(pv)
        if args.steps is not None:
            steps = min(steps, args.steps)
        t0 = time.perf_counter()
        fn(path, steps=min(steps, 4))
        first = time.perf_counter() - t0
        wall = float("inf")
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            fn(path, steps=steps)
            wall = min(wall, time.perf_counter() - t0)
        rate = steps / wall
        rows.append((rate * period, label, path, fn, steps))
        print(
            f"| {label:<28} | {kind:<14} | {period * 1e3:>6g} | {steps:>6} | {wall:>7.3f} "
            f"| {rate:>9,.0f} | {rate * period:>10.1f}x | {first:>7.3f} |",
            flush=True,
        )
    rows.sort(key=lambda r: r[0])
    print(f"slowest: {rows[0][1]} at {rows[0][0]:.1f}x real time", flush=True)
    for factor, label, path, fn, steps in rows[: args.profile]:
        prof = cProfile.Profile()
        prof.runcall(fn, path, steps=steps)
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(15)
        print(f"\n=== profile: {label} ({factor:.1f}x real time) ===", file=sys.stderr)
        print(text.getvalue(), file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
