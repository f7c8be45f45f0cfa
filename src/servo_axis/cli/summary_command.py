"""``summary RUN_DIR``: a run's summary again, from its summary.json."""

from __future__ import annotations

import argparse
from pathlib import Path

from servo_axis.cli.options import Subparsers


def add_parser(commands: Subparsers) -> None:
    """The ``summary`` command."""
    sm = commands.add_parser("summary", help="print the summary of a run directory")
    sm.add_argument("run_dir", help="run directory (holds summary.json)")
    sm.set_defaults(func=handle)


def handle(args: argparse.Namespace) -> int:
    """Print the summary as ``run`` does."""
    from servo_axis.analysis.summary import load_summary
    from servo_axis.analysis.text import format_any_summary

    print(format_any_summary(load_summary(Path(args.run_dir))))
    return 0
