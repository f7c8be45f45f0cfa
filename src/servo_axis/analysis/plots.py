"""PNG figures of recorded runs (matplotlib, Agg backend, imported when called).

* :func:`plot`: reference and position, tracking error and, for a periodic
  reference, the error per cycle of one run;
* :func:`plot_cycles`: max and RMS error per cycle of several runs (000 Fig. 15);
* :func:`plot_error_overlay`: the error of several runs against time, one
  cycle enlarged (000 Fig. 13(b)-(c), Fig. 15(b)-(c));
* :func:`plot_contour`: the path of a two-axis circle run with the radial
  error magnified, and the circular deviation per cycle (000 Fig. 18).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.analysis.summary import (
    SUMMARY_FILE,
    AxesSummary,
    RunSummary,
    contour,
    cycle_errors,
    run_series,
)
from servo_axis.analysis.text import period_word
from servo_axis.core.errors import ConfigError
from servo_axis.core.timing import SampleGrid


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_cycles(
    summaries: Sequence[RunSummary], labels: Sequence[str], path: Path, *, title: str
) -> Path:
    """Max and RMS tracking error per cycle of one or more runs (000 Fig. 15), log scale."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for summary, label, marker in zip(summaries, labels, "osd^v<>", strict=False):
        c = cycle_errors(summary)
        (line,) = ax.semilogy(c["cycle"], 1e6 * c["max_m"], "-" + marker, label=f"{label}: max")
        ax.semilogy(
            c["cycle"],
            1e6 * c["rms_m"],
            ":" + marker,
            color=line.get_color(),
            ms=4,
            label=f"{label}: RMS",
        )
    ax.set_xlabel(period_word(summaries))
    ax.set_ylabel("tracking error (um)")
    ax.set_title(title)
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_error_overlay(
    run_dirs: Sequence[Path],
    labels: Sequence[str],
    path: Path,
    *,
    zoom_cycle: int,
    title: str,
) -> Path:
    """Tracking error of several runs against time, whole run and one cycle
    enlarged (000 Fig. 13(b)-(c), Fig. 15(b)-(c))."""
    plt = _pyplot()
    fig, (whole, zoom) = plt.subplots(2, 1, figsize=(9, 6))
    word = "cycle"
    for run_dir, label in zip(run_dirs, labels, strict=True):
        series = run_series(Path(run_dir))
        word = series.summary.period_name or "cycle"
        t = series.time_s
        err_um = series.error_m * 1e6
        whole.plot(t, err_um, lw=0.7, label=label)
        cycle_s = series.summary.reference_period_s
        if cycle_s:
            inside = (t >= (zoom_cycle - 1) * cycle_s) & (t < zoom_cycle * cycle_s)
            zoom.plot(t[inside], err_um[inside], lw=0.8, label=label)
    whole.set_title(title)
    zoom.set_title(f"{word} {zoom_cycle} enlarged")
    for ax in (whole, zoom):
        ax.set_xlabel("time (s)")
        ax.set_ylabel("tracking error (um)")
        ax.grid(True, lw=0.3)
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot(run_dir: Path) -> list[Path]:
    """Write ``reference_position.png``, ``error.png`` and, for a periodic
    reference, ``cycle_errors.png`` into the run directory."""
    plt = _pyplot()
    run_dir = Path(run_dir)
    series = run_series(run_dir)
    summary, sig, y, lead = series.summary, series.signals, series.y_rad, series.lead_m_per_rad
    t = series.time_s
    err = series.error_m * 1e6
    even = SampleGrid(control_period_s=summary.control_period_s).reference_instants(sig.step)
    figures: list[tuple[str, str, str, list[tuple[Any, Any, str, str]]]] = [
        (
            "reference_position.png",
            "table position (mm)",
            "reference and position",
            [
                (t, sig.reference_rad * lead * 1e3, "-", "reference r"),
                (t, y * lead * 1e3, "--", "position y"),
            ],
        ),
        (
            "error.png",
            "tracking error (um)",
            "tracking error e = R (r - y)",
            [(t, err, "-", "all samples"), (t[even], err[even], ".", "T_r instants")],
        ),
    ]
    paths = []
    for name, ylabel, title, lines in figures:
        fig, ax = plt.subplots(figsize=(9, 4))
        for x_values, y_values, style, label in lines:
            ax.plot(x_values, y_values, style, label=label, lw=0.8, ms=2)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{summary.scenario}: {title}")
        ax.legend()
        ax.grid(True)
        fig.tight_layout()
        paths.append(run_dir / name)
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    if len(cycle_errors(summary)["cycle"]) >= 2:
        paths.append(
            plot_cycles(
                [summary],
                [summary.scenario],
                run_dir / "cycle_errors.png",
                title=f"{summary.scenario}: tracking error per {summary.period_name or 'cycle'}",
            )
        )
    return paths


def plot_contour(run_dir: Path) -> Path:
    """``contour.png``: the path of the first and last cycle with the radial
    error magnified (000 Fig. 18), and the circular deviation per cycle."""
    plt = _pyplot()
    run_dir = Path(run_dir)
    summary = AxesSummary.from_json(run_dir / SUMMARY_FILE)
    if summary.contour is None:
        raise ConfigError(f"run_dir: {run_dir} is not a two-axis run (no contour in its summary)")
    axes = list(summary.contour.axes)
    c = contour(run_dir, axes)
    steps, measured, radial = c.steps, c.measured, c.radial
    centre, radius = np.array(c.centre_m), c.radius_m
    first = summary.axes[axes[0]]
    if first.reference_period_s is None:
        raise ConfigError(f"run_dir: axis {axes[0]} of {run_dir} has no periodic reference")
    per_cycle = round(first.reference_period_s / first.control_period_s)
    gain = 0.2 * radius / max(c.max_radial_m, 1e-15)
    fig, (xy, bars) = plt.subplots(1, 2, figsize=(11, 5))
    angle = np.arctan2(*(measured - centre).T[::-1])
    phi = np.linspace(0, 2 * np.pi, 400)
    xy.plot(
        1e3 * (centre[0] + radius * np.cos(phi)),
        1e3 * (centre[1] + radius * np.sin(phi)),
        "k:",
        lw=0.8,
        label="target",
    )
    last = max(0, (int(steps.max()) + 1) // per_cycle - 1)  # the last whole cycle
    for cycle, style in ((0, "-"), (last, "-")):
        inside = (steps >= cycle * per_cycle) & (steps < (cycle + 1) * per_cycle)
        r = radius + gain * radial[inside]
        xy.plot(
            1e3 * (centre[0] + r * np.cos(angle[inside])),
            1e3 * (centre[1] + r * np.sin(angle[inside])),
            style,
            lw=0.9,
            label=f"cycle {cycle + 1}",
        )
    xy.set_aspect("equal")
    xy.set_xlabel(f"{axes[0]} (mm)")
    xy.set_ylabel(f"{axes[1]} (mm)")
    xy.set_title(f"radial error x {gain:,.0f}")
    xy.legend(fontsize="small")
    rows = summary.contour.cycles
    bars.bar([r.cycle for r in rows], [1e6 * r.circular_deviation_m for r in rows])
    bars.set_xlabel("cycle")
    bars.set_ylabel("circular deviation (um)")
    bars.set_title(f"{summary.scenario}: circularity per cycle")
    bars.grid(True, lw=0.3)
    fig.tight_layout()
    path = run_dir / "contour.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
