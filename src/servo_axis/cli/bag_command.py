"""``bag recover BAG_DIR``: the bag tools (a bag whose recorder died made readable)."""

from __future__ import annotations

import argparse
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
        "again; the original file is kept as <file>.unfinished",
    )
    rec.add_argument("bag_dir", help="the bag directory, e.g. <run>/bag")
    rec.set_defaults(func=recover)


def recover(args: argparse.Namespace) -> int:
    """``bag recover``: print what was recovered."""
    from servo_axis.recording.recover import recover_bag

    print(recover_bag(Path(args.bag_dir)).line())
    return 0
