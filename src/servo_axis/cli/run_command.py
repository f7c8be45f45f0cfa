"""``run SCENARIO``: run a scenario end to end and record it (``run/runner.run_scenario``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from servo_axis.cli.options import (
    Subparsers,
    domain_id,
    int_at_least,
    namespace,
    positive_float,
)
from servo_axis.core.errors import ConfigError


def add_parser(commands: Subparsers) -> None:
    """The ``run`` command and its options."""
    run = commands.add_parser(
        "run",
        help="run a scenario end to end and record it",
        description="Run a scenario end to end: start the nodes, record every topic, "
        "write summary.json and the plots.",
    )
    run.add_argument(
        "scenario",
        help="name of a shipped scenario (see `list`), e.g. rptc_detailed, "
        "or a scenario file (ROS parameter YAML)",
    )
    run.add_argument(
        "--out",
        help="run directory to create; must be empty or not exist (default runs/<name>-<time>)",
    )
    run.add_argument(
        "--composed", action="store_true", help="all nodes in one process on one executor"
    )
    run.add_argument(
        "--domain-id",
        type=domain_id,
        default=None,
        help="ROS_DOMAIN_ID of the run, 0..232 (default: ROS_DOMAIN_ID, else derived from the pid)",
    )
    run.add_argument(
        "--namespace",
        type=namespace,
        default="",
        help="ROS namespace of a single-axis run's nodes and topics, absolute "
        "(default /<axis>, e.g. /x; / for the root)",
    )
    run.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    run.add_argument(
        "--floor",
        metavar="FILE",
        help="a realtime run's summary shows this host's floor next to its misses: the "
        "output of the shared tools' rt_floor.py --json (one result a line, by period)",
    )
    run.add_argument(
        "--respawn-limit",
        type=int_at_least(0),
        default=None,
        help="restarts of a dead learning unit or identifier per axis (default 3; 0: no restart)",
    )
    _add_outside_options(run)
    run.set_defaults(func=handle)


def _add_outside_options(run: argparse.ArgumentParser) -> None:
    """What runs outside the suite's nodes: outside nodes of a role, the live view."""
    run.add_argument(
        "--external",
        action="append",
        default=[],
        metavar="ROLE",
        help="a node from outside the suite plays ROLE (plant, feedback, feedforward, "
        "learning, identifier; repeatable; also the scenario key external_roles): the run "
        "starts the others, prints the topics the outside node must serve and waits for it",
    )
    run.add_argument(
        "--external-timeout",
        type=positive_float,
        default=120.0,
        metavar="S",
        help="seconds to wait for the outside nodes before the first step (default 120)",
    )
    run.add_argument(
        "--live",
        action="store_true",
        help="serve the run to Foxglove / Lichtblick while it runs on ws://127.0.0.1:8765 "
        "(needs the extra: pip install -e '.[live]')",
    )
    run.add_argument(
        "--live-port",
        type=int_at_least(1, 65535),
        default=None,
        help="port of the live view, 1..65535 (implies --live)",
    )


def _read_floor(path: str) -> dict[int, dict[str, Any]]:
    """rt_floor.py ``--json`` results by period in us (one clear line if the file is not that)."""
    import json

    try:
        rows = [json.loads(ln) for ln in Path(path).read_text().splitlines() if ln.strip()]
        return {int(r["period_us"]): r for r in rows if {"miss_pct", "round_trip_us"} <= set(r)}
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ConfigError(f"--floor {path}: not rt_floor.py --json output ({err})") from err


def handle(args: argparse.Namespace) -> int:
    """Run the scenario, print its summary and where it is; the run's exit code."""
    from servo_axis.analysis.health import (
        EXIT_FAILED,
        EXIT_FAULT,
        EXIT_LOOP_NOT_CLOSED,
        EXIT_OK,
    )
    from servo_axis.analysis.summary import AxesSummary
    from servo_axis.analysis.text import format_any_summary
    from servo_axis.run.live_channels import DEFAULT_PORT
    from servo_axis.run.runner import RunError, RunInterruptedError, RunOptions, run_scenario

    floor = None
    if args.floor:
        floor = _read_floor(args.floor)
    live_port = args.live_port  # --live-port implies --live
    if live_port is None and args.live:
        live_port = DEFAULT_PORT
    try:
        options = RunOptions(
            out_dir=Path(args.out) if args.out else None,
            composed=args.composed,
            domain_id=args.domain_id,
            namespace=args.namespace,
            plots=not args.no_plots,
            external=tuple(args.external),
            external_timeout_s=args.external_timeout,
            **({} if args.respawn_limit is None else {"respawn_limit": args.respawn_limit}),
            live_port=live_port,
            floor=floor,
        )
        result = run_scenario(args.scenario, options)
    except RunInterruptedError as err:
        print(f"\nrun {err}", file=sys.stderr)
        return 128 + err.signum
    except RunError as err:
        print(f"run failed: {err}", file=sys.stderr)
        return EXIT_FAILED
    print()
    print(format_any_summary(result.summary))
    print()
    axis = (
        "bag/, summary.json, scenario.yaml, params.yaml, *.png, logs/"
        if options.plots
        else "bag/, summary.json, scenario.yaml, params.yaml, logs/"
    )
    contents = (
        f"{', '.join(a + '/' for a in result.summary.axes)} (one axis each: {axis}), "
        + ("summary.json, contour.png" if options.plots else "summary.json")
        if isinstance(result.summary, AxesSummary)
        else axis
    )
    print(f"run directory: {result.run_dir}  ({contents})")
    health = result.health
    if health.exit_code != EXIT_OK:
        verdict = {
            EXIT_FAULT: "the feedback loop tripped",
            EXIT_LOOP_NOT_CLOSED: "the realtime loop was NOT closed",
        }.get(health.exit_code, "this result is NOT the deterministic one of the scenario")
        print(f"\nrun complete, but {verdict} (exit {health.exit_code}):", file=sys.stderr)
        for reason in health.reasons:
            print(f"  - {reason}", file=sys.stderr)
    return health.exit_code
