"""Summaries and comparisons of runs as plain-text tables.

Errors are shown in um, or in urad for a rotary table (a summary with
``error_unit: rad``, the plant model's ``rotary``).
Runs are compared per cycle (:func:`compare_table`, 000 Fig. 15) or, when
cycles do not apply (a rotary table, an identifier, no periodic reference),
by the RMSD of the whole run (:func:`rmsd_table`, 003 Fig. 9).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from servo_axis.analysis.health import RunHealth
from servo_axis.analysis.summary import (
    AxesSummary,
    Deformation,
    ErrorStats,
    Identification,
    Realtime,
    RunSummary,
    cycle_errors,
)

#: The unit errors are shown in, per unit of the summary (both scaled by 1e6).
MICRO: dict[str, str] = {"m": "um", "rad": "urad"}


def micro(unit: str) -> str:
    """The micro unit errors in ``unit`` are shown in: ``um`` for m, ``urad`` for rad."""
    return MICRO.get(unit, f"u{unit}")


def _um(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x * 1e6:.6g}"


def _row(label: str, stats: ErrorStats) -> str:
    return f"  {label:<21}{_um(stats.rms_m):>12} {_um(stats.max_m):>14}"


def _g(x: float | None, spec: str = ".6g") -> str:
    return "-" if x is None or not math.isfinite(x) else format(x, spec)


#: A base below this (m or rad) gives no reduction (``n/a``): 1 - x / 0 means nothing.
TINY_BASE = 1e-12
#: Between two columns of a comparison: a wider value than its column cannot run into the next.
GAP = "  "


def reduction(value: float, base: float) -> float:
    """``100 (1 - value / base)``, %; NaN when ``base`` is below :data:`TINY_BASE` or not finite."""
    if not math.isfinite(base) or abs(base) < TINY_BASE:
        return math.nan
    return 100.0 * (1.0 - value / base)


def _cut(value: float) -> str:
    """A reduction as the tables show it: 2 decimals, ``n/a`` when there is none."""
    return "n/a" if not math.isfinite(value) else f"{value:.2f}"


#: Row labels of the identified parameters, in :data:`~servo_axis.analysis.summary.IDENTIFIED` order.
PARAMETER_ROWS: tuple[str, ...] = ("J (kg m^2)", "D (N m s/rad)", "U (N m)", "C (N m)")


def identification_lines(ident: Identification) -> list[str]:
    """The identification of a run (003): counts, then a row per parameter."""
    steps = (
        f" (steps {ident.first_step} to {ident.last_step})" if ident.first_step is not None else ""
    )
    window = "run" if ident.last_period_s is None else f"last {ident.last_period_s:g} s"
    lines = [
        f"identification    {ident.estimates} estimates{steps}, {ident.repeated} repeated, "
        f"{ident.dropped} dropped; final kappa {_g(ident.final_kappa, '.4g')}",
        f"  {'parameter':<15}{'final':>13}{'true':>13}{'final/true':>12}"
        f"{'p2p, ' + window:>20}{'updates':>9}",
    ]
    columns = zip(
        PARAMETER_ROWS,
        ident.final.values(),
        ident.true.values(),
        ident.final_ratio.values(),
        ident.last_period_p2p.values(),
        (
            ident.updates.inertia_kgm2,
            ident.updates.damping_Nms_per_rad,
            ident.updates.unbalance_Nm,
            ident.updates.coulomb_Nm,
        ),
        strict=True,
    )
    for label, final, true, ratio, p2p, updates in columns:
        lines.append(
            f"  {label:<15}{_g(final):>13}{_g(true):>13}{_g(ratio, '.5g'):>12}"
            f"{_g(p2p, '.4g'):>20}{updates:>9}"
        )
    return lines


def deformation_lines(deformation: Deformation) -> list[str]:
    """The deformation ratio of a run (004 Sect. III-C): settings, counts, then a row per stop.

    Each row: the stop's time (s), kind, deceleration into it (m/s^2) and,
    per window before it, the mean ``d_r`` in um/rad (``-`` without a valid
    sample) and its number of valid samples.
    """
    d = deformation
    lines = [
        f"deformation d_r   p = {d.window_samples} samples, min rotation "
        f"{d.min_rotation_rad:g} rad; {d.samples} samples, {d.valid_samples} valid, "
        f"{d.dropped} dropped",
    ]
    if not d.stops:
        return [*lines, "  no stop of the reference"]
    heads = [
        f"{f'[{1e3 * w.start_s:g}, {1e3 * w.end_s:g}] ms (um/rad, n)':>30}"
        for w in d.stops[0].windows
    ]
    lines.append(f"  {'stop (s)':>9}  {'kind':<13}{'decel (m/s^2)':>14}" + "".join(heads))
    for stop in d.stops:
        cells = "".join(
            f"{_g(None if w.mean_d_r_m_per_rad is None else 1e6 * w.mean_d_r_m_per_rad, '.4g'):>24}"
            f" ({w.valid_samples:>3})"
            for w in stop.windows
        )
        lines.append(
            f"  {stop.time_s:>9.4f}  {stop.kind:<13}{_g(stop.deceleration_m_s2, '.4g'):>14}{cells}"
        )
    return lines


def _around(startup_s: float | None, finish_s: float | None) -> str:
    """What the run's wall time leaves out: `` (steps only; start-up 0.81 s, end 0.15 s)``."""
    if startup_s is None or finish_s is None:
        return ""
    return f" (steps only; start-up {startup_s:.2f} s, end {finish_s:.2f} s)"


