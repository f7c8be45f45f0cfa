"""``compare RUN_DIR...``: runs side by side, per cycle or by RMSD (000 Fig. 15, 003 Fig. 9)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from servo_axis.cli.options import Subparsers, int_at_least, output_file, writing
from servo_axis.core.errors import ConfigError

if TYPE_CHECKING:
    from servo_axis.analysis.summary import RunSummary


def add_parser(commands: Subparsers) -> None:
    """The ``compare`` command and its options."""
    cmp = commands.add_parser(
        "compare",
        help="max/RMS error per cycle of several runs, each run's reduction against the first "
        "in the same cycle, and the headline: each run's last cycle against the first run's "
        "last cycle (e.g. Q vs Q~n, 000 Fig. 15); for runs where cycles do not apply (a rotary "
        "table, an identifier, no periodic reference) the RMSD of each run and its reduction "
        "against the run labelled pid (else the scenario *_pid, else the first), with the final "
        "estimates / true values (003 Fig. 9)",
    )
    cmp.add_argument(
        "run_dirs",
        nargs="+",
        metavar="run_dir",
        help="run directories (single-axis, or one axis of a multi-axis run)",
    )
    cmp.add_argument("--labels", help="comma-separated, one per run (default: directory names)")
    cmp.add_argument("--out", type=output_file, help="PNG to write: max and RMS error per cycle")
    cmp.add_argument(
        "--error-out",
        type=output_file,
        help="PNG to write: error against time, one cycle enlarged",
    )
    cmp.add_argument(
        "--zoom-cycle",
        type=int_at_least(1),
        help="the cycle --error-out enlarges, from 1; a complete cycle of every run (default: "
        "the last cycle every run completed)",
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
        "--bar-chart", type=output_file, help="PNG to write: RMSD per run as bars (003 Fig. 9)"
    )
    cmp.add_argument(
        "--force",
        action="store_true",
        help="compare runs with different references, control periods or cycles anyway",
    )
    cmp.set_defaults(func=handle)


def handle(args: argparse.Namespace) -> int:
    """Print the table, write the figures asked for; a run that does not compare is refused."""
    from servo_axis.analysis.comparison import differences
    from servo_axis.analysis.text import compare_table, last_cycle_table, rmsd_applies, rmsd_table

    summaries = _single_axis_summaries(args.run_dirs)
    labels = _labels(args.labels, args.run_dirs)
    units = sorted({s.unit for s in summaries})
    if len(units) > 1:  # no --force for this one: m and rad have no common scale
        raise ConfigError(f"runs with errors in different units ({', '.join(units)})")
    differ = differences([Path(d) for d in args.run_dirs], summaries, labels)
    if differ and not args.force:
        raise ConfigError(
            f"the runs do not compare: {'; '.join(differ)} (--force compares them anyway)"
        )
    zoom = _zoom_cycle(args.zoom_cycle, summaries, labels) if args.error_out else None
    if differ:
        print(f"warning: compared anyway (--force): {'; '.join(differ)}", file=sys.stderr)
    by_rmsd = args.rmsd or rmsd_applies(summaries)
    rmsd = rmsd_table(summaries, labels) if by_rmsd or args.bar_chart else ""
    print(rmsd if by_rmsd else compare_table(summaries, labels))
    if not by_rmsd:
        print()
        print(last_cycle_table(summaries, labels))
    _write_figures(args, summaries, labels, zoom if zoom else None)
    return 0


def _zoom_cycle(given: int | None, summaries: list[RunSummary], labels: list[str]) -> int:
    """The cycle ``--error-out`` enlarges: ``--zoom-cycle``, checked against every run's
    complete cycles, else the last cycle every run completed; 0 for runs without cycles."""
    from servo_axis.analysis.text import last_common_cycle, period_word

    last = last_common_cycle(summaries)
    if given is None:
        return last
    word = period_word(summaries)
    missing = [
        label
        for label, s in zip(labels, summaries, strict=True)
        if given not in {c.cycle for c in s.tracking_error.cycles}
    ]
    if missing:
        have = (
            f"every run completed {word}s 1 to {last}"
            if last
            else f"no {word} is complete in every run"
        )
        raise ConfigError(
            f"--zoom-cycle {given}: not a complete {word} of {', '.join(missing)}; {have}"
        )
    return given


def _single_axis_summaries(run_dirs: list[str]) -> list[RunSummary]:
    """Each run's summary; a multi-axis run is refused, naming its axes."""
    from servo_axis.analysis.summary import AxesSummary, load_summary

    loaded = [load_summary(Path(d)) for d in run_dirs]
    summaries: list[RunSummary] = []
    for run_dir, summary in zip(run_dirs, loaded, strict=True):
        if isinstance(summary, AxesSummary):
            axes = ", ".join(str(Path(run_dir) / a) for a in summary.axes)
            raise ConfigError(f"{run_dir}: a multi-axis run; compare its axes: {axes}")
        summaries.append(summary)
    return summaries


def _labels(given: str | None, run_dirs: list[str]) -> list[str]:
    """``--labels``, one per run and none empty; else the directories' names."""
    labels = given.split(",") if given else [Path(d).name for d in run_dirs]
    if len(labels) != len(run_dirs):
        raise ConfigError(
            f"--labels: expected {len(run_dirs)} comma-separated labels, got {len(labels)}"
        )
    if not all(label.strip() for label in labels):
        raise ConfigError(f"--labels {given!r}: a label is empty")
    return labels


def _write_figures(
    args: argparse.Namespace, summaries: list[RunSummary], labels: list[str], zoom: int | None
) -> None:
    """The figures of ``--bar-chart``, ``--out`` and ``--error-out``, each when asked for."""
    from servo_axis.analysis.plots import plot_cycles, plot_error_overlay, plot_rmsd_bars

    if args.bar_chart:
        with writing("--bar-chart", args.bar_chart):
            plot_rmsd_bars(summaries, labels, Path(args.bar_chart), title="RMSD of tracking error")
        print(f"figure written to {args.bar_chart}")
    if args.out:
        with writing("--out", args.out):
            plot_cycles(summaries, labels, Path(args.out), title=args.title)
        print(f"figure written to {args.out}")
    if args.error_out:
        with writing("--error-out", args.error_out):
            plot_error_overlay(
                [Path(d) for d in args.run_dirs],
                labels,
                Path(args.error_out),
                zoom_cycle=zoom,
                title=args.title,
            )
        print(f"figure written to {args.error_out}")
