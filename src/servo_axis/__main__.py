"""Command line: ``python -m servo_axis [run SCENARIO | friction-table RUN_DIR | summary RUN_DIR]``.

With no arguments it runs the default scenario (``config/ptc_nominal.yaml``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from servo_axis.core.errors import ServoAxisError

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
DEFAULT_SCENARIO = CONFIG_DIR / "ptc_nominal.yaml"


def _run(args: argparse.Namespace) -> int:
    from servo_axis import report
    from servo_axis.bringup import RunError, RunInterruptedError, run_scenario

    try:
        result = run_scenario(
            Path(args.scenario),
            out_dir=Path(args.out) if args.out else None,
            composed=args.composed,
            domain_id=args.domain_id,
            namespace=args.namespace,
            plots=not args.no_plots,
        )
    except RunInterruptedError as err:
        print(f"\nrun {err}", file=sys.stderr)
        return 128 + err.signum
    except RunError as err:
        print(f"run failed: {err}", file=sys.stderr)
        return 1
    print()
    print(report.format_any_summary(result.summary))
    print()
    contents = (
        f"{', '.join(a + '/' for a in result.summary['axes'])} (one axis each: bag/, summary.json, "
        "*.png, logs/), summary.json, contour.png"
        if "axes" in result.summary
        else "bag/, summary.json, *.png, logs/"
    )
    print(f"run directory: {result.run_dir}  ({contents})")
    return 0


def _friction_table(args: argparse.Namespace) -> int:
    from servo_axis.friction_id import table_from_run

    table = table_from_run(
        Path(args.run_dir), bin_width_m=args.bin_width_m, max_displacement_m=args.max_displacement_m
    )
    table.save(Path(args.out))
    print(f"friction table with {len(table.displacement_m)} points written to {args.out}")
    return 0


def _summary(args: argparse.Namespace) -> int:
    from servo_axis import report

    summary = json.loads((Path(args.run_dir) / "summary.json").read_text())
    print(report.format_any_summary(summary))
    return 0


def _compare(args: argparse.Namespace) -> int:
    from servo_axis import report

    summaries = [json.loads((Path(d) / "summary.json").read_text()) for d in args.run_dirs]
    for run_dir, summary in zip(args.run_dirs, summaries, strict=True):
        if "axes" in summary:
            axes = ", ".join(str(Path(run_dir) / a) for a in summary["axes"])
            print(f"error: {run_dir}: a multi-axis run; compare its axes: {axes}", file=sys.stderr)
            return 2
    labels = args.labels.split(",") if args.labels else [Path(d).name for d in args.run_dirs]
    if len(labels) != len(summaries):
        print(
            f"error: --labels: expected {len(summaries)} comma-separated labels, got {len(labels)}",
            file=sys.stderr,
        )
        return 2
    print(report.compare_table(summaries, labels))
    if args.out:
        report.plot_cycles(summaries, labels, Path(args.out), title=args.title)
        print(f"figure written to {args.out}")
    if args.error_out:
        report.plot_error_overlay(
            [Path(d) for d in args.run_dirs],
            labels,
            Path(args.error_out),
            zoom_cycle=args.zoom_cycle,
            title=args.title,
        )
        print(f"figure written to {args.error_out}")
    return 0


def _list(args: argparse.Namespace) -> int:
    from servo_axis.bringup import load_scenario, shared

    for path in sorted(Path(args.config_dir).glob("*.yaml")):
        about = shared(load_scenario(path)).get("scenario", {})
        print(f"{path.name:<28} {about.get('description', '')}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis``."""
    parser = argparse.ArgumentParser(prog="python -m servo_axis", description=__doc__)
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run a scenario end to end and record it")
    run.add_argument(
        "scenario", help="scenario file (ROS parameter YAML), e.g. config/ptc_nominal.yaml"
    )
    run.add_argument("--out", help="run directory to create (default runs/<name>-<time>)")
    run.add_argument("--composed", action="store_true", help="all nodes in one process")
    run.add_argument(
        "--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: from env or pid)"
    )
    run.add_argument("--namespace", default="", help="namespace of the axis, e.g. /x")
    run.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    run.set_defaults(func=_run)
    ft = sub.add_parser("friction-table", help="build a friction table from a friction_id run")
    ft.add_argument("run_dir")
    ft.add_argument("--out", required=True, help="CSV file to write")
    ft.add_argument("--bin-width-m", type=float, default=0.5e-6)
    ft.add_argument("--max-displacement-m", type=float, default=40e-6)
    ft.set_defaults(func=_friction_table)
    sm = sub.add_parser("summary", help="print the summary of a run directory")
    sm.add_argument("run_dir")
    sm.set_defaults(func=_summary)
    ls = sub.add_parser("list", help="the scenarios in config/ and what each runs")
    ls.add_argument("--config-dir", default=str(CONFIG_DIR))
    ls.set_defaults(func=_list)
    cmp = sub.add_parser(
        "compare", help="max/RMS error per cycle of several runs (e.g. Q vs Q~n, 000 Fig. 15)"
    )
    cmp.add_argument("run_dirs", nargs="+")
    cmp.add_argument("--labels", help="comma-separated, one per run (default: directory names)")
    cmp.add_argument("--out", help="PNG to write: max and RMS error per cycle")
    cmp.add_argument("--error-out", help="PNG to write: error against time, one cycle enlarged")
    cmp.add_argument("--zoom-cycle", type=int, default=3, help="the cycle enlarged (default 3)")
    cmp.add_argument("--title", default="tracking error per cycle")
    cmp.set_defaults(func=_compare)
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["run", str(DEFAULT_SCENARIO)])
    try:
        return int(args.func(args))
    except (ServoAxisError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
