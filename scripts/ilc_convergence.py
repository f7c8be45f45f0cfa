#!/usr/bin/env python3
"""Convergence condition eq. (7) of paper 001 for its simulation (Sect. IV-A) into docs/figures/.

|Q (1 - S L P)| against frequency for the nominal model (Table I) and the
true plant J = 0.8 J_n, D = 1.2 D_n, with the 30 Hz pole-placement PID
(Tustin), T_s = 1 ms, L the ZPETC of S_n P_n and Q of eq. (24) with Nq = 16.
Prints both maxima and writes docs/figures/ilc_convergence.png.

    .venv/bin/python scripts/ilc_convergence.py
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from servo_axis import numerics
from servo_axis.core.feedback.pid import design_pid_pole_placement
from servo_axis.core.learning.ilc import IlcParams, convergence_gain, convergence_measure
from servo_axis.core.models.base import NominalModel

REPO = Path(__file__).resolve().parents[1]
PERIOD_S = 1e-3
NQ = 16
NOMINAL = NominalModel(inertia_kgm2=0.015, damping_Nms_per_rad=0.1, torque_constant_Nm_per_A=0.715)
TRUE_PLANT = NominalModel(
    inertia_kgm2=0.8 * 0.015, damping_Nms_per_rad=1.2 * 0.1, torque_constant_Nm_per_A=0.715
)


def main() -> None:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    params = IlcParams(
        samples_per_trial=4000,  # only bounds Nq; the condition does not depend on N
        nq=NQ,
        period_s=PERIOD_S,
        lead_m_per_rad=1.91e-3,
        nominal=NOMINAL,
        pid=design_pid_pole_placement(bandwidth_hz=30.0, **NOMINAL.as_kwargs()),
    )
    f = np.linspace(0.0, 0.5 / PERIOD_S, 4097)
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, plant in (
        ("nominal (J_n, D_n)", None),
        ("true plant (0.8 J_n, 1.2 D_n)", TRUE_PLANT),
    ):
        measure = convergence_measure(params=params, plant=plant)
        print(f"max |Q(1 - S L P)|, {label}: {measure:.6f}")
        gain = convergence_gain(f, params=params, plant=plant)
        ax.semilogy(f, np.maximum(gain, 1e-12), label=f"{label}, max {measure:.4f}")
    ax.axhline(1.0, color="k", lw=0.8, label="1 (eq. (7))")
    ax.set_ylim(1e-8, 3.0)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("|Q (1 - S L P)|")
    ax.set_title(f"ILC convergence condition eq. (7), 001 Sect. IV-A, Nq = {NQ}, T_s = 1 ms")
    ax.grid(True, which="both", alpha=0.4)
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = REPO / "docs" / "figures" / "ilc_convergence.png"
    fig.savefig(out, dpi=120)
    print(f"wrote {out.relative_to(REPO)}")


if __name__ == "__main__":
    main()
