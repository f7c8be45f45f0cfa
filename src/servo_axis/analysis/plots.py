"""PNG figures of recorded runs (matplotlib, Agg backend, imported when called).

* :func:`plot`: reference and position, tracking error and, for a periodic
  reference, the error per cycle of one run;
* :func:`plot_cycles`: max and RMS error per cycle of several runs (000 Fig. 15);
* :func:`plot_error_overlay`: the error of several runs against time, one
  cycle enlarged (000 Fig. 13(b)-(c), Fig. 15(b)-(c));
* :func:`plot_contour`: the path of a two-axis circle run with the radial
  error magnified, and the circular deviation per cycle (000 Fig. 18);
* :func:`plot_identification`: a run's online estimates ``J, D, U, C``
  against the true values (003 Fig. 7) and its PE index (003 Fig. 6), part
  of :func:`plot` for a run with an identifier;
* :func:`plot_rmsd_bars`: the RMSD of several runs as bars with their
  reduction against the baseline (003 Fig. 9);
* :func:`plot_deformation`: the table position and the deformation ratio
  ``d_r`` before each stop of the reference, a column per stop (004 Fig. 11),
  part of :func:`plot` for a run with the ``deformation`` topic;
* :func:`plot_reversal_detail`: position, ``d_r``, control input and
  tracking error around one stop (004 Fig. 12).

Every axis is in the one unit of its quantity (:mod:`servo_axis.analysis.units`),
named in its label, whatever the size of the values: a tracking error in um
(rad on a rotary axis), a position in mm (rad), a contour error in um,
``d_r`` in um/rad. Tick labels say their value without an offset or a
multiplier above the axis (:func:`plain_ticks`: plain numbers, or each in
e-notation below 1e-4 and from 1e6); cycle axes have integer ticks.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.analysis.summary import (
    SUMMARY_FILE,
    AxesSummary,
    Deformation,
    OnlineIdentification,
    RunSeries,
    RunSummary,
    contour,
    cycle_errors,
    run_series,
)
from servo_axis.analysis.text import (
    PARAMETER_ROWS,
    baseline_index,
    period_word,
    reductions,
)
from servo_axis.analysis.units import (
    CONTOUR_ERROR,
    DEFORMATION_RATIO,
    QUANTITIES,
    TIME_FROM_STOP,
    position,
    position_error,
)
from servo_axis.core.errors import ConfigError
from servo_axis.core.timing import SampleGrid
from servo_axis.wire.cdr import EstimateData

#: The figures :func:`plot_identification` writes into a run directory.
IDENTIFICATION_FIGURES: tuple[str, str] = (
    "identification_parameters.png",
    "identification_pe_index.png",
)


#: The figure :func:`plot_deformation` writes into a run directory.
DEFORMATION_FIGURE = "deformation.png"

#: Stops :func:`plot_deformation` shows at most (the first ones), a column each.
DEFORMATION_COLUMNS = 6


def _tick_formatter() -> Any:
    """A matplotlib formatter whose every tick label says its value (see :func:`plain_ticks`)."""
    from matplotlib.ticker import ScalarFormatter

    class SelfContained(ScalarFormatter):  # type: ignore[misc]
        def __init__(self) -> None:
            super().__init__(useOffset=False)
            self.set_scientific(False)
            self.exponent: int | None = None
            self.decimals = 0

        def set_locs(self, locs: Any) -> None:
            super().set_locs(locs)
            ticks = [float(v) for v in locs if math.isfinite(v)]
            peak = max((abs(v) for v in ticks), default=0.0)
            self.exponent = None
            if peak and not 1e-4 <= peak < 1e6:
                # One exponent for every tick, and the decimals that keep each exact.
                self.exponent = math.floor(math.log10(peak))
                scale = 10.0**self.exponent
                ordered = sorted(ticks)
                gaps = [b - a for a, b in itertools.pairwise(ordered) if b > a]
                step = min(gaps, default=peak)
                self.decimals = next(
                    (
                        d
                        for d in range(9)
                        if all(abs(round(v / scale, d) * scale - v) <= 1e-6 * step for v in ticks)
                    ),
                    8,
                )

        def __call__(self, x: float, pos: int | None = None) -> str:
            if self.exponent is None:
                return str(super().__call__(x, pos))
            if x == 0:
                return "0"
            text = f"{x / 10.0**self.exponent:.{self.decimals}f}e{self.exponent}"
            return text.replace("-", "\u2212")

    return SelfContained()


def plain_ticks(ax: Any, axis: str = "y") -> None:
    """Tick labels of a linear axis that each say their value, in the axis's unit.

    No offset and no multiplier above the axis (a label ``(um)`` over ticks
    ``1e-6`` apart would say another unit): plain numbers from 1e-4 to 1e6
    (``0.00125``, ``587.13``), else every tick in e-notation with one exponent
    (``2.5e-11``).
    """
    target = ax.yaxis if axis == "y" else ax.xaxis
    target.set_major_formatter(_tick_formatter())


_plain = plain_ticks


def _integer_ticks(ax: Any) -> None:
    """Ticks of the x axis (cycles, trials) at whole numbers only."""
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_cycles(
    summaries: Sequence[RunSummary], labels: Sequence[str], path: Path, *, title: str
) -> Path:
    """Max and RMS tracking error per cycle of one or more runs (000 Fig. 15), log scale.

    Integer cycle ticks; the error in um (rad on a rotary axis).
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    per_run = [cycle_errors(summary) for summary in summaries]
    q = position_error(summaries[0].unit if summaries else "m")
    factor, shown = q.factor, q.unit
    for c, label, marker in zip(per_run, labels, "osd^v<>", strict=False):
        (line,) = ax.semilogy(c["cycle"], factor * c["max_m"], "-" + marker, label=f"{label}: max")
        ax.semilogy(
            c["cycle"],
            factor * c["rms_m"],
            ":" + marker,
            color=line.get_color(),
            ms=4,
            label=f"{label}: RMS",
        )
    _integer_ticks(ax)
    ax.set_xlabel(period_word(summaries))
    ax.set_ylabel(f"tracking error ({shown})")
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
    zoom_cycle: int | None,
    title: str,
) -> Path:
    """Tracking error of several runs against time, whole run and one cycle
    enlarged (000 Fig. 13(b)-(c), Fig. 15(b)-(c)); the whole run alone when
    ``zoom_cycle`` is None. The error in um (rad on a rotary axis)."""
    plt = _pyplot()
    if zoom_cycle is None:
        fig, whole = plt.subplots(1, 1, figsize=(9, 3.5))
        panels = [whole]
    else:
        fig, (whole, zoom) = plt.subplots(2, 1, figsize=(9, 6))
        panels = [whole, zoom]
    word = "cycle"
    runs = [run_series(Path(run_dir)) for run_dir in run_dirs]
    q = position_error(runs[0].summary.unit if runs else "m")
    factor, unit = q.factor, q.unit
    for series, label in zip(runs, labels, strict=True):
        word = series.summary.period_name or "cycle"
        t = series.time_s
        err = series.error_m * factor
        whole.plot(t, err, lw=0.7, label=label)
        cycle_s = series.summary.reference_period_s
        if cycle_s and zoom_cycle is not None:
            inside = (t >= (zoom_cycle - 1) * cycle_s) & (t < zoom_cycle * cycle_s)
            zoom.plot(t[inside], err[inside], lw=0.8, label=label)
    whole.set_title(title)
    if zoom_cycle is not None:
        zoom.set_title(f"{word} {zoom_cycle} enlarged")
    for ax in panels:
        _plain(ax)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"tracking error ({unit})")
        ax.grid(True, lw=0.3)
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot(run_dir: Path, *, series: RunSeries | None = None) -> list[Path]:
    """Write ``reference_position.png``, ``error.png``, for a periodic
    reference ``cycle_errors.png``, for a run with an identifier the
    :data:`IDENTIFICATION_FIGURES` and, for a run with the ``deformation``
    topic, :data:`DEFORMATION_FIGURE` into the run directory.

    ``series`` is what :func:`~servo_axis.analysis.summary.run_series` reads
    from ``run_dir``, if the caller has it already
    (:func:`~servo_axis.analysis.summary.summarise_series`).
    """
    plt = _pyplot()
    run_dir = Path(run_dir)
    if series is None:
        series = run_series(run_dir)
    summary, sig, y, lead = series.summary, series.signals, series.y_rad, series.lead_m_per_rad
    t = series.time_s
    q = position_error(summary.unit)
    err = q.shown(series.error_m)
    rotary = summary.unit == "rad"
    where = position(summary.unit)
    even = SampleGrid(control_period_s=summary.control_period_s).reference_instants(sig.step)
    figures: list[tuple[str, str, str, list[tuple[Any, Any, str, str]]]] = [
        (
            "reference_position.png",
            where.label("table angle" if rotary else "table position"),
            "reference and position",
            [
                (t, where.shown(sig.reference_rad * lead), "-", "reference r"),
                (t, where.shown(y * lead), "--", "position y"),
            ],
        ),
        (
            "error.png",
            q.label("tracking error"),
            "tracking error e = r - y" if rotary else "tracking error e = R (r - y)",
            [(t, err, "-", "all samples"), (t[even], err[even], ".", "T_r instants")],
        ),
    ]
    paths = []
    for name, ylabel, title, lines in figures:
        fig, ax = plt.subplots(figsize=(9, 4))
        for x_values, y_values, style, label in lines:
            ax.plot(x_values, y_values, style, label=label, lw=0.8, ms=2)
        _plain(ax)
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
    if summary.identification is not None:
        paths += plot_identification(
            sig.estimates,
            summary.identification,
            run_dir,
            control_period_s=summary.control_period_s,
            title=summary.scenario,
        )
    if summary.deformation is not None and sig.deformation is not None:
        paths.append(plot_deformation(series, summary.deformation, run_dir / DEFORMATION_FIGURE))
    return paths


