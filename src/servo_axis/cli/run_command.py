"""``run SCENARIO``: run a scenario end to end and record it (``run/runner.run_scenario``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from servo_axis.cli.options import (
    Parser,
    Subparsers,
    domain_id,
    int_at_least,
    namespace,
    override,
    positive_float,
)


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
        "--set",
        dest="overrides",
        action="append",
        type=override,
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a key of the scenario (repeatable, the last one of a key wins): "
        "SECTION is shared (the /** keys), a node (plant, feedback, feedforward, learning, "
        "identifier, recorder) or /<axis>/<node> of a multi-axis scenario; KEY is dotted "
        "where the file nests (plant.friction.elements=8); VALUE is YAML. Checked as the "
        "file is; params.yaml shows the result, summary.json the overrides",
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
        help="a realtime run's summary shows this host's floor next to its misses: what "
        "`python -m servo_axis floor --json` printed (one result a line, by period), "
        "measured in the same session",
    )
    run.add_argument(
        "--respawn-limit",
        type=int_at_least(0),
        default=None,
        help="restarts of a dead learning unit or identifier per axis (default 3; 0: no restart)",
    )
    _add_outside_options(run)
    run.set_defaults(func=handle)
    Parser.option_hints["run"] = _key_for_option


def _key_for_option(option: str) -> str:
    """For an option ``run`` does not have that looks like a scenario key: its ``--set``."""
    from servo_axis.core.errors import closest
    from servo_axis.params import schemas

    sections = {
        "shared": schemas.SHARED,
        "plant": schemas.PLANT,
        "feedback": schemas.FEEDBACK,
        "feedforward": schemas.FEEDFORWARD,
        "learning": schemas.LEARNING,
        "identifier": schemas.IDENTIFIER,
        "recorder": schemas.RECORDER,
    }
    name = option.lstrip("-").replace("-", "_")
    for section, schema in sections.items():
        found = closest(name, schema)
        if found:
            return f"a key of the scenario? --set {section}.{found[0]}=VALUE"
    return ""


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
        help="seconds to wait for the outside nodes before the first step, counted from when "
        "the run's own nodes are up (default 120)",
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
        from servo_axis.run.floor import read_floor

        floor = read_floor(args.floor)
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
            overrides=tuple(args.overrides),
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
