"""``identify``: an axis identified from measurement runs, written as a scenario."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from servo_axis.cli.options import Parser, Subparsers, output_file
from servo_axis.core.errors import ConfigError
from servo_axis.identify import MODELS


def add_parser(commands: Subparsers) -> None:
    """The ``identify`` command and its options."""
    p = commands.add_parser(
        "identify",
        help="identify an axis from a measure_frf_* run (frequency response, the plant "
        "model's keys, friction) and write a scenario that runs it",
        description="Identify an axis: the closed-loop frequency response of an excitation "
        "run (coherence, uncertainty), a fit of the plant model's own keys with standard "
        "errors, the friction from slow-reversal runs, a validation on a held-out run; write "
        "a scenario that `run` takes as it is and, with --report, the figures. "
        "See docs/how-to/identify-your-axis.md.",
    )
    p.add_argument(
        "run_dir",
        metavar="RUN_DIR",
        help="the excitation run (measure_frf_*, measure_tilting_table): one; the slow-reversal "
        "runs go with --friction, a held-out run with --validate",
    )
    p.add_argument(
        "--model", required=True, choices=MODELS, help="the plant model whose keys are fitted"
    )
    p.add_argument("--out", required=True, type=output_file, help="scenario file to write (YAML)")
    p.add_argument(
        "--friction",
        action="append",
        default=[],
        metavar="RUN_DIR",
        help="a slow-reversal run (measure_reversal_*, measure_small_reversals_*, friction_id); repeatable",
    )
    p.add_argument(
        "--validate",
        metavar="RUN_DIR",
        help="a held-out run: its scenario on the fitted plant, compared",
    )
    p.add_argument("--report", metavar="DIR", help="folder for report.md and the figures")
    p.set_defaults(func=handle)
    Parser.extra_hints["identify"] = (
        "identify takes one excitation run, RUN_DIR; a slow-reversal run goes with "
        "--friction RUN_DIR (repeatable), a held-out run with --validate RUN_DIR"
    )


def handle(args: argparse.Namespace) -> int:
    """The handler: read the runs, identify, write the scenario (and the report)."""
    from servo_axis.identify.data import from_run
    from servo_axis.identify.driver import identify
    from servo_axis.identify.report import summary_text, write_report
    from servo_axis.identify.writer import write_scenario

    runs = [from_run(Path(args.run_dir))]
    friction = [from_run(Path(d)) for d in args.friction]
    validation = from_run(Path(args.validate)) if args.validate else None
    ident = identify(args.model, runs, friction=friction, validation=validation)
    command = "python -m servo_axis identify " + " ".join(shlex.quote(a) for a in sys.argv[2:])
    try:
        write_scenario(Path(args.out), ident, validation or runs[0], command=command)
    except OSError as err:
        raise ConfigError(f"--out {args.out}: cannot write it: {err}") from None
    print(summary_text(ident))
    print(f"scenario written to {args.out}")
    if args.report:
        try:
            files = write_report(Path(args.report), ident)
        except OSError as err:
            raise ConfigError(f"--report {args.report}: cannot write it: {err}") from None
        print(f"report written to {files[-1]}")
    return 0
