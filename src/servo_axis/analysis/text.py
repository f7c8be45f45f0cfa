"""Summaries and comparisons of runs as plain-text tables.

Every value is shown in the unit of :mod:`servo_axis.analysis.units`, named
in its header: a tracking error in um on a linear axis and in rad on a
rotary one (a summary with ``error_unit: rad``, the plant model's
``rotary``), a contour error in um, ``d_r`` in um/rad.
Runs are compared per cycle (:func:`compare_table`, 000 Fig. 15; the last
cycle every run completed as the headline, :func:`last_cycle_table`) or,
when cycles do not apply (a rotary table, an identifier, no periodic
reference), by the RMSD of the whole run (:func:`rmsd_table`, 003 Fig. 9).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from shlex import quote

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
from servo_axis.analysis.units import (
    CONTOUR_ERROR,
    DEFORMATION_RATIO,
    QUANTITIES,
    TIME_FROM_STOP,
    Quantity,
    position_error,
)


def _row(label: str, stats: ErrorStats, q: Quantity) -> str:
    return f"  {label:<21}{q.format(stats.rms_m):>12} {q.format(stats.max_m):>14}"


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
    per window before it (ms from the stop), the mean ``d_r`` in um/rad
    (``-`` without a valid sample) and its number of valid samples.
    """
    d = deformation
    ms, ratio = TIME_FROM_STOP, DEFORMATION_RATIO
    lines = [
        f"deformation d_r   p = {d.window_samples} samples, min rotation "
        f"{d.min_rotation_rad:g} rad; {d.samples} samples, {d.valid_samples} valid, "
        f"{d.dropped} dropped",
    ]
    if not d.stops:
        return [*lines, "  no stop of the reference"]
    heads = [
        f"{f'[{ms.shown(w.start_s):g}, {ms.shown(w.end_s):g}] {ms.unit} ({ratio.unit}, n)':>30}"
        for w in d.stops[0].windows
    ]
    lines.append(f"  {'stop (s)':>9}  {'kind':<13}{'decel (m/s^2)':>14}" + "".join(heads))
    for stop in d.stops:
        cells = "".join(
            f"{ratio.format(w.mean_d_r_m_per_rad, '.4g'):>24} ({w.valid_samples:>3})"
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
            f"floor             {f['miss_pct']:.2f} % misses at {f['period_us']} us "
            f"({f.get('executor', '?')}), round trip p50 {trip.get('p50')}  p99 {trip.get('p99')}"
            f"  max {trip.get('max')}"
        )
    return lines


