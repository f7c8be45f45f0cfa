"""The identification report: Bode measured vs fitted with coherence, friction, table, validation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from servo_axis.identify.driver import Identification, well_measured

_UNITS = {"encoder": "rad/(N m)", "scale": "m/(N m)"}


def table(ident: Identification) -> str:
    """The parameter table as text (one row per key)."""
    rows = [f"{'key':<32} {'value':>14} {'std':>11}  source"]
    for k in ident.keys:
        std = "-" if k.std != k.std else f"{k.std:.3g}"
        rows.append(f"{k.key:<32} {k.value:>14.6g} {std:>11}  {k.source}")
    return "\n".join(rows)


def summary_text(ident: Identification) -> str:
    """Table, Bode errors, validation and notes, as the command prints them."""
    out = [table(ident), ""]
    for sensor, (db, deg, up_to) in ident.bode.items():
        out.append(
            f"Bode {sensor}: fitted vs measured within {db:.2f} dB and {deg:.2f} deg up to "
            f"{up_to:.4g} Hz (lines of coherence >= 0.9 and std <= 2 %)"
        )
    v = ident.validation
    if v is not None:
        out.append(
            f"validation on {v.source}: NRMSE position {v.nrmse_position:.3g}, tracking error "
            f"{v.nrmse_error:.3g}; RMS tracking error measured {v.rms_error_measured:.4g} rad, "
            f"fitted {v.rms_error_fitted:.4g} rad (ratio {v.rms_error_fitted / v.rms_error_measured:.3f})"
        )
    for note in ident.notes:
        out.append(f"note: {note}")
    return "\n".join(out)


def write_report(folder: Path, ident: Identification) -> list[Path]:
    """Figures and ``report.md`` into ``folder`` (made if missing); the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for sensor, frf in ident.responses.items():
        fig, ax = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
        f = frf.frequency_hz
        good = well_measured(frf)
        ax[0].loglog(f, np.abs(frf.response), ".", ms=3, color="0.6", label="measured")
        ax[0].loglog(
            f[good], np.abs(frf.response[good]), ".", ms=3, color="C0", label="measured (compared)"
        )
        ph = np.degrees(np.unwrap(np.angle(frf.response)))
        ax[1].semilogx(f, ph, ".", ms=3, color="0.6")
        ax[1].semilogx(f[good], ph[good], ".", ms=3, color="C0")
        if sensor in ident.fitted:
            m = ident.fitted[sensor]
            ax[0].loglog(f, np.abs(m), "-", color="C3", label="fitted model")
            ax[1].semilogx(f, np.degrees(np.unwrap(np.angle(m))), "-", color="C3")
        ax[2].semilogx(f, frf.coherence, "-", color="C2")
        ax[0].set_ylabel(f"|P| {_UNITS.get(sensor, '')}")
        ax[1].set_ylabel("phase (deg)")
        ax[2].set_ylabel("coherence")
        ax[2].set_xlabel("frequency (Hz)")
        ax[2].set_ylim(0, 1.05)
        ax[0].legend()
        db, deg, up_to = ident.bode.get(sensor, (math.nan, math.nan, math.nan))
        ax[0].set_title(
            f"{ident.model}: torque -> {sensor}; fitted within {db:.2f} dB, {deg:.2f} deg up to {up_to:.4g} Hz"
        )
        for a in ax:
            a.grid(True, which="both", alpha=0.3)
        path = folder / f"bode_{sensor}.png"
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    if ident.friction is not None:
        pos, meas, model = ident.friction
        fig, ax = plt.subplots(figsize=(7, 4.5))
        ax.plot(pos * 1e6, meas, ".", ms=2, color="C0", label="measured K_T i - J a_r - D v_r")
        ax.plot(pos * 1e6, model, "-", color="C3", label="fitted friction law")
        ax.set_xlabel("reference position (um)")
        ax.set_ylabel("friction torque (N m)")
        ax.legend()
        ax.grid(True, alpha=0.3)
        path = folder / "friction.png"
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    v = ident.validation
    if v is not None:
        fig, ax = plt.subplots(figsize=(8, 4.5))
        ax.plot(v.time_s, v.error_measured, "-", color="C0", label="measured axis")
        ax.plot(v.time_s, v.error_fitted, "--", color="C3", label="fitted scenario")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("tracking error (rad at the motor)")
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
