"""``friction-table RUN_DIR --out FILE``: a friction table from a friction_id run (``friction_id``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from servo_axis.cli.options import Subparsers, output_file, positive_float, writing


def add_parser(commands: Subparsers) -> None:
    """The ``friction-table`` command and its options."""
    ft = commands.add_parser("friction-table", help="build a friction table from a friction_id run")
    ft.add_argument("run_dir", help="run directory of a friction_id run")
    ft.add_argument("--out", required=True, type=output_file, help="CSV file to write")
    ft.add_argument(
        "--bin-width-m",
        type=positive_float,
        default=0.5e-6,
        help="displacement bin of the table, m (default 0.5e-6)",
    )
    ft.add_argument(
        "--max-displacement-m",
        type=positive_float,
        default=40e-6,
        help="displacement after a reversal the table covers, m (default 40e-6)",
    )
    ft.set_defaults(func=handle)


def handle(args: argparse.Namespace) -> int:
    """Build the table and write it to ``--out``."""
    from servo_axis.identify.friction import table_from_run
    from servo_axis.storage import save_friction_table

    table = table_from_run(
        Path(args.run_dir), bin_width_m=args.bin_width_m, max_displacement_m=args.max_displacement_m
    )
    with writing("--out", args.out):
        save_friction_table(Path(args.out), table)
    print(f"friction table with {len(table.displacement_m)} points written to {args.out}")
    return 0