def format_summary(summary: RunSummary) -> str:
    """A single-axis summary as a plain-text table (errors in um, rad for a rotary table)."""
    s = summary
    te = s.tracking_error
    q = position_error(s.unit)
    mu = q.unit
    lines = [
        f"scenario          {s.scenario}  ({s.processes}, {s.time_mode})",
        *(
            ["overrides         " + " ".join(f"--set {quote(o)}" for o in s.overrides)]
            if s.overrides
            else []
        ),
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
            ["error unit        rad of table angle (rotary table); RMSD = RMS over all samples"]
            if s.unit == "rad"
            else []
        ),
        "",
        f"{'tracking error (' + mu + ')':<29}RMS            max",
        _row("all samples", te.all_samples, q),
        _row("at T_r instants", te.reference_instants, q),
    ]
    if te.after_first_cycle is not None:
        a = te.after_first_cycle
        name = s.period_name or "cycle"
        lines += [
            _row(f"after {name} 1", a.all_samples, q),
            _row("... at T_r instants", a.reference_instants, q),
            "",
            f"{name:<5}   {'RMS (' + mu + ')':<15}{'max (' + mu + ')':<15}max at T_r ({mu})",
        ]
        for c in te.cycles:
            lines.append(
                f"{c.cycle:>5} {q.format(c.rms_m):>12} {q.format(c.max_m):>14} "
                f"{q.format(c.reference_instants.max_m):>18}"
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
        q, mm = CONTOUR_ERROR, QUANTITIES["circle_radius"]
        um = q.unit
        lines += [
            "",
            f"== contour: circle of radius {mm.format(c.radius_m, '.3f')} {mm.unit} "
            f"(target off the circle by {q.format(c.target_radial_deviation_m)} {um})",
            f"circular deviation {q.format(c.circular_deviation_m)} {um}, "
            f"max radial error {q.format(c.max_radial_m)} {um}",
            f"cycle   circular deviation ({um})   max radial error ({um})",
        ]
        for row in c.cycles:
            lines.append(
                f"{row.cycle:>5} {q.format(row.circular_deviation_m):>25} "
                f"{q.format(row.max_radial_m):>23}"
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


def _counts(summaries: Sequence[RunSummary]) -> list[int]:
    """The last complete cycle (or trial) of each run, from 1 (0: none)."""
    return [max((c.cycle for c in s.tracking_error.cycles), default=0) for s in summaries]


def last_common_cycle(summaries: Sequence[RunSummary]) -> int:
    """The last cycle every run completed (from 1); 0 when no cycle is complete in every run.

    The cycle ``compare --error-out`` enlarges unless told.
    """
    if not summaries:
        return 0
    common = set.intersection(*({c.cycle for c in s.tracking_error.cycles} for s in summaries))
    return max(common, default=0)


def _unit_of(summaries: Sequence[RunSummary]) -> Quantity:
    """The tracking error's quantity of runs that share one unit.

    Raises
    ------
    ValueError
        When the runs' errors are in different units (m and rad).
    """
    units = sorted({s.unit for s in summaries})
    if len(units) > 1:
        raise ValueError(f"runs with errors in different units ({', '.join(units)})")
    return position_error(units[0] if units else "m")


def compare_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> str:
    """Max and RMS tracking error per cycle of several runs side by side (000 Fig. 15).

    Two blocks, ``max tracking error per cycle (um)`` and ``RMS ...`` (rad on
    a rotary axis), a row per cycle and a column per run (6 significant
    digits); after each run but the first, its reduction against the first
    run in the same cycle, ``100 (1 - run / first)`` in % (2 decimals, ``n/a``
    against a base below :data:`TINY_BASE`, ``-`` where the first run has no
    such cycle). Columns are two spaces apart.
    """
    q = _unit_of(summaries)
    per_run = [
        {int(n): (m, r) for n, m, r in zip(c["cycle"], c["max_m"], c["rms_m"], strict=True)}
        for c in (cycle_errors(s) for s in summaries)
    ]
    cycles = sorted(set().union(*per_run)) if per_run else []
    width = max(12, *(len(label) for label in labels))
    cut = len("reduction (%)")
    word = period_word(summaries)
    head = f"{word:<5}" + "".join(
        f"{GAP}{x:>{width}}" + (f"{GAP}{'reduction (%)':>{cut}}" if i else "")
        for i, x in enumerate(labels)
    )
    lines: list[str] = []
    for title, key in (("max", 0), ("RMS", 1)):
        if lines:
            lines.append("")
        lines += [
            f"{q.label(f'{title} tracking error per {word}')}; reduction (%) = "
            f"100 (1 - run / {labels[0]}) in the same {word}",
            head,
        ]
        for k in cycles:
            base = per_run[0][k][key] if k in per_run[0] else None
            cells = []
            for i, c in enumerate(per_run):
                value = c[k][key] if k in c else None
                cells.append(f"{GAP}{'' if value is None else q.format(value):>{width}}")
                if i:
                    if value is None:
                        cut_text = ""
                    else:  # "-": the first run has no such cycle to compare with
                        cut_text = "-" if base is None else _cut(reduction(value, base))
                    cells.append(f"{GAP}{cut_text:>{cut}}")
            lines.append(f"{k:>5}" + "".join(cells).rstrip())
    return "\n".join(lines)


def last_cycle_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> str:
    """The headline of a per-cycle comparison: each run's last cycle against the first run's.

    What learning and compensation leave once they have acted: the max and
    RMS tracking error (um; rad on a rotary axis) of each run's last complete
    cycle and its reduction against the first run's last complete cycle,
    ``100 (1 - run / first)`` in % (``base`` for the first, ``n/a`` against a
    base below :data:`TINY_BASE`). The header names the cycles compared (one
    number when every run's last cycle is the same); a run without a complete
    cycle shows ``-``. Columns are two spaces apart.
    """
    q = _unit_of(summaries)
    word = period_word(summaries)
    counts = _counts(summaries)
    rows = [
        next((c for c in s.tracking_error.cycles if c.cycle == n), None)
        for s, n in zip(summaries, counts, strict=True)
    ]
    if len(set(counts)) == 1:
        which = f"{word} {counts[0]} of every run" if counts[0] else f"no complete {word}"
    else:
        which = ", ".join(
            f"{label} {word} {n}" if n else f"{label} none"
            for label, n in zip(labels, counts, strict=True)
        )
    width = max(12, *(len(label) for label in labels))
    cut = len("reduction (%)")
    lines = [
        f"last {word} of each run ({which}); reduction (%) = 100 (1 - run / {labels[0]}), "
        f"each against the last {word} of {labels[0]}",
        f"{'run':<{width}}{GAP}{word:>5}{GAP}{'max (' + q.unit + ')':>12}{GAP}"
        f"{'reduction (%)':>{cut}}{GAP}{'RMS (' + q.unit + ')':>12}{GAP}{'reduction (%)':>{cut}}",
    ]
    base = rows[0]
    for i, (label, row) in enumerate(zip(labels, rows, strict=True)):
        peak, rms = (row.max_m, row.rms_m) if row is not None else (math.nan, math.nan)
        if i == 0:
            peak_cut = rms_cut = "base"
        else:
            peak_cut = _cut(reduction(peak, base.max_m if base else math.nan))
            rms_cut = _cut(reduction(rms, base.rms_m if base else math.nan))
        number = str(row.cycle) if row is not None else "-"
        lines.append(
            f"{label:<{width}}{GAP}{number:>5}{GAP}{q.format(peak):>12}{GAP}{peak_cut:>{cut}}"
            f"{GAP}{q.format(rms):>12}{GAP}{rms_cut:>{cut}}"
        )
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

    One row per run: label, RMSD (um, or rad on a rotary axis; 6 significant digits), reduction
    (%, 2 decimals; ``base`` for the baseline, ``n/a`` against a baseline
    below :data:`TINY_BASE`) and, if any run identified
    parameters, ``J/true``, ``D/true``, ``U/true``, ``C/true`` (``-`` for a
    run without).

    Raises
    ------
    ValueError
        When the runs' errors are in different units (m and rad).
    """
    q = _unit_of(summaries)
    mu = q.unit
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
        row = f"{label:<{width}}{GAP}{q.format(s.rmsd):>14}{GAP}{shown:>13}"
        if ident:
            ratios = s.identification.final_ratio.values() if s.identification else (None,) * 4
            row += "".join(f"{GAP}{_g(r, '.5g'):>8}" for r in ratios)
        lines.append(row)
    return "\n".join(lines)
