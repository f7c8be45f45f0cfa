"""``floor``: the realtime floor of this host, a bare rclpy pair's deadline misses (``run/floor``)."""

from __future__ import annotations

import argparse
import json
import sys

from servo_axis.cli.options import Subparsers, domain_id, int_at_least, output_file, writing

#: The shortest and the longest period measured, us.
PERIOD_RANGE_US = (50.0, 1_000_000.0)


def period_us(text: str) -> float:
    """A period in us within :data:`PERIOD_RANGE_US`."""
    low, high = PERIOD_RANGE_US
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not low <= value <= high:  # NaN too
        raise argparse.ArgumentTypeError(f"{text!r}: expected a period in us, {low:g}..{high:g}")
    return value


def add_parser(commands: Subparsers) -> None:
    """The ``floor`` command and its options."""
    fl = commands.add_parser(
        "floor",
        help="measure this host's realtime floor: the deadline misses of a bare pair of "
        "rclpy processes, which a realtime run's misses are compared with (run --floor)",
        description="Measure the realtime floor of this host: a plant process publishes a "
        "JointState at absolute deadlines (sleep, then spin to each) and a controller "
        "process echoes it; an echo later than the next tick is a deadline miss, the rule of "
        "the plant node. Nothing else runs in them: the least any node pair here misses. "
        "Measure it in the same session as the runs it is compared with.",
    )
    fl.add_argument(
        "--period-us",
        type=period_us,
        nargs="+",
        default=None,
        metavar="US",
        help="the periods to measure, us (default 1000 500 400)",
    )
    fl.add_argument(
        "--ticks",
        type=int_at_least(1, 10_000_000),
        default=None,
        help="ticks per period, 1..10000000 (default 10000)",
    )
    fl.add_argument(
        "--executor",
        choices=("events", "single"),
        default="events",
        help="rclpy's EventsExecutor, as the suite's nodes (default), or SingleThreadedExecutor",
    )
    fl.add_argument(
        "--priority",
        type=int_at_least(0, 99),
        default=0,
        help="SCHED_FIFO priority of both processes' executor threads, 1..99, their "
        "middleware receive threads one below, as a realtime run's plant and feedback with "
        "thread_priority N (default 0: the default scheduler; a run's default is 50)",
    )
    fl.add_argument(
        "--domain-id",
        type=domain_id,
        default=None,
        help="ROS_DOMAIN_ID of the pair, 0..232 (default: ROS_DOMAIN_ID, else derived from the pid)",
    )
    fl.add_argument(
        "--json",
        action="store_true",
        help="one JSON object a line instead of a table: the input of run --floor FILE",
    )
    fl.add_argument(
        "--out",
        type=output_file,
        metavar="FILE",
        help="also write the JSON lines to FILE (for run --floor FILE)",
    )
    fl.set_defaults(func=handle)


def handle(args: argparse.Namespace) -> int:
    """Measure each period, print its result as it comes; write ``--out``."""
    from servo_axis.run.floor import (
        DEFAULT_PERIODS_US,
        DEFAULT_TICKS,
        FloorInterruptedError,
        FloorOptions,
        measure_all,
        table_header,
        table_row,
    )
    from servo_axis.run.processes import default_domain_id

    options = FloorOptions(
        ticks=args.ticks or DEFAULT_TICKS,
        executor=args.executor,
        priority=args.priority,
        domain_id=default_domain_id() if args.domain_id is None else args.domain_id,
    )
    if not args.json:
        print(table_header(), flush=True)

    def show(r: dict[str, object]) -> None:
        print(json.dumps(r) if args.json else table_row(r), flush=True)

    try:
        results = measure_all(args.period_us or DEFAULT_PERIODS_US, options, show)
    except FloorInterruptedError as err:
        print(f"floor interrupted ({err}); the pair is stopped", file=sys.stderr)
        return 128 + err.signum
    if args.out:
        with writing("--out", args.out):
            with open(args.out, "w") as f:
                f.writelines(json.dumps(r) + "\n" for r in results)
        if not args.json:
            print(f"results written to {args.out}")
    return 0
