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
``python -m servo_axis sweep STUDY.yaml [--out DIR] [--scheduler tcp://HOST:PORT] [--workers N]``
    a parameter sweep (a study) on dask.distributed: results.parquet/.csv,
    manifest.json (an interrupted study resumes), a PNG per figure and parameter;
``python -m servo_axis bag recover BAG_DIR``
    make a bag whose recorder died readable again (a complete bag is left as it is).

With no arguments it runs the shipped scenario ``rptc_friction_table``: the
detailed axis (resonances, dead time, rolling friction) with the friction
table from cycle 1 and repetitive PTC learning from cycle 2.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import NoReturn

from servo_axis.core.errors import ConfigError, ServoAxisError
from servo_axis.params.names import domain_id_problem, namespace_problem

#: The shipped scenario ``python -m servo_axis`` runs.
DEFAULT_SCENARIO = "rptc_friction_table"


def _read_floor(path: str) -> dict[int, dict]:
    """rt_floor.py ``--json`` results by period in us (one clear line if the file is not that)."""
    import json

    try:
        rows = [json.loads(ln) for ln in Path(path).read_text().splitlines() if ln.strip()]
        return {int(r["period_us"]): r for r in rows if {"miss_pct", "round_trip_us"} <= set(r)}
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ConfigError(f"--floor {path}: not rt_floor.py --json output ({err})") from err


def _run(args: argparse.Namespace) -> int:
    from servo_axis.analysis.health import EXIT_FAILED, EXIT_FAULT, EXIT_OK
    from servo_axis.analysis.summary import AxesSummary
    from servo_axis.analysis.text import format_any_summary
    from servo_axis.run.live_channels import DEFAULT_PORT
    from servo_axis.run.runner import RunError, RunInterruptedError, RunOptions, run_scenario

    floor = None
    if args.floor:
        floor = _read_floor(args.floor)
    live_port = args.live_port  # --live-port implies --live
    if live_port is None and args.live:
        live_port = DEFAULT_PORT
    try:
        options = RunOptions(
            out_dir=Path(args.out) if args.out else None,
            composed=args.composed,
            domain_id=args.domain_id,
            namespace=args.namespace,
            plots=not args.no_plots,
            external=tuple(args.external),
            external_timeout_s=args.external_timeout,
            **({} if args.respawn_limit is None else {"respawn_limit": args.respawn_limit}),
            live_port=live_port,
            floor=floor,
        )
        result = run_scenario(args.scenario, options)
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
    with _writing("--out", args.out):
        save_friction_table(Path(args.out), table)
    print(f"friction table with {len(table.displacement_m)} points written to {args.out}")
    return 0


def _gms_fit(args: argparse.Namespace) -> int:
    from servo_axis.gms_fit import fit_run_data, load_fit_data, plot_fit
    from servo_axis.storage import save_gms_parameters

    data = load_fit_data(Path(args.run_dir))
    fit = fit_run_data(data, elements=args.elements)
    p = fit.params
    with _writing("--out", args.out):
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
        with _writing("--plot", args.plot):
            plot_fit(fit, data.position_m, data.torque_Nm, Path(args.plot))
        print(f"figure written to {args.plot}")
    return 0


def _sweep(args: argparse.Namespace) -> int:
    from servo_axis.sweep.engine import VersionMismatchError, run_study
    from servo_axis.sweep.spec import load_study

    study = load_study(args.study)
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


def _summary(args: argparse.Namespace) -> int:
    from servo_axis.analysis.summary import load_summary
    from servo_axis.analysis.text import format_any_summary

    print(format_any_summary(load_summary(Path(args.run_dir))))
    return 0


def _compare(args: argparse.Namespace) -> int:
    from servo_axis.analysis.comparison import differences
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
    if not all(label.strip() for label in labels):
        print(f"error: --labels {args.labels!r}: a label is empty", file=sys.stderr)
        return 2
    units = sorted({s.unit for s in summaries})
    if len(units) > 1:  # no --force for this one: m and rad have no common scale
        print(f"error: runs with errors in different units ({', '.join(units)})", file=sys.stderr)
        return 2
    differ = differences([Path(d) for d in args.run_dirs], summaries, labels)
    if differ and not args.force:
        print(
            f"error: the runs do not compare: {'; '.join(differ)} (--force compares them anyway)",
            file=sys.stderr,
        )
        return 2
    if differ:
        print(f"warning: compared anyway (--force): {'; '.join(differ)}", file=sys.stderr)
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
        with _writing("--bar-chart", args.bar_chart):
            plot_rmsd_bars(summaries, labels, Path(args.bar_chart), title="RMSD of tracking error")
        print(f"figure written to {args.bar_chart}")
    if args.out:
        with _writing("--out", args.out):
            plot_cycles(summaries, labels, Path(args.out), title=args.title)
        print(f"figure written to {args.out}")
    if args.error_out:
        with _writing("--error-out", args.error_out):
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
    found = sorted(folder.glob("*.yaml"))
    if not found:
        raise ConfigError(f"--config-dir {folder}: no scenario files (*.yaml) there")
    for path in found:
        about = shared(load_scenario(path)).get("scenario", {})
        print(f"{path.stem:<24} {about.get('description', '')}")
    _list_extensions()
    return 0


def _list_extensions() -> None:
    """The installed plant models, feedforward terms, learning laws and identification methods."""
    from servo_axis.params.registry import REGISTRIES

    selected_by = {
        "plant model": "plant.model",
        "feedforward term": "its <term>.enabled",
        "learning law": "learning.law",
        "identification method": "identifier.method",
    }
    for kind, registry in REGISTRIES.items():
        print(f"\n{kind}s (selected by {selected_by[kind]}; entry points {registry.group}):")
        for name in sorted(registry):
            entry = registry[name]
            print(f"  {name:<22} {entry.description} [{registry.source(name)}]")
            if entry.schema:
                print(f"  {'':<22} keys: {', '.join(entry.schema)}")


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
  python -m servo_axis run ptc_nominal --out runs/ptc
  python -m servo_axis run rptc_detailed --composed --namespace /x --domain-id 42
  python -m servo_axis summary runs/ptc
  python -m servo_axis compare runs/q runs/q5 --labels Q,Q~5 --out cycles.png
  python -m servo_axis compare runs/pid runs/lpf2 --rmsd --bar-chart rmsd.png
  python -m servo_axis friction-table runs/friction_id --out table.csv
  python -m servo_axis gms-fit runs/friction_id_elastic --out gms.txt --plot fit.png
  python -m servo_axis bag recover runs/ptc/bag
(`servo-axis` is the same command as `python -m servo_axis`.)

Exit codes of run: 0 complete and deterministic (realtime: complete, never
deterministic), 1 failed, 2 bad option or configuration (nothing started or
written), 3 not the deterministic result, 4 the feedback loop tripped,
130/143 interrupted by SIGINT/SIGTERM.
"""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit 2)."""

    def error(self, message: str) -> NoReturn:
        text = " ".join(message.split())
        self.exit(2, f"error: {text} (see {self.prog} --help)\n")


def _domain_id(text: str) -> int:
    problem = domain_id_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return int(text)


def _namespace(text: str) -> str:
    if text == "":
        return ""
    problem = namespace_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{text!r} is not a valid ROS namespace: {problem}")
    return "" if text == "/" else text


def _int_at_least(low: int, high: int | None = None) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value > high):
            span = f"{low}..{high}" if high is not None else f">= {low}"
            raise argparse.ArgumentTypeError(f"{text!r}: expected an integer {span}")
        return value

    return parse


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number > 0")
    return value


