"""Summaries and per-cycle comparisons of runs as plain-text tables (errors in um)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from servo_axis.analysis.health import RunHealth
from servo_axis.analysis.summary import AxesSummary, ErrorStats, RunSummary, cycle_errors


def _um(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x * 1e6:.6g}"


def _row(label: str, stats: ErrorStats) -> str:
    return f"  {label:<21}{_um(stats.rms_m):>12} {_um(stats.max_m):>14}"


def _health_lines(health: RunHealth | None) -> list[str]:
    """The run's health: outcome, determinism, rejected messages, strangers, deaths."""
    if health is None:
        return []
    verdict = "deterministic" if health.deterministic else "NOT the deterministic result"
    rejected: dict[str, int] = {}
    for report in health.nodes.values():
        for name, n in report.get("rejected", {}).items():
            rejected[name] = rejected.get(name, 0) + n
    lines = [f"health            {health.outcome}, {verdict} (exit {health.exit_code})"]
    if rejected:
        lines.append(
            "rejected messages " + ", ".join(f"{k}: {v}" for k, v in sorted(rejected.items()))
        )
    lines += [f"                  - {reason}" for reason in health.reasons]
    return lines


def format_summary(summary: RunSummary) -> str:
    """A single-axis summary as a plain-text table (errors in um)."""
    s = summary
    te = s.tracking_error
    lines = [
        f"scenario          {s.scenario}  ({s.processes}, {s.time_mode})",
        f"steps             {s.steps}  ({s.sim_time_s:.3f} s simulated)",
        f"wall time         {s.wall_time_s:.2f} s  ->  {s.steps_per_s:,.0f} steps/s, "
        f"{s.realtime_factor:.2f}x real time",
        "messages          " + ", ".join(f"{k}: {v}" for k, v in sorted(s.message_counts.items())),
        "faults            "
        + (", ".join(f"{f.name} at step {f.step}" for f in s.faults) or "none"),
        *_health_lines(s.health),
        *(
            [
                f"ILC eq. (7)       max |Q(1 - S L P)| = {s.ilc_convergence['nominal']:.4g} "
                f"(nominal), {s.ilc_convergence['plant']:.4g} (plant), "
                f"Nq = {s.ilc_convergence['nq']:g}"
            ]
            if s.ilc_convergence
            else []
        ),
        "",
        "tracking error (um)          RMS            max",
        _row("all samples", te.all_samples),
        _row("at T_r instants", te.reference_instants),
    ]
    if te.after_first_cycle is not None:
        a = te.after_first_cycle
        name = s.period_name or "cycle"
        lines += [
            _row(f"after {name} 1", a.all_samples),
            _row("... at T_r instants", a.reference_instants),
            "",
            f"{name:<5}   RMS (um)       max (um)       max at T_r (um)",
        ]
        for c in te.cycles:
            lines.append(
                f"{c.cycle:>5} {_um(c.rms_m):>12} {_um(c.max_m):>14} "
                f"{_um(c.reference_instants.max_m):>18}"
            )
    return "\n".join(lines)


def format_axes_summary(summary: AxesSummary) -> str:
    """A multi-axis summary as text: each axis, then the contour per cycle (um)."""
    lines = [
        f"scenario          {summary.scenario}  (axes {', '.join(summary.axes)})",
        *_health_lines(summary.health),
    ]
    for axis, s in summary.axes.items():
        lines += ["", f"== axis {axis}", format_summary(s)]
    c = summary.contour
    if c is not None:
        lines += [
            "",
            f"== contour: circle of radius {1e3 * c.radius_m:.3f} mm "
            f"(target off the circle by {_um(c.target_radial_deviation_m)} um)",
            f"circular deviation {_um(c.circular_deviation_m)} um, "
            f"max radial error {_um(c.max_radial_m)} um",
            "cycle   circular deviation (um)   max radial error (um)",
        ]
        for row in c.cycles:
            lines.append(
                f"{row.cycle:>5} {_um(row.circular_deviation_m):>25} {_um(row.max_radial_m):>23}"
            )
    return "\n".join(lines)


def format_any_summary(summary: RunSummary | AxesSummary) -> str:
    """:func:`format_axes_summary` for a multi-axis run, else :func:`format_summary`."""
    if isinstance(summary, AxesSummary):
        return format_axes_summary(summary)
    return format_summary(summary)


def period_word(summaries: Sequence[RunSummary]) -> str:
    """``trial`` when the first run's periods are trials, else ``cycle``."""
    return (summaries[0].period_name if summaries else None) or "cycle"


def compare_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> str:
    """Max and RMS tracking error per cycle of several runs side by side (000 Fig. 15).

    Two blocks, ``max error per cycle (um)`` and ``RMS error per cycle (um)``,
    a row per cycle and a column per run; 6 significant digits.
    """
    per_run = [cycle_errors(s) for s in summaries]
    n = max((len(c["cycle"]) for c in per_run), default=0)
    width = max(14, *(len(label) + 2 for label in labels))
    word = period_word(summaries)
    lines: list[str] = []
    for title, key in (("max", "max_m"), ("RMS", "rms_m")):
        if lines:
            lines.append("")
        lines += [
            f"{title} error per {word} (um)",
            f"{word:<5}" + "".join(f"{x:>{width}}" for x in labels),
        ]
        for k in range(n):
            cells = [
                f"{1e6 * c[key][k]:>{width}.6g}" if k < len(c[key]) else " " * width
                for c in per_run
            ]
            lines.append(f"{k + 1:>5}" + "".join(cells))
    return "\n".join(lines)