def _wall_time_line(s: RunSummary) -> str:
    """The wall time and rate; not known for a summary made after the run (``bag recover``)."""
    if math.isnan(s.wall_time_s):
        return "wall time         not known (this summary was made after the run, from its bag)"
    return (
        f"wall time         {s.wall_time_s:.2f} s  ->  {s.steps_per_s:,.0f} steps/s, "
        f"{s.realtime_factor:.2f}x real time" + _around(s.startup_s, s.finish_s)
    )


def _health_lines(health: RunHealth | None, realtime: bool = False) -> list[str]:
    """The run's health: outcome, determinism, rejected messages, strangers, deaths."""
    if health is None:
        return []
    if realtime:  # never deterministic: its misses depend on the host
        verdict = "realtime, not deterministic" + (
            "" if health.exit_code == 0 else " and not clean"
        )
    else:
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


def _late(d: dict[str, float] | None) -> str:
    return "none" if d is None else f"p50 {d['p50']:.0f}  p99 {d['p99']:.0f}  max {d['max']:.0f}"


def _realtime_lines(rt: Realtime | None) -> list[str]:
    """A realtime run's clock: deadline misses, lateness (us), the host's floor if given."""
    if rt is None:
        return []
    period_us = rt.period_ns / 1000
    lines = [
        f"deadline misses   {rt.misses} of {rt.ticks} ticks ({100 * rt.miss_fraction:.2f} %), "
        f"{rt.commands_missing} command(s) never came; clock rate {rt.timer_rate:.4f}x",
        f"tick late (us)    {_late(rt.tick_late_us)}",
        f"command late (us) {_late(rt.command_late_us)}  (after its state's tick; a miss: > "
        f"{period_us:g})"
        if rt.setpoints is None
        else f"command late (us) {_late(rt.command_late_us)}  (after the newest state's tick)",
    ]
    if rt.setpoints is not None:
        sp = rt.setpoints
        lines.append(
            f"set-points        {sp['received']} received every {sp['period_ns'] / 1000:g} us "
            f"(a miss: none for 1.5 of that), {sp['unset']} NaN (no command yet, not applied), "
            f"{sp['quiet_ticks']} tick(s) held on a silent commander"
        )
    if rt.references_held is not None or rt.late_estimates is not None:
        held, estimates, corrections = (
            "-" if n is None else str(n)
            for n in (rt.references_held, rt.late_estimates, rt.late_corrections)
        )
        lines.append(
            f"late inputs       {held} state(s) answered with the last reference; "
            f"applied late: {estimates} estimate(s), {corrections} correction(s)"
        )
    if rt.scheduling is not None:
        sched = rt.scheduling
        how = (
            f"SCHED_FIFO priority {sched['priority']}"
            if sched["policy"] == "fifo"
            else "default scheduler"
            + (f" (refused: {sched['refused']})" if "refused" in sched else "")
        )
        lines.append(f"scheduling        {how} (plant and feedback)")
    if rt.floor is not None:
        f = rt.floor
        trip = f.get("round_trip_us") or {}
        lines.append(
            f"floor (rt_floor)  {f['miss_pct']:.2f} % misses at {f['period_us']} us "
            f"({f.get('executor', '?')}), round trip p50 {trip.get('p50')}  p99 {trip.get('p99')}"
            f"  max {trip.get('max')}"
        )
    return lines


