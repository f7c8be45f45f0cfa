"""Command line of the suite.

``python -m servo_axis run SCENARIO``
    run a scenario end to end and record it; SCENARIO is the name of a
    shipped scenario (``rptc_detailed``) or a scenario file;
``python -m servo_axis list``
    the shipped scenarios and what each runs;
``python -m servo_axis summary RUN_DIR`` / ``compare RUN_DIR...`` / ``friction-table RUN_DIR``
    a run's summary again, runs side by side, a friction table from a run;
``python -m servo_axis gms-fit RUN_DIR --out FILE [--elements N] [--plot PNG]``
    a GMS friction model fitted to a friction_id run (paper 004 Fig. 4(b));
``python -m servo_axis bag recover BAG_DIR``
    make a bag whose recorder died readable again (a complete bag is left as it is).

With no arguments it runs the shipped scenario ``rptc_friction_table``: the
detailed axis (resonances, dead time, rolling friction) with the friction
table from cycle 1 and repetitive PTC learning from cycle 2.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from servo_axis.core.errors import ServoAxisError

#: The shipped scenario ``python -m servo_axis`` runs.
DEFAULT_SCENARIO = "rptc_friction_table"


def _run(args: argparse.Namespace) -> int:
    from servo_axis.analysis.health import EXIT_FAILED, EXIT_FAULT, EXIT_OK
    from servo_axis.analysis.summary import AxesSummary
    from servo_axis.analysis.text import format_any_summary
    from servo_axis.run.live import DEFAULT_PORT
    from servo_axis.run.runner import RunError, RunInterruptedError, run_scenario

    live_port = args.live_port  # --live-port implies --live
    if live_port is None and args.live:
        live_port = DEFAULT_PORT
    try:
        result = run_scenario(
            args.scenario,
            out_dir=Path(args.out) if args.out else None,
            composed=args.composed,
            domain_id=args.domain_id,
            namespace=args.namespace,
            plots=not args.no_plots,
            **({} if args.respawn_limit is None else {"respawn_limit": args.respawn_limit}),
            live_port=live_port,
        )
    except RunInterruptedError as err:
        print(f"\nrun {err}", file=sys.stderr)
        return 128 + err.signum
    except RunError as err:
        print(f"run failed: {err}", file=sys.stderr)
        return EXIT_FAILED
    print()
    print(format_any_summary(result.summary))
    print()
    contents = (
        f"{', '.join(a + '/' for a in result.summary.axes)} (one axis each: bag/, summary.json, "
        "*.png, logs/), summary.json, contour.png"
        if isinstance(result.summary, AxesSummary)
        else "bag/, summary.json, *.png, logs/"
    )
    print(f"run directory: {result.run_dir}  ({contents})")
    health = result.health
    if health.exit_code != EXIT_OK:
        verdict = (
            "the feedback loop tripped"
            if health.exit_code == EXIT_FAULT
            else "this result is NOT the deterministic one of the scenario"
        )
        print(f"\nrun complete, but {verdict} (exit {health.exit_code}):", file=sys.stderr)
        for reason in health.reasons:
            print(f"  - {reason}", file=sys.stderr)
    return health.exit_code


def _friction_table(args: argparse.Namespace) -> int:
    from servo_axis.friction_id import table_from_run
    from servo_axis.storage import save_friction_table

    table = table_from_run(
        Path(args.run_dir), bin_width_m=args.bin_width_m, max_displacement_m=args.max_displacement_m
    )
    save_friction_table(Path(args.out), table)
    print(f"friction table with {len(table.displacement_m)} points written to {args.out}")
    return 0


def _gms_fit(args: argparse.Namespace) -> int:
    from servo_axis.gms_fit import fit_run_data, load_fit_data, plot_fit
    from servo_axis.storage import save_gms_parameters

    data = load_fit_data(Path(args.run_dir))
    fit = fit_run_data(data, elements=args.elements)
    p = fit.params
    save_gms_parameters(
        Path(args.out),
        p,
        plant_model=data.plant_model,
        plant_fingerprint=data.plant_fingerprint,
    )
    print(f"GMS model with {p.elements} elements written to {args.out} ({data.plant_fingerprint})")
    print(f"  F_c = {p.coulomb_Nm:.6g} N m")
    print(f"  {'element':>7}  {'k_i (N m/m)':>12}  {'alpha_i':>8}  {'break-away (um)':>15}")
    for i, (k, a, b) in enumerate(zip(p.stiffness_Nm_per_m, p.weights, p.breakaway_m, strict=True)):
        print(f"  {i + 1:>7}  {k:>12.6g}  {a:>8.4f}  {b * 1e6:>15.4g}")
    print(f"  RMS residual = {fit.rms_residual_Nm:.4g} N m (samples from the first reversal on)")
    if args.plot:
        plot_fit(fit, data.position_m, data.torque_Nm, Path(args.plot))
        print(f"figure written to {args.plot}")
    return 0


def _summary(args: argparse.Namespace) -> int:
    from servo_axis.analysis.summary import load_summary
    from servo_axis.analysis.text import format_any_summary

    print(format_any_summary(load_summary(Path(args.run_dir))))
    return 0


def _compare(args: argparse.Namespace) -> int:
    from servo_axis.analysis.plots import plot_cycles, plot_error_overlay, plot_rmsd_bars
    from servo_axis.analysis.summary import AxesSummary, RunSummary, load_summary
    from servo_axis.analysis.text import (
        compare_table,
        max_error_table,
        rmsd_applies,
        rmsd_table,
    )

    loaded = [load_summary(Path(d)) for d in args.run_dirs]
    summaries: list[RunSummary] = []
    for run_dir, summary in zip(args.run_dirs, loaded, strict=True):
        if isinstance(summary, AxesSummary):
            axes = ", ".join(str(Path(run_dir) / a) for a in summary.axes)
            print(f"error: {run_dir}: a multi-axis run; compare its axes: {axes}", file=sys.stderr)
            return 2
        summaries.append(summary)
    labels = args.labels.split(",") if args.labels else [Path(d).name for d in args.run_dirs]
    if len(labels) != len(summaries):
        print(
            f"error: --labels: expected {len(summaries)} comma-separated labels, got {len(labels)}",
            file=sys.stderr,
        )
        return 2
    by_rmsd = args.rmsd or rmsd_applies(summaries)
    try:
        rmsd = rmsd_table(summaries, labels) if by_rmsd or args.bar_chart else ""
    except ValueError as err:  # errors in m and in rad
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(rmsd if by_rmsd else compare_table(summaries, labels))
    if not by_rmsd:
        print()
        print(max_error_table(summaries, labels))
    if args.bar_chart:
        plot_rmsd_bars(summaries, labels, Path(args.bar_chart), title="RMSD of tracking error")
        print(f"figure written to {args.bar_chart}")
    if args.out:
        plot_cycles(summaries, labels, Path(args.out), title=args.title)
        print(f"figure written to {args.out}")
    if args.error_out:
        plot_error_overlay(
            [Path(d) for d in args.run_dirs],
            labels,
            Path(args.error_out),
            zoom_cycle=args.zoom_cycle,
            title=args.title,
        )
        print(f"figure written to {args.error_out}")
    return 0


def _bag_recover(args: argparse.Namespace) -> int:
    from servo_axis.recording.recover import recover_bag

    print(recover_bag(Path(args.bag_dir)).line())
    return 0


def _list(args: argparse.Namespace) -> int:
    from servo_axis.params.scenario import load_scenario, scenario_dir, shared

    folder = Path(args.config_dir) if args.config_dir else scenario_dir()
    for path in sorted(folder.glob("*.yaml")):
        about = shared(load_scenario(path)).get("scenario", {})
        print(f"{path.stem:<24} {about.get('description', '')}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m servo_axis``."""
    parser = argparse.ArgumentParser(prog="python -m servo_axis", description=__doc__)
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run a scenario end to end and record it")
    run.add_argument(
        "scenario",
        help="name of a shipped scenario (see `list`), e.g. rptc_detailed, "
        "or a scenario file (ROS parameter YAML)",
    )
    run.add_argument("--out", help="run directory to create (default runs/<name>-<time>)")
    run.add_argument("--composed", action="store_true", help="all nodes in one process")
    run.add_argument(
        "--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: from env or pid)"
    )
    run.add_argument("--namespace", default="", help="namespace of the axis, e.g. /x")
    run.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    run.add_argument(
        "--respawn-limit",
        type=int,
        default=None,
        help="restarts of a dead learning unit per axis (default 3; 0: no restart)",
    )
    run.add_argument(
        "--live",
        action="store_true",
        help="serve the run to Foxglove / Lichtblick while it runs on ws://127.0.0.1:8765 "
        "(needs the extra: pip install -e '.[live]')",
    )
    run.add_argument(
        "--live-port", type=int, default=None, help="port of the live view (implies --live)"
    )
    run.set_defaults(func=_run)
    ft = sub.add_parser("friction-table", help="build a friction table from a friction_id run")
    ft.add_argument("run_dir")
    ft.add_argument("--out", required=True, help="CSV file to write")
    ft.add_argument("--bin-width-m", type=float, default=0.5e-6)
    ft.add_argument("--max-displacement-m", type=float, default=40e-6)
    ft.set_defaults(func=_friction_table)
    gms = sub.add_parser(
        "gms-fit",
        help="fit a GMS friction model (Al-Bender et al. 2005; paper 004 Fig. 4(b)) to a "
        "friction_id run",
    )
    gms.add_argument("run_dir")
    gms.add_argument("--out", required=True, help="GMS parameter file to write")
    gms.add_argument("--elements", type=int, default=4, help="number of elements (default 4)")
    gms.add_argument("--plot", help="PNG to write: measured and model torque against displacement")
    gms.set_defaults(func=_gms_fit)
    sm = sub.add_parser("summary", help="print the summary of a run directory")
    sm.add_argument("run_dir")
    sm.set_defaults(func=_summary)
    ls = sub.add_parser("list", help="the shipped scenarios and what each runs")
    ls.add_argument("--config-dir", default=None, help="list this folder's scenarios instead")
    ls.set_defaults(func=_list)
    cmp = sub.add_parser(
        "compare",
        help="max/RMS error per cycle of several runs (e.g. Q vs Q~n, 000 Fig. 15); for "
        "runs where cycles do not apply (a rotary table, an identifier, no periodic "
        "reference) the RMSD of each run and its reduction against the run labelled pid "
        "(else the scenario *_pid, else the first), with the final estimates / true values "
        "(003 Fig. 9)",
    )
    cmp.add_argument("run_dirs", nargs="+")
    cmp.add_argument("--labels", help="comma-separated, one per run (default: directory names)")
    cmp.add_argument("--out", help="PNG to write: max and RMS error per cycle")
    cmp.add_argument("--error-out", help="PNG to write: error against time, one cycle enlarged")
    cmp.add_argument("--zoom-cycle", type=int, default=3, help="the cycle enlarged (default 3)")
    cmp.add_argument("--title", default="tracking error per cycle")
    cmp.add_argument(
        "--rmsd", action="store_true", help="compare by RMSD of the whole run, not per cycle"
    )
    cmp.add_argument("--bar-chart", help="PNG to write: RMSD per run as bars (003 Fig. 9)")
    cmp.set_defaults(func=_compare)
    bag = sub.add_parser("bag", help="bag tools: recover")
    bag_sub = bag.add_subparsers(dest="bag_command", required=True)
    rec = bag_sub.add_parser(
        "recover",
        help="make a bag whose recorder died (no metadata.yaml, no MCAP summary) readable "
        "again; the original file is kept as <file>.unfinished",
    )
    rec.add_argument("bag_dir", help="the bag directory, e.g. <run>/bag")
    rec.set_defaults(func=_bag_recover)
    args = parser.parse_args(argv)
    if args.command is None:
        args = parser.parse_args(["run", DEFAULT_SCENARIO])
    try:
        return int(args.func(args))
    except BrokenPipeError:
        # The reader of our output went away (`list | head`): not an error of ours.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (ServoAxisError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
