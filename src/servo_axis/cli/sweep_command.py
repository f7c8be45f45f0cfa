"""``sweep STUDY``: a parameter study of a scenario on dask.distributed (``sweep/``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from servo_axis.cli.options import Subparsers, int_at_least, override


def add_parser(commands: Subparsers) -> None:
    """The ``sweep`` command and its options."""
    sw = commands.add_parser(
        "sweep",
        help="run a study (a parameter sweep of a scenario) on dask.distributed",
        description="Run a study: the points of a grid or list of overrides of a base "
        "scenario, on a LocalCluster or a running dask scheduler; write results.parquet, "
        "results.csv, manifest.json (a second call resumes) and a PNG per figure and "
        "swept parameter.",
    )
    sw.add_argument(
        "study",
        help="study file (YAML; docs/reference/studies.md) or a shipped study's name, e.g. reversal_004",
    )
    sw.add_argument("--out", help="study directory (default studies/<name>)")
    sw.add_argument(
        "--set",
        dest="overrides",
        action="append",
        type=override,
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a key of the study's scenario in every point, after the study's own "
        "set (repeatable; as run --set: shared, a node or /<axis>/<node>; VALUE is YAML); "
        "a swept key keeps its points' values",
    )
    sw.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="address of a running dask scheduler (default: a LocalCluster)",
    )
    sw.add_argument(
        "--workers",
        type=int_at_least(1),
        default=None,
        help="worker processes of the LocalCluster, one thread each (default: the cores)",
    )
    sw.add_argument(
        "--retry-failed", action="store_true", help="run again the points that failed before"
    )
    sw.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    sw.set_defaults(func=handle)


def handle(args: argparse.Namespace) -> int:
    """Run the study's points; 1 if any failed."""
    from servo_axis.sweep.engine import VersionMismatchError, run_study
    from servo_axis.sweep.spec import load_study

    study = load_study(args.study, args.overrides)
    out = Path(args.out) if args.out else Path("studies") / study.name
    try:
        rows = run_study(
            study,
            out,
            scheduler=args.scheduler,
            workers=args.workers,
            retry_failed=args.retry_failed,
            plots=not args.no_plots,
        )
    except VersionMismatchError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    failed = [r for r in rows if r["status"] != "ok"]
    for r in failed[:5]:
        print(f"point {r['point']} failed: {r['error']}", file=sys.stderr)
    print(
        f"study {study.name}: {len(rows) - len(failed)} ok, {len(failed)} failed; results in {out}"
    )
    return 1 if failed else 0