def format_summary(summary: RunSummary) -> str:
    """A single-axis summary as a plain-text table (errors in um, urad for a rotary table)."""
    s = summary
    te = s.tracking_error
    mu = micro(s.unit)
    lines = [
        f"scenario          {s.scenario}  ({s.processes}, {s.time_mode})",
        f"steps             {s.steps}  ({s.sim_time_s:.3f} s simulated)",
        _wall_time_line(s),
        "messages          " + ", ".join(f"{k}: {v}" for k, v in sorted(s.message_counts.items())),
        "faults            "
        + (", ".join(f"{f.name} at step {f.step}" for f in s.faults) or "none"),
        *_health_lines(s.health, s.time_mode == "realtime"),
        *_realtime_lines(s.realtime),
        *(
            [
                f"ILC eq. (7)       max |Q(1 - S L P)| = {s.ilc_convergence['nominal']:.4g} "
                f"(nominal), {s.ilc_convergence['plant']:.4g} (plant), "
                f"Nq = {s.ilc_convergence['nq']:g}"
            ]
            if s.ilc_convergence
            else []
        ),
        *(
            [
                f"error unit        rad of table angle (rotary table), shown in {mu}; "
                "RMSD = RMS over all samples"
            ]
            if s.unit == "rad"
            else []
        ),
        "",
        f"{'tracking error (' + mu + ')':<29}RMS            max",
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
            f"{name:<5}   {'RMS (' + mu + ')':<15}{'max (' + mu + ')':<15}max at T_r ({mu})",
        ]
        for c in te.cycles:
            lines.append(
                f"{c.cycle:>5} {_um(c.rms_m):>12} {_um(c.max_m):>14} "
                f"{_um(c.reference_instants.max_m):>18}"
            )
    if s.identification is not None:
        lines += ["", *identification_lines(s.identification)]
    if s.deformation is not None:
        lines += ["", *deformation_lines(s.deformation)]
    return "\n".join(lines)


