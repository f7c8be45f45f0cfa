"""GMS friction model from a slow-reversal run (paper 004 Sect. II-A, Fig. 4(b)).

Paper 004 identifies its ball screw's friction by a slow 50 um, 0.05 Hz
sinusoid and fits the conventional GMS model (Al-Bender et al. 2005) to
the torque against the table position (its Fig. 4(b), dashed line). Here
the run is a ``friction_id`` one: as for the friction table
(:mod:`servo_axis.identify.friction`), the friction is the torque the loop
supplies less the nominal inertial and viscous parts,
``K_T i - J_n a_r - D_n v_r``, against the reference at the table
(``reference_rad * lead_m_per_rad``). The fit
(:func:`servo_axis.core.friction.gms_fitting.fit_gms`) counts the samples from the
first reversal on: those before it (the virgin start) only bring the
model into the same sliding state as the axis.

The parameter file names the plant it was fitted on: its model and a
fingerprint of that model's own parameter values and the lead
(:func:`plant_fingerprint`).

``python -m servo_axis gms-fit runs/<friction_id run> --out gms.txt [--plot gms.png]``
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.core.errors import SignalError
from servo_axis.core.friction.gms_fitting import GmsFit, fit_gms
from servo_axis.identify.friction import measured_friction
from servo_axis.params import resolve
from servo_axis.params.resolve import Resolved


@dataclass(frozen=True)
class RunFitData:
    """What a GMS fit takes from a run.

    Attributes
    ----------
    position_m : ndarray
        Reference position at the table per recorded step, m.
    torque_Nm : ndarray
        Friction torque estimate ``K_T i - J_n a_r - D_n v_r`` per step, N m.
    period_s : float
        Control period ``T_u``, s.
    plant_model, plant_fingerprint : str
        The run's plant model and its :func:`plant_fingerprint`.
    """

    position_m: np.ndarray
    torque_Nm: np.ndarray
    period_s: float
    plant_model: str
    plant_fingerprint: str


def plant_fingerprint(scenario: dict[str, Any]) -> str:
    """``"<model>:<16 hex>"``: the plant model and a hash of its checked values.

    The first 16 hex digits of the SHA-256 of the JSON (keys sorted, floats
    as ``repr``) of the scenario's checked plant values of the plant
    model's own schema keys and the lead. One definition, the feedforward's
    (:func:`servo_axis.params.resolve.plant_fingerprint`), so that the
    GMS term accepts exactly the files fitted on its plant.
    """
    return resolve.plant_fingerprint(scenario)


def load_fit_data(run_dir: Path) -> RunFitData:
    """Position, friction torque and plant identity of a recorded run directory.

    The control period, the lead and the nominal model are the checked
    feedforward parameters of the run's scenario (their defaults where it
    does not set them), as for :func:`servo_axis.identify.friction.table_from_run`.
    """
    measured = measured_friction(run_dir)
    resolved = Resolved(measured.scenario)
    return RunFitData(
        position_m=measured.position_m,
        torque_Nm=measured.torque_Nm,
        period_s=measured.period_s,
        plant_model=str(resolved.plant.model),
        plant_fingerprint=resolve.plant_fingerprint(resolved),
    )


def fit_run_data(data: RunFitData, *, elements: int = 4) -> GmsFit:
    """The GMS fit of :func:`load_fit_data`'s arrays (samples from the first reversal on)."""
    return fit_gms(data.position_m, data.torque_Nm, elements=elements, period_s=data.period_s)


def fit_from_run(run_dir: Path, *, elements: int = 4) -> GmsFit:
    """Fit a GMS model with ``elements`` elements to a recorded ``friction_id`` run.

    Raises
    ------
    SignalError
        When the run has no reversal or is too short after it.
    ConfigError
        For ``elements`` outside 1..20.
    """
    return fit_run_data(load_fit_data(run_dir), elements=elements)


def plot_fit(fit: GmsFit, position_m: np.ndarray, torque_Nm: np.ndarray, path: Path) -> None:
    """Measured (solid) and GMS model (dashed) torque against displacement (004 Fig. 4(b)).

    ``position_m`` and ``torque_Nm`` are the arrays the fit was made on
    (one per sample, as ``fit.model_torque_Nm``); the displacement is from
    the first sample, in um.
    """
    pos = np.asarray(position_m, dtype=float)
    tq = np.asarray(torque_Nm, dtype=float)
    n = fit.model_torque_Nm.size
    if pos.shape != (n,) or tq.shape != (n,):
        raise SignalError(
            f"position_m, torque_Nm: expected {n} samples each (as the fit), "
            f"got shapes {pos.shape} and {tq.shape}"
        )
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from servo_axis.analysis.units import DISPLACEMENT, QUANTITIES

    x_um = DISPLACEMENT.shown(pos - pos[0])
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.plot(x_um, tq, "-", lw=1.0, color="tab:blue", label="measured")
    ax.plot(x_um, fit.model_torque_Nm, "--", lw=1.2, color="tab:red", label="GMS model")
    p = fit.params
    ax.set_title(
        f"GMS fit: {p.elements} elements, F_c = {p.coulomb_Nm:.4g} N m, "
        f"RMS residual {fit.rms_residual_Nm:.3g} N m",
        fontsize=10,
    )
    ax.set_xlabel(DISPLACEMENT.label("displacement of the table"))
    ax.set_ylabel(QUANTITIES["torque"].label("friction torque at the motor"))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="center")  # the middle of a reversal loop is empty
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