def _output_file(text: str) -> str:
    """A file to write: its folder must exist; it must not be a folder."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a directory, expected a file to write")
    if not path.parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: cannot write it: no directory {path.parent}")
    return text


def _existing_dir(text: str) -> str:
    if not Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"{text}: no such directory")
    return text


@contextmanager
def _writing(option: str, path: str) -> Iterator[None]:
    """Turn an OS error while ``path`` is written into one line naming ``option``."""
    try:
        yield
    except OSError as err:
        raise ConfigError(f"{option} {path}: cannot write it: {err}") from None


def build_parser(prog: str = "python -m servo_axis") -> argparse.ArgumentParser:
    """The command line's parser (every argument with its help)."""
    parser = _Parser(
        prog=prog,
        description=DESCRIPTION,
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(
        dest="command", metavar="COMMAND", help=f"what to do (default: run {DEFAULT_SCENARIO})"
    )
    run = sub.add_parser(
        "run",
        help="run a scenario end to end and record it",
        description="Run a scenario end to end: start the nodes, record every topic, "
        "write summary.json and the plots.",
    )
    run.add_argument(
        "scenario",
        help="name of a shipped scenario (see `list`), e.g. rptc_detailed, "
        "or a scenario file (ROS parameter YAML)",
    )
    run.add_argument(
        "--out",
        help="run directory to create; must be empty or not exist (default runs/<name>-<time>)",
    )
    run.add_argument(
        "--composed", action="store_true", help="all nodes in one process on one executor"
    )
    run.add_argument(
        "--domain-id",
        type=_domain_id,
        default=None,
        help="ROS_DOMAIN_ID of the run, 0..232 (default: ROS_DOMAIN_ID, else derived from the pid)",
    )
    run.add_argument(
        "--namespace",
        type=_namespace,
        default="",
        help="ROS namespace of a single-axis run's nodes and topics, absolute "
        "(default /<axis>, e.g. /x; / for the root)",
    )
    run.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    run.add_argument(
        "--floor",
        metavar="FILE",
        help="a realtime run's summary shows this host's floor next to its misses: the "
        "output of the shared tools' rt_floor.py --json (one result a line, by period)",
    )
    run.add_argument(
        "--respawn-limit",
        type=_int_at_least(0),
        default=None,
        help="restarts of a dead learning unit or identifier per axis (default 3; 0: no restart)",
    )
    run.add_argument(
        "--external",
        action="append",
        default=[],
        metavar="ROLE",
        help="a node from outside the suite plays ROLE (plant, feedback, feedforward, "
        "learning, identifier; repeatable; also the scenario key external_roles): the run "
        "starts the others, prints the topics the outside node must serve and waits for it",
    )
    run.add_argument(
        "--external-timeout",
        type=float,
        default=120.0,
        metavar="S",
        help="seconds to wait for the outside nodes before the first step (default 120)",
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
    ft.add_argument("run_dir", help="run directory of a friction_id run")
    ft.add_argument("--out", required=True, type=_output_file, help="CSV file to write")
    ft.add_argument(
        "--bin-width-m",
        type=_positive_float,
        default=0.5e-6,
        help="displacement bin of the table, m (default 0.5e-6)",
    )
    ft.add_argument(
        "--max-displacement-m",
        type=_positive_float,
        default=40e-6,
        help="displacement after a reversal the table covers, m (default 40e-6)",
    )
    ft.set_defaults(func=_friction_table)
    gms = sub.add_parser(
        "gms-fit",
        help="fit a GMS friction model (Al-Bender et al. 2005; paper 004 Fig. 4(b)) to a "
        "friction_id run",
    )
    gms.add_argument(
        "run_dir", help="run directory of a friction_id run (e.g. friction_id_elastic)"
    )
    gms.add_argument("--out", required=True, type=_output_file, help="GMS parameter file to write")
    gms.add_argument(
        "--elements",
        type=_int_at_least(1, 20),
        default=4,
        help="number of Maxwell-slip elements, 1..20 (default 4)",
    )
    gms.add_argument(
        "--plot",
        type=_output_file,
        help="PNG to write: measured and model torque against displacement",
    )
    gms.set_defaults(func=_gms_fit)
    sw = sub.add_parser(
        "sweep",
        help="run a study (a parameter sweep of a scenario) on dask.distributed",
        description="Run a study: the points of a grid or list of overrides of a base "
        "scenario, on a LocalCluster or a running dask scheduler; write results.parquet, "
        "results.csv, manifest.json (a second call resumes) and a PNG per figure and "
        "swept parameter.",
    )
    sw.add_argument(
        "study",
        help="study file (YAML; README, Studies) or a shipped study's name, e.g. reversal_004",
    )
    sw.add_argument("--out", help="study directory (default studies/<name>)")
    sw.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="address of a running dask scheduler (default: a LocalCluster)",
    )
    sw.add_argument(
        "--workers",
        type=_int_at_least(1),
        default=None,
        help="worker processes of the LocalCluster, one thread each (default: the cores)",
    )
    sw.add_argument(
        "--retry-failed", action="store_true", help="run again the points that failed before"
    )
    sw.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    sw.set_defaults(func=_sweep)
    sm = sub.add_parser("summary", help="print the summary of a run directory")
    sm.add_argument("run_dir", help="run directory (holds summary.json)")
    sm.set_defaults(func=_summary)
    ls = sub.add_parser(
        "list",
        help="the shipped scenarios and what each runs, then the installed plant models, "
        "feedforward terms, learning laws and identification methods with their keys",
    )
    ls.add_argument(
        "--config-dir",
        type=_existing_dir,
        default=None,
        help="list this folder's scenarios instead",
    )
    ls.set_defaults(func=_list)
    cmp = sub.add_parser(
        "compare",
        help="max/RMS error per cycle of several runs (e.g. Q vs Q~n, 000 Fig. 15); for "
        "runs where cycles do not apply (a rotary table, an identifier, no periodic "
        "reference) the RMSD of each run and its reduction against the run labelled pid "
        "(else the scenario *_pid, else the first), with the final estimates / true values "
        "(003 Fig. 9)",
    )
    cmp.add_argument(
        "run_dirs",
        nargs="+",
        metavar="run_dir",
        help="run directories (single-axis, or one axis of a multi-axis run)",
    )
    cmp.add_argument("--labels", help="comma-separated, one per run (default: directory names)")
    cmp.add_argument("--out", type=_output_file, help="PNG to write: max and RMS error per cycle")
    cmp.add_argument(
        "--error-out",
        type=_output_file,
        help="PNG to write: error against time, one cycle enlarged",
    )
    cmp.add_argument(
        "--zoom-cycle",
        type=_int_at_least(1),
        default=3,
        help="the cycle --error-out enlarges, from 1 (default 3)",
    )
    cmp.add_argument(
        "--title",
        default="tracking error per cycle",
        help="title of the --out and --error-out figures",
    )
    cmp.add_argument(
        "--rmsd", action="store_true", help="compare by RMSD of the whole run, not per cycle"
    )
    cmp.add_argument(
        "--bar-chart", type=_output_file, help="PNG to write: RMSD per run as bars (003 Fig. 9)"
    )
    cmp.add_argument(
        "--force",
        action="store_true",
        help="compare runs with different references, control periods or cycles anyway",
    )
    cmp.set_defaults(func=_compare)
    bag = sub.add_parser("bag", help="bag tools: recover")
    bag_sub = bag.add_subparsers(
        dest="bag_command", required=True, metavar="BAG_COMMAND", help="what to do with a bag"
    )
    rec = bag_sub.add_parser(
        "recover",
        help="make a bag whose recorder died (no metadata.yaml, no MCAP summary) readable "
        "again; the original file is kept as <file>.unfinished",
    )
    rec.add_argument("bag_dir", help="the bag directory, e.g. <run>/bag")
    rec.set_defaults(func=_bag_recover)
    for group in (sub, bag_sub):  # each command's --help starts with what it does
        for choice in group._choices_actions:
            command = group.choices[choice.dest]
            if command.description is None:
                command.description = f"{choice.help[0].upper()}{choice.help[1:]}."
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
    try:
        return int(args.func(args))
    except BrokenPipeError:
        # The reader of our output went away (`list | head`): not an error of ours.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return 128 + int(signal.SIGINT)
    except (ServoAxisError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


def console() -> int:
    """Entry point of the ``servo-axis`` console command."""
    return main(prog="servo-axis")


if __name__ == "__main__":
    raise SystemExit(main())
