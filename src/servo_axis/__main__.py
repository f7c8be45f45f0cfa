"""Command line of the suite: the commands of ``servo_axis/cli/``, one module each.

This module lists them (:data:`COMMANDS`, in the order of the help), builds
the parser and dispatches to the command's handler; every error of bad input
is one line on stderr and exit 2.

``python -m servo_axis run SCENARIO``
    run a scenario end to end and record it; SCENARIO is the name of a
    shipped scenario (``rptc_detailed``) or a scenario file;
``python -m servo_axis list``
    the shipped scenarios and what each runs, the installed extensions (a broken one marked);
``python -m servo_axis params [NAME]``
    every key of the nodes and of the installed extensions (plugins included): default, unit,
    range, meaning;
``python -m servo_axis summary RUN_DIR`` / ``compare RUN_DIR...`` / ``friction-table RUN_DIR``
    a run's summary again, runs side by side, a friction table from a run;
``python -m servo_axis gms-fit RUN_DIR --out FILE [--elements N] [--plot PNG]``
    a GMS friction model fitted to a friction_id run (paper 004 Fig. 4(b));
``python -m servo_axis sweep STUDY.yaml [--out DIR] [--scheduler tcp://HOST:PORT] [--workers N]``
    a parameter sweep (a study) on dask.distributed: results.parquet/.csv,
    manifest.json (an interrupted study resumes), a PNG per figure and parameter;
``python -m servo_axis identify RUN_DIR --model NAME --out SCENARIO.yaml [--friction RUN_DIR] [--validate RUN_DIR]``
    an axis identified from a measure_frf_* run, written as a scenario (docs/how-to/identify-your-axis.md);
``python -m servo_axis bag recover BAG_DIR``
    make a bag whose recorder died readable again (a complete bag is left as it is);
``python -m servo_axis floor [--period-us US ...] [--ticks N] [--json]``
    this host's realtime floor: a bare rclpy pair's deadline misses (``run --floor FILE``).

With no arguments it runs the shipped scenario ``rptc_friction_table``: the
detailed axis (resonances, dead time, rolling friction) with the friction
table from cycle 1 and repetitive PTC learning from cycle 2.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys

from servo_axis.cli import (
    bag_command,
    compare_command,
    floor_command,
    friction_table_command,
    gms_fit_command,
    identify_command,
    list_command,
    params_command,
    run_command,
    summary_command,
    sweep_command,
)
from servo_axis.cli.options import DEFAULT_SCENARIO, Parser, describe_commands
from servo_axis.core.errors import ServoAxisError

#: The commands in the order of the help: each module's ``add_parser`` adds its
#: parser and handler (``servo_axis.cli``).
COMMANDS = (
    run_command,
    friction_table_command,
    gms_fit_command,
    sweep_command,
    identify_command,
    summary_command,
    list_command,
    params_command,
    compare_command,
    bag_command,
    floor_command,
)

#: What the top-level help says first.
DESCRIPTION = f"""\
servo_axis: a ROS 2 (Jazzy) emulation of a machine-tool servo axis and its
controllers. `run` starts the plant, feedback, feedforward, learning,
identifier and recorder nodes of a scenario, records every topic to a
rosbag2 (MCAP) bag and writes the tracking error's summary and plots.
With no command it runs the shipped scenario {DEFAULT_SCENARIO}.
"""

#: Examples at the end of the top-level help.
EXAMPLES = """\
examples:
  python -m servo_axis list
  python -m servo_axis params friction_table
  python -m servo_axis run ptc_nominal --out runs/ptc
  python -m servo_axis run rptc_detailed --composed --namespace /x --domain-id 42
  python -m servo_axis summary runs/ptc
  python -m servo_axis compare runs/q runs/q5 --labels Q,Q~5 --out cycles.png
  python -m servo_axis compare runs/pid runs/lpf2 --rmsd --bar-chart rmsd.png
  python -m servo_axis friction-table runs/friction_id --out table.csv
  python -m servo_axis gms-fit runs/friction_id_elastic --out gms.txt --plot fit.png
  python -m servo_axis identify runs/frf --model ball_screw --out my_axis.yaml
  python -m servo_axis bag recover runs/ptc/bag
  python -m servo_axis floor --period-us 1000 --json --out runs/floor.jsonl
(`servo-axis` is the same command as `python -m servo_axis`.)

Exit codes of run: 0 complete and deterministic (realtime: complete, never
deterministic), 1 failed, 2 bad option or configuration (nothing started or
written), 3 not the deterministic result, 4 the feedback loop tripped,
5 realtime: the loop was not closed (misses over realtime.max_miss_fraction,
commands that never came, the plant's clock stalled), 130/143 interrupted by
SIGINT/SIGTERM.
"""


def build_parser(prog: str = "python -m servo_axis") -> argparse.ArgumentParser:
    """The command line's parser (every argument with its help)."""
    parser = Parser(
        prog=prog,
        description=DESCRIPTION,
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    commands = parser.add_subparsers(
        dest="command", metavar="COMMAND", help=f"what to do (default: run {DEFAULT_SCENARIO})"
    )
    for command in COMMANDS:
        command.add_parser(commands)
    describe_commands(parser)  # each command's --help starts with what it does
    return parser


def main(argv: list[str] | None = None, prog: str = "python -m servo_axis") -> int:
    """Entry point of ``python -m servo_axis`` (and of the ``servo-axis`` command)."""
    parser = build_parser(prog)
    try:
        args = parser.parse_args(argv)
    except SystemExit as done:  # --help (0) or a bad option (2, its line already written)
        return done.code if isinstance(done.code, int) else 2
    if args.command is None:
        args = parser.parse_args(["run", DEFAULT_SCENARIO])
    from servo_axis.numerics import scipy_import

    scipy_import.install()
    try:
        code = int(args.func(args))
    except BrokenPipeError:
        # The reader of our output went away (`list | head`): not an error of ours.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return 128 + int(signal.SIGINT)
    except (ServoAxisError, OSError) as err:
        # One line: the error (the other broken plugins are named by a command that works).
        print(f"error: {err}", file=sys.stderr)
        return 2
    _report_broken_plugins()
    return code


def _report_broken_plugins() -> None:
    """Name once each installed plugin that cannot be loaded, of those the command looked at."""
    registry = sys.modules.get("servo_axis.params.registry")
    if registry is not None:  # else the command read no registry (and imports none now)
        registry.report_broken()


def console() -> int:
    """Entry point of the ``servo-axis`` console command."""
    return main(prog="servo-axis")


if __name__ == "__main__":
    raise SystemExit(main())