def format_axes_summary(summary: AxesSummary) -> str:
    """A multi-axis summary as text: each axis, then the contour per cycle (um)."""
    lines = [
        f"scenario          {summary.scenario}  (axes {', '.join(summary.axes)})",
        *_health_lines(
            summary.health, any(a.time_mode == "realtime" for a in summary.axes.values())
        ),
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
    width = max(12, *(len(label) for label in labels))
    word = period_word(summaries)
    lines: list[str] = []
    for title, key in (("max", "max_m"), ("RMS", "rms_m")):
        if lines:
            lines.append("")
        lines += [
            f"{title} error per {word} (um)",
            f"{word:<5}" + "".join(f"{GAP}{x:>{width}}" for x in labels),
        ]
        for k in range(n):
            cells = [
                f"{GAP}{1e6 * c[key][k]:>{width}.6g}" if k < len(c[key]) else GAP + " " * width
                for c in per_run
            ]
            lines.append(f"{k + 1:>5}" + "".join(cells).rstrip())
    return "\n".join(lines)


def max_error_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> str:
    """The max tracking error after the first cycle of each run and its reduction (004 Sect. V).

    After the first cycle, so that the start from rest does not count: what
    is left are the periodic reversals. The reduction is
    ``100 (1 - max / max_base)`` against the first run (the conventional
    method: ``compare runs/fast_reversal_gms runs/fast_reversal_sigmoid``),
    ``n/a`` against a base below :data:`TINY_BASE`. Runs without a complete
    first cycle use all their samples. Columns are two spaces apart.
    """
    maxima = [
        (s.tracking_error.after_first_cycle or s.tracking_error).all_samples.max_m
        for s in summaries
    ]
    width = max(12, *(len(label) for label in labels))
    lines = [
        f"max tracking error after cycle 1 (um); reduction against {labels[0]}",
        f"{'run':<{width}}{GAP}{'max (um)':>12}{GAP}{'reduction (%)':>13}",
    ]
    for i, (label, peak) in enumerate(zip(labels, maxima, strict=True)):
        cut = "base" if i == 0 else _cut(reduction(peak, maxima[0]))
        lines.append(f"{label:<{width}}{GAP}{_um(peak):>12}{GAP}{cut:>13}")
    return "\n".join(lines)


def rmsd_applies(summaries: Sequence[RunSummary]) -> bool:
    """Whether runs compare by RMSD (:func:`rmsd_table`) rather than per cycle.

    True when a run is on a rotary table or has an identifier (paper 003),
    or when no run has a complete cycle (cycles do not apply).
    """
    return any(s.unit != "m" or s.identification is not None for s in summaries) or not any(
        s.tracking_error.cycles for s in summaries
    )


def baseline_index(summaries: Sequence[RunSummary], labels: Sequence[str]) -> int:
    """The run the others are compared with: the one labelled ``pid``, else the
    first whose scenario is ``pid`` or ends in ``_pid``, else the first."""
    for i, label in enumerate(labels):
        if label == "pid":
            return i
    for i, s in enumerate(summaries):
        if s.scenario == "pid" or s.scenario.endswith("_pid"):
            return i
    return 0


def reductions(summaries: Sequence[RunSummary], base: int) -> list[float]:
    """Per run, ``100 (1 - RMSD / RMSD_base)``: how much lower its RMSD is, % (NaN: no base)."""
    ref = summaries[base].rmsd
    return [reduction(s.rmsd, ref) for s in summaries]


def rmsd_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> str:
    """RMSD of the tracking error over each whole run and its reduction against the
    baseline (:func:`baseline_index`), plus the final estimate / true value of
    each identified parameter when a run has them (003 Figs. 7, 9).

    One row per run: label, RMSD (um or urad, 6 significant digits), reduction
    (%, 2 decimals; ``base`` for the baseline, ``n/a`` against a baseline
    below :data:`TINY_BASE`) and, if any run identified
    parameters, ``J/true``, ``D/true``, ``U/true``, ``C/true`` (``-`` for a
    run without).

    Raises
    ------
    ValueError
        When the runs' errors are in different units (m and rad).
    """
    units = {s.unit for s in summaries}
    if len(units) > 1:
        raise ValueError(f"runs with errors in different units ({', '.join(sorted(units))})")
    mu = micro(units.pop() if units else "m")
    base = baseline_index(summaries, labels)
    width = max(12, *(len(label) for label in labels))
    ident = any(s.identification is not None for s in summaries)
    names = ("J", "D", "U", "C")
    lines = [
        f"RMSD of the tracking error over the whole run ({mu}); reduction against {labels[base]}",
        f"{'run':<{width}}{GAP}{'RMSD (' + mu + ')':>14}{GAP}{'reduction (%)':>13}"
        + ("".join(f"{GAP}{n + '/true':>8}" for n in names) if ident else ""),
    ]
    for i, (s, label, cut) in enumerate(
        zip(summaries, labels, reductions(summaries, base), strict=True)
    ):
        shown = "base" if i == base else _cut(cut)
        row = f"{label:<{width}}{GAP}{_um(s.rmsd):>14}{GAP}{shown:>13}"
        if ident:
            ratios = s.identification.final_ratio.values() if s.identification else (None,) * 4
            row += "".join(f"{GAP}{_g(r, '.5g'):>8}" for r in ratios)
        lines.append(row)
    return "\n".join(lines)
