"""``bag recover BAG_DIR``: the bag tools (a bag whose recorder died made readable)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from servo_axis.cli.options import Subparsers


def add_parser(commands: Subparsers) -> None:
    """The ``bag`` command and its own commands (``recover``)."""
    bag = commands.add_parser("bag", help="bag tools: recover")
    bag_sub = bag.add_subparsers(
        dest="bag_command", required=True, metavar="BAG_COMMAND", help="what to do with a bag"
    )
    rec = bag_sub.add_parser(
        "recover",
        help="make a bag whose recorder died (no metadata.yaml, no MCAP summary) readable "
        "again; the original file is kept as <file>.unfinished. A run directory without "
        "summary.json (killed with its nodes) gets the summary of what it recorded",
    )
    rec.add_argument("bag_dir", help="the bag directory, e.g. <run>/bag")
    rec.set_defaults(func=recover)


def recover(args: argparse.Namespace) -> int:
    """``bag recover``: print what was recovered; write the run's summary if it has none.

    A bag whose run directory has no ``summary.json`` (its runner was
    killed with the nodes) gets the summary of what it recorded
    (:func:`servo_axis.analysis.recovered.summarise_unfinished`), so that
    ``summary``, ``identify``, ``compare`` and ``friction-table`` read the
    run; a second line says so.
    """
    from servo_axis.recording.recover import recover_bag

    bag_dir = Path(args.bag_dir)
    print(recover_bag(bag_dir).line())
    run_dir = bag_dir.parent
    recorded = any((run_dir / name).is_file() for name in ("scenario.yaml", "params.yaml"))
    if recorded and not (run_dir / "summary.json").exists():
        from servo_axis.analysis.recovered import summarise_unfinished
        from servo_axis.core.errors import ServoAxisError

        try:
            summary = summarise_unfinished(run_dir)
        except (ServoAxisError, OSError) as err:
            # The bag is recovered all the same; what stops the summary is said.
            print(f"warning: {run_dir}: no summary.json written: {err}", file=sys.stderr)
            return 0
        print(
            f"{run_dir}: summary.json written, of the {summary.steps} steps recorded "
            f"({summary.sim_time_s:g} s simulated): python -m servo_axis summary {run_dir}"
        )
    return 0