def _stop_kind(kind: str) -> str:
    return kind.replace("_", "-")


def _valid_d_r(series: RunSeries) -> Any:
    """``d_r`` per recorded step, NaN where not valid (a line breaks there)."""
    trace = series.signals.deformation
    if trace is None:
        raise ConfigError("run: its bag has no deformation topic")
    return np.where(trace.valid, trace.d_r_m_per_rad, np.nan)


def plot_deformation(
    series: RunSeries,
    deformation: Deformation,
    path: Path,
    *,
    before_s: float = 0.1,
    after_s: float = 0.05,
) -> Path:
    """The table position and ``d_r`` before each stop of the reference (004 Fig. 11).

    One column per stop (the first :data:`DEFORMATION_COLUMNS`), over
    ``[t_stop - before_s, t_stop + after_s]``: above, the scale ``x_t``
    (mm, dashed) relative to its value at the stop; below, ``d_r`` (um/rad,
    solid) at its valid samples only, with the windows of the summary
    shaded. Each column is titled with the kind of stop and the reference's
    deceleration into it (m/s^2).

    Parameters
    ----------
    series : RunSeries
        The run (:func:`~servo_axis.analysis.summary.run_series`), with its
        ``deformation`` signals.
    deformation : Deformation
        Its summary block (the stops).
    path : Path
        The PNG to write.
    before_s, after_s : float
        The span shown around each stop, s.

    Returns
    -------
    Path
        ``path``.
    """
    plt = _pyplot()
    t = series.time_s
    mm, ms = QUANTITIES["position"], TIME_FROM_STOP
    scale_mm = mm.shown(series.signals.scale_m)
    d_r = DEFORMATION_RATIO.shown(_valid_d_r(series))
    stops = deformation.stops[:DEFORMATION_COLUMNS]
    columns = max(1, len(stops))
    fig, axes = plt.subplots(
        2, columns, figsize=(2.6 * columns + 1.0, 5), sharex="col", squeeze=False
    )
    for col, stop in enumerate(stops):
        top, bottom = axes[0, col], axes[1, col]
        inside = (t >= stop.time_s - before_s) & (t <= stop.time_s + after_s)
        rel_ms = ms.shown(t[inside] - stop.time_s)
        # Relative to the stop: the columns' moves are of different sizes.
        x_stop = float(np.interp(stop.time_s, t, scale_mm)) if t.size else 0.0
        top.plot(rel_ms, scale_mm[inside] - x_stop, "--", lw=0.9)
        bottom.plot(rel_ms, d_r[inside], "-", lw=0.9)
        for w in stop.windows:
            bottom.axvspan(ms.shown(w.start_s), ms.shown(w.end_s), color="0.85", lw=0)
        for ax in (top, bottom):
            plain_ticks(ax)
            ax.axvline(0.0, color="k", lw=0.5)
            ax.grid(True, lw=0.3)
        top.set_title(
            f"{_stop_kind(stop.kind)} at {stop.time_s:.3g} s\n{stop.deceleration_m_s2:.3g} m/s^2",
            fontsize="small",
        )
        bottom.set_xlabel(ms.label("t - t_stop"))
    if not stops:
        axes[0, 0].set_title("no stop of the reference", fontsize="small")
    axes[0, 0].set_ylabel(mm.label("x_t - x_t(stop)"))
    axes[1, 0].set_ylabel(DEFORMATION_RATIO.label("d_r"))
    more = len(deformation.stops) - len(stops)
    shown = f" (first {len(stops)} of {len(deformation.stops)} stops)" if more > 0 else ""
    fig.suptitle(
        f"{series.summary.scenario}: deformation ratio d_r before the stops (p = "
        f"{deformation.window_samples}){shown}",
        fontsize="medium",
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_reversal_detail(
    run_dir: Path, t_stop: float, path: Path, *, before_s: float = 0.15, after_s: float = 0.1
) -> Path:
    """Position, ``d_r``, control input and tracking error around one stop (004 Fig. 12).

    A 2 x 2 figure over ``[t_stop - before_s, t_stop + after_s]``: the
    reference ``R r`` and the scale ``x_t`` (mm); ``d_r`` at its valid
    samples (um/rad); the motor torque reference ``K_T u`` of the feedback
    and the feedforward torque ``K_T u_ff`` (N m, as the bag has them); the
    tracking error ``R (r - y)`` (um).
    A dotted line marks ``t_stop``.

    Parameters
    ----------
    run_dir : Path
        A single-axis run directory whose bag has the ``deformation`` topic.
    t_stop : float
        The stop, s (e.g. a ``time_s`` of the summary's ``deformation.stops``).
    path : Path
        The PNG to write.
    before_s, after_s : float
        The span shown, s.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ConfigError
        When the bag has no ``deformation`` topic, or no recorded sample lies
        in the span.
    """
    series = run_series(Path(run_dir))
    d_r = DEFORMATION_RATIO.shown(_valid_d_r(series))
    mm = QUANTITIES["position"]
    t = series.time_s
    inside = (t >= t_stop - before_s) & (t <= t_stop + after_s)
    if not np.any(inside):
        raise ConfigError(
            f"t_stop: no recorded sample within {t_stop!r} s - {before_s} s + {after_s} s"
        )
    sig, lead = series.signals, series.lead_m_per_rad
    ts = t[inside]
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
    (pos, torque), (ratio, error) = axes
    pos.plot(ts, mm.shown(lead * sig.reference_rad[inside]), "-", lw=0.9, label="reference R r")
    pos.plot(ts, mm.shown(sig.scale_m[inside]), "--", lw=0.9, label="scale x_t")
    pos.set_ylabel(mm.label("position"))
    pos.legend(fontsize="small")
    ratio.plot(ts, d_r[inside], "-", lw=0.9)
    ratio.set_ylabel(DEFORMATION_RATIO.label("d_r"))
    torque.plot(ts, sig.command_Nm[inside], "-", lw=0.9, label="K_T u (command)")
    torque.plot(ts, sig.feedforward_Nm[inside], ":", lw=0.9, label="K_T u_ff (feedforward)")
    torque.set_ylabel(QUANTITIES["torque"].label("control input, torque"))
    torque.legend(fontsize="small")
    q = position_error(series.summary.unit)
    error.plot(ts, q.shown(series.error_m[inside]), "-", lw=0.9)
    error.set_ylabel(q.label("tracking error"))
    for ax in axes.flat:
        _plain(ax)
        ax.axvline(t_stop, color="k", ls=":", lw=0.8)
        ax.grid(True, lw=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(f"{series.summary.scenario}: around the stop at {t_stop:.4g} s", fontsize="medium")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_identification(
    estimates: Sequence[EstimateData],
    identification: OnlineIdentification,
    out_dir: Path,
    *,
    control_period_s: float,
    title: str,
) -> list[Path]:
    """Write ``identification_parameters.png`` (``J, D, U, C`` against time, the
    true values dashed: 003 Fig. 7) and ``identification_pe_index.png`` (the PE
    index ``kappa`` against time, log scale when it has a value > 0: 003
    Fig. 6) into ``out_dir``; an estimate's time is ``step * T_u``."""
    plt = _pyplot()
    out_dir = Path(out_dir)
    ordered = sorted(estimates, key=lambda e: e.step)
    t = np.array([e.step for e in ordered], dtype=float) * control_period_s
    values = np.array(
        [(e.inertia_kgm2, e.damping_Nms_per_rad, e.unbalance_Nm, e.coulomb_Nm) for e in ordered],
        dtype=float,
    ).reshape(-1, 4)
    kappa = np.array([e.kappa for e in ordered], dtype=float)
    fig, axes = plt.subplots(4, 1, figsize=(8, 8), sharex=True)
    for i, (ax, label, true) in enumerate(
        zip(axes, PARAMETER_ROWS, identification.true.values(), strict=True)
    ):
        ax.plot(t, values[:, i], "-", lw=0.9, label="estimate")
        if np.isfinite(true):
            ax.axhline(true, color="k", ls="--", lw=0.8, label="true")
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize="small", loc="best")
    axes[0].set_title(f"{title}: identified parameters")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    paths = [out_dir / IDENTIFICATION_FIGURES[0]]
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.plot(t, kappa, "-", lw=0.9)
    if np.any(kappa > 0):
        ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("PE index kappa")
    ax.set_title(f"{title}: PE index (003 eq. (7))")
    ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    paths.append(out_dir / IDENTIFICATION_FIGURES[1])
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths


def plot_rmsd_bars(
    summaries: Sequence[RunSummary], labels: Sequence[str], path: Path, *, title: str
) -> Path:
    """The RMSD of each run's tracking error as a bar, its reduction against the
    baseline (:func:`~servo_axis.analysis.text.baseline_index`) written above
    it (003 Fig. 9)."""
    plt = _pyplot()
    base = baseline_index(summaries, labels)
    cuts = reductions(summaries, base)
    q = position_error(summaries[0].unit if summaries else "m")
    heights = [q.shown(s.rmsd) for s in summaries]
    fig, ax = plt.subplots(figsize=(max(4.0, 1.2 * len(summaries) + 2), 4))
    bars = ax.bar(range(len(summaries)), heights, color="tab:blue")
    for i, (bar, cut) in enumerate(zip(bars, cuts, strict=True)):
        text = "base" if i == base else ("n/a" if not np.isfinite(cut) else f"{-cut:+.1f}%")
        ax.annotate(
            text,
            (bar.get_x() + bar.get_width() / 2, bar.get_height()),
            ha="center",
            va="bottom",
            fontsize="small",
        )
    ax.set_xticks(range(len(summaries)), list(labels))
    _plain(ax)
    ax.set_ylabel(q.label("RMSD of tracking error"))
    ax.set_title(title)
    ax.grid(True, axis="y", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


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
    mm = QUANTITIES["position"]
    angle = np.arctan2(*(measured - centre).T[::-1])
    phi = np.linspace(0, 2 * np.pi, 400)
    xy.plot(
        mm.shown(centre[0] + radius * np.cos(phi)),
        mm.shown(centre[1] + radius * np.sin(phi)),
        "k:",
        lw=0.8,
        label="target",
    )
    last = max(0, (int(steps.max()) + 1) // per_cycle - 1)  # the last whole cycle
    for cycle, style in ((0, "-"), (last, "-")):
        inside = (steps >= cycle * per_cycle) & (steps < (cycle + 1) * per_cycle)
        r = radius + gain * radial[inside]
        xy.plot(
            mm.shown(centre[0] + r * np.cos(angle[inside])),
            mm.shown(centre[1] + r * np.sin(angle[inside])),
            style,
            lw=0.9,
            label=f"cycle {cycle + 1}",
        )
    xy.set_aspect("equal")
    xy.set_xlabel(mm.label(axes[0]))
    xy.set_ylabel(mm.label(axes[1]))
    xy.set_title(f"radial error x {gain:,.0f}")
    xy.legend(fontsize="small")
    rows = summary.contour.cycles
    deviations = [r.circular_deviation_m for r in rows]
    bars.bar([r.cycle for r in rows], [CONTOUR_ERROR.shown(d) for d in deviations])
    _integer_ticks(bars)
    _plain(bars)
    bars.set_xlabel("cycle")
    bars.set_ylabel(CONTOUR_ERROR.label("circular deviation"))
    bars.set_title(f"{summary.scenario}: circularity per cycle")
    bars.grid(True, lw=0.3)
    fig.tight_layout()
    path = run_dir / "contour.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
