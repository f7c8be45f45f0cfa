#!/usr/bin/env python3
"""Figures of the learning filters (000 Fig. 11, 12, 14) into docs/figures/.

.venv/bin/python scripts/learning_figures.py
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from servo_axis import numerics
from servo_axis.core.feedback.pid import design_pid_pole_placement
from servo_axis.core.learning.filters import modelling_error_and_sensitivity, n_times_gain, q_gain
from servo_axis.core.models.ball_screw import BALL_SCREW_MODES, ball_screw_response

REPO = Path(__file__).resolve().parents[1]
TR = 2e-3
NOMINAL = {"torque_constant_Nm_per_A": 0.715, "inertia_kgm2": 0.01, "damping_Nms_per_rad": 0.1}


def main() -> None:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    f = np.linspace(0.1, 250.0, 2500)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for nq in (1, 5, 20, 40):
        ax1.plot(
            f,
            20 * np.log10(np.maximum(q_gain(f, nq=nq, period_s=TR), 1e-12)),
            label=f"Q, Nq = {nq}",
        )
    for n in (2, 5):
        gain = n_times_gain(f, nq=20, n=n, period_s=TR)
        ax1.plot(f, 20 * np.log10(np.maximum(gain, 1e-12)), "--", label=f"Q~{n}, Nq = 20")
    ax1.set_ylim(-60, 5)
    ax1.set_xlabel("frequency (Hz)")
    ax1.set_ylabel("gain (dB)")
    ax1.set_title("learning filters at T_r = 2 ms (000 Fig. 11/12)")
    ax1.grid(True)
    ax1.legend(fontsize=8)
    s = 2j * np.pi * f
    p = ball_screw_response(f, modes=BALL_SCREW_MODES, dead_time_s=70e-6, **NOMINAL)
    pn = ball_screw_response(f, **NOMINAL)
    num, den = design_pid_pole_placement(bandwidth_hz=45.0, **NOMINAL).transfer_function()
    delta, sens = modelling_error_and_sensitivity(
        f, plant=p, nominal=pn, controller=np.polyval(num, s) / np.polyval(den, s)
    )
    ax2.semilogy(f, np.abs(sens * delta), label="|S_n Delta| (3 modes + 70 us)")
    for label, q in (
        ("|1 - Q - Q S Delta|, Q (Nq 20)", q_gain(f, nq=20, period_s=TR)),
        ("|1 - Q~5 - Q~5 S Delta|, Nq 20", n_times_gain(f, nq=20, n=5, period_s=TR)),
        ("|1 - Q - Q S Delta|, Q = I", np.ones_like(f)),
    ):
        ax2.semilogy(f, np.abs(1 - q - q * sens * delta), label=label)
    ax2.axhline(1.0, color="k", lw=0.8)
    ax2.set_xlabel("frequency (Hz)")
    ax2.set_title("convergence condition (15)/(21), PID 45 Hz (000 Fig. 14)")
    ax2.grid(True, which="both")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    out = REPO / "docs" / "figures" / "learning_filters.png"
    fig.savefig(out, dpi=110)
    print(f"written {out}")


if __name__ == "__main__":
    main()
