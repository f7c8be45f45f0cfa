"""The identification report: Bode measured vs fitted, friction, table, validation.

Every quantity in the unit of :mod:`servo_axis.analysis.units`: the
frequency responses' magnitude in dB (re 1 rad/(N m) at the encoder, 1
m/(N m) at the scale) and phase in degrees, each measured line with its
error bar (one standard deviation of the periods' spread, to first order:
``20 log10(e) std / |P|`` dB and ``std / |P|`` rad), the residual of the fit
against it, and the coherence; the validation's tracking error at the table
in um (rad on a rotary table), as a run's summary has it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.analysis.units import (
    DISPLACEMENT,
    FRF_MAGNITUDE,
    FRF_PHASE,
    QUANTITIES,
    position_error,
)
from servo_axis.identify.driver import BodeFit, Identification, well_measured

#: What each sensor's response is, torque to ...: its magnitude in dB is re 1 of this unit.
RESPONSE_UNITS = {"encoder": "rad/(N m)", "scale": "m/(N m)"}

#: dB per unit of relative error, to first order: ``20 / ln 10``.
DB_PER_RELATIVE = 20.0 / math.log(10.0)


def table(ident: Identification) -> str:
    """The parameter table as text (one row per key, in the key's own unit)."""
    rows = [f"{'key':<32} {'value':>14} {'std':>11}  source"]
    for k in ident.keys:
        std = "-" if k.std != k.std else f"{k.std:.3g}"
        rows.append(f"{k.key:<32} {k.value:>14.6g} {std:>11}  {k.source}")
    return "\n".join(rows)


def bode_claim(fit: BodeFit) -> str:
    """The accuracy claim of a fit, with the band it covers: ``within 0.51 dB and ...``."""
    if fit.lines == 0:
        return f"no well-measured line between {fit.from_hz:.4g} and {fit.to_hz:.4g} Hz"
    return (
        f"within {fit.db:.2f} dB and {fit.deg:.2f} deg from {fit.from_hz:.4g} to "
        f"{fit.to_hz:.4g} Hz ({fit.lines} lines of coherence >= 0.9 and std <= 2 %)"
    )


def summary_text(ident: Identification) -> str:
    """Table, Bode errors, validation and notes, as the command prints them."""
    out = [table(ident), ""]
    for sensor, fit in ident.bode.items():
        out.append(f"Bode {sensor}: fitted vs measured {bode_claim(fit)}")
    v = ident.validation
    if v is not None:
        q = position_error(v.unit)
        out.append(
            f"validation on {v.source}: NRMSE position {v.nrmse_position:.3g}, tracking error "
            f"{v.nrmse_error:.3g}; RMS tracking error measured "
            f"{q.format(v.rms_error_measured, '.4g')} {q.unit}, fitted "
            f"{q.format(v.rms_error_fitted, '.4g')} {q.unit} "
            f"(ratio {v.rms_error_fitted / v.rms_error_measured:.3f})"
        )
    for note in ident.notes:
        out.append(f"note: {note}")
    return "\n".join(out)


def bode_figure(ident: Identification, sensor: str) -> Any:
    """The Bode figure of one sensor's response (a matplotlib figure; the caller closes it).

    Five panels sharing the frequency axis (Hz, log): the magnitude (dB)
    and the phase (deg) measured, each line with its error bar, grey where
    the line is not compared (coherence below 0.9 or a spread above 2 %),
    and the fitted model; the residual of the fit against each line,
    ``20 log10 |P_fit / P|`` (dB) and ``angle(P_fit / P)`` (deg), with the
    line's error bar, so that a misfit larger than the measurement's own
    uncertainty shows; the coherence. The band of the accuracy claim is
    shaded in every panel.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from servo_axis.analysis.plots import plain_ticks

    frf = ident.responses[sensor]
    f = frf.frequency_hz
    good = well_measured(frf)
    measured = frf.response
    relative = np.where(np.abs(measured) > 0, frf.std / np.abs(measured), np.nan)
    err_db = DB_PER_RELATIVE * relative
    err_deg = FRF_PHASE.shown(relative)
    level = FRF_MAGNITUDE.shown(measured)
    fitted = ident.fitted.get(sensor)
    if fitted is not None:
        phase_fit = FRF_PHASE.shown(np.unwrap(np.angle(fitted)))
        residual = fitted / measured
        # The measured phase on the fitted one's branch: the two curves cannot be 360 deg apart.
        phase = phase_fit - FRF_PHASE.shown(np.angle(residual))
    else:
        phase = FRF_PHASE.shown(np.unwrap(np.angle(measured)))
    fig, ax = plt.subplots(5, 1, figsize=(8, 12), sharex=True)
    mag, ph, res_db, res_deg, coh = ax
    for panel, values, errors in ((mag, level, err_db), (ph, phase, err_deg)):
        for keep, colour, label in (
            (~good, "0.6", "measured"),
            (good, "C0", "measured (compared)"),
        ):
            panel.errorbar(
                f[keep], values[keep], yerr=errors[keep], fmt=".", ms=3, lw=0.6,
                color=colour, ecolor=colour, label=label,
            )  # fmt: skip
    if fitted is not None:
        mag.plot(f, FRF_MAGNITUDE.shown(fitted), "-", color="C3", label="fitted model", zorder=3)
        ph.plot(f, phase_fit, "-", color="C3", label="fitted model", zorder=3)
        for panel, values, errors in (
            (res_db, FRF_MAGNITUDE.shown(residual), err_db),
            (res_deg, FRF_PHASE.shown(np.angle(residual)), err_deg),
        ):
            for keep, colour in ((~good, "0.6"), (good, "C0")):
                panel.errorbar(
                    f[keep], values[keep], yerr=errors[keep], fmt=".", ms=3, lw=0.6,
                    color=colour, ecolor=colour,
                )  # fmt: skip
            panel.axhline(0.0, color="k", lw=0.6)
    # The view: the lines of coherence >= 0.9 with their error bars; a line with less is
    # clipped, its spread (of order its value) would hide every other one.
    from servo_axis.core.sysid.fit import MIN_COHERENCE

    coherent = (frf.coherence >= MIN_COHERENCE) & np.isfinite(relative)
    views = [(mag, level, err_db), (ph, phase, err_deg)]
    if fitted is not None:
        views += [
            (res_db, FRF_MAGNITUDE.shown(residual), err_db),
            (res_deg, FRF_PHASE.shown(np.angle(residual)), err_deg),
        ]
    for panel, values, errors in views:
        if coherent.any():
            lo = float(np.min(values[coherent] - errors[coherent]))
            hi = float(np.max(values[coherent] + errors[coherent]))
            pad = 0.08 * (hi - lo) or 1.0
            panel.set_ylim(lo - pad, hi + pad)
    coh.semilogx(f, frf.coherence, "-", color="C2")
    coh.set_ylim(0, 1.05)
    unit = RESPONSE_UNITS.get(sensor, "1")
    mag.set_ylabel(f"|P| ({FRF_MAGNITUDE.unit} re 1 {unit})")
    ph.set_ylabel(FRF_PHASE.label("phase"))
    res_db.set_ylabel(f"fit / measured ({FRF_MAGNITUDE.unit})")
    res_deg.set_ylabel(FRF_PHASE.label("fit - measured"))
    coh.set_ylabel("coherence")
    coh.set_xlabel(QUANTITIES["frequency"].label("frequency"))
    fit = ident.bode.get(sensor)
    for a in ax:
        a.set_xscale("log")
        a.grid(True, which="both", alpha=0.3)
        if fit is not None and fit.lines:
            a.axvspan(fit.from_hz, fit.to_hz, color="C0", alpha=0.05, lw=0)
    for a in (mag, ph, res_db, res_deg):
        plain_ticks(a)
    mag.legend(fontsize="small")
    claim = bode_claim(fit).split(" (")[0] if fit is not None else "not compared"
    mag.set_title(f"{ident.model}: torque -> {sensor}; fitted {claim}", fontsize="medium")
    fig.tight_layout()
    return fig


def write_report(folder: Path, ident: Identification) -> list[Path]:
    """Figures and ``report.md`` into ``folder`` (made if missing); the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for sensor in ident.responses:
        fig = bode_figure(ident, sensor)
        path = folder / f"bode_{sensor}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    if ident.friction is not None:
        pos, meas, model = ident.friction
        torque = QUANTITIES["torque"]
        fig, ax = plt.subplots(figsize=(7, 4.5))
        ax.plot(
            DISPLACEMENT.shown(pos),
            meas,
            ".",
            ms=2,
            color="C0",
            label="measured K_T i - J a_r - D v_r",
        )
        ax.plot(DISPLACEMENT.shown(pos), model, "-", color="C3", label="fitted friction law")
        ax.set_xlabel(DISPLACEMENT.label("reference position"))
        ax.set_ylabel(torque.label("friction torque"))
        ax.legend()
        ax.grid(True, alpha=0.3)
        path = folder / "friction.png"
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    v = ident.validation
    if v is not None:
        q = position_error(v.unit)
        fig, ax = plt.subplots(figsize=(8, 4.5))
        ax.plot(v.time_s, q.shown(v.error_measured), "-", color="C0", label="measured axis")
        ax.plot(v.time_s, q.shown(v.error_fitted), "--", color="C3", label="fitted scenario")
        ax.set_xlabel(QUANTITIES["time"].label())
        ax.set_ylabel(q.label("tracking error"))
        ax.set_title(f"held-out run: NRMSE of the error {v.nrmse_error:.3g}")
        ax.legend()
        ax.grid(True, alpha=0.3)
        path = folder / "validation.png"
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    md = folder / "report.md"
    figures = "\n".join(f"![{p.stem}]({p.name})" for p in written)
    md.write_text(
        f"# {ident.model}: identification report\n\n```\n{summary_text(ident)}\n```\n\n{figures}\n"
    )
    written.append(md)
    return written
