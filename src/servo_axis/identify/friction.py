"""Friction table from a slow-reversal run (scenario ``friction_id``, docs/design.md section 7).

In a slow reversing motion the inertial and viscous torques are tiny, so the
motor torque the loop supplies is the friction: ``T_f ~ K_T i - J_n a_r -
D_n v_r`` with the nominal model and the reference's acceleration and
velocity; ``K_T i`` is the motor torque reference the bag's ``command``
carries (the feedback's current reference times the nominal ``K_T``).
Binned against the displacement from the reference's last reversal, it is
the data-based friction table of paper 000 Fig. 17 (and the table of paper
001) that the feedforward generator reads.

``python -m servo_axis friction-table runs/<friction_id run> --out table.csv``
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.analysis.signals import load_signals
from servo_axis.analysis.summary import RunSummary, load_summary
from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.feedforward.friction_table import (
    FrictionTable,
    ReversalTracker,
    build_friction_table,
)
from servo_axis.params.recorded import recorded_scenario
from servo_axis.params.resolve import Resolved


def estimate_friction_torque(
    *,
    reference_rad: np.ndarray,
    motor_torque_Nm: np.ndarray,
    period_s: float,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
) -> np.ndarray:
    """Friction torque estimate ``K_T i - J a_r - D v_r`` per sample, N m.

    Parameters
    ----------
    reference_rad : ndarray
        The motor-angle reference ``r``, rad.
    motor_torque_Nm : ndarray
        The motor torque reference ``K_T i`` (the ``command`` topic), N m.
    period_s : float
        ``T_u``, s (the derivatives of ``r``).
    inertia_kgm2, damping_Nms_per_rad : float
        ``J`` and ``D`` of the nominal model.
    """
    vel = np.gradient(reference_rad, period_s)
    acc = np.gradient(vel, period_s)
    return motor_torque_Nm - inertia_kgm2 * acc - damping_Nms_per_rad * vel


@dataclass(frozen=True)
class MeasuredFriction:
    """The friction a slow-reversal run measured, per sample.

    Attributes
    ----------
    scenario : dict
        The run's scenario.
    period_s : float
        ``T_u``, s.
    position_m : ndarray
        The reference at the table, m.
    torque_Nm : ndarray
        ``K_T i - J_n a_r - D_n v_r`` (:func:`estimate_friction_torque`), N m.
    """

    scenario: dict[str, Any]
    period_s: float
    position_m: np.ndarray
    torque_Nm: np.ndarray


#: The most of the motor torque that the reference's inertial and viscous
#: torque ``J_n a_r + D_n v_r`` may be in a slow-reversal run: above it the
#: command is not the friction (friction_id: 0.1 %, a 10 mm 2 Hz sine: 100 %).
SLOW_FRACTION = 0.1


def measured_friction(run_dir: Path) -> MeasuredFriction:
    """The friction of a recorded slow-reversal run directory, with the run's own values.

    The control period, the lead and the nominal model are the checked
    feedforward parameters of the run's scenario (their defaults where it
    does not set them). SignalError for a bag with fewer than 3 samples,
    ConfigError for a directory that is not a single-axis run or a run that
    is not a slow reversal (:func:`slow_reversal_problem`).
    """
    summary = load_summary(Path(run_dir))
    if not isinstance(summary, RunSummary):
        axes = ", ".join(str(Path(run_dir) / a) for a in summary.axes)
        raise ConfigError(f"{run_dir}: a multi-axis run; give one of its axes: {axes}")
    scenario = recorded_scenario(Path(run_dir), summary.scenario_file).scenario
    resolved = Resolved(scenario)
    values = resolved.feedforward
    period = float(values.control_period_s)
    sig = load_signals(Path(run_dir) / "bag", period, scenario=resolved)
    if sig.step.size < 3:
        raise SignalError(
            f"{Path(run_dir) / 'bag'}: expected a recorded run, got {sig.step.size} samples "
            "with both state and reference"
        )
    torque = estimate_friction_torque(
        reference_rad=sig.reference_rad,
        motor_torque_Nm=sig.command_Nm,
        period_s=period,
        inertia_kgm2=values.nominal.inertia_kgm2,
        damping_Nms_per_rad=values.nominal.damping_Nms_per_rad,
    )
    problem = slow_reversal_problem(sig.reference_rad, sig.command_Nm, torque)
    if problem is not None:
        name = summary.scenario
        raise ConfigError(
            f"{run_dir}: not a slow-reversal (friction identification) run like friction_id: "
            f"the reference of {name} {problem}"
        )
    return MeasuredFriction(
        scenario=scenario,
        period_s=period,
        position_m=sig.reference_rad * values.lead_m_per_rad,
        torque_Nm=torque,
    )


def slow_reversal_problem(
    reference_rad: np.ndarray, motor_torque_Nm: np.ndarray, friction_Nm: np.ndarray
) -> str | None:
    """Why a run's samples do not measure friction after reversals, or None when they do.

    They do when the reference reverses and moves so slowly that its
    inertial and viscous torque (``motor_torque_Nm - friction_Nm``) is at
    most :data:`SLOW_FRACTION` of the motor torque: the command is then the
    friction.
    """
    tracker = ReversalTracker()
    for position in np.asarray(reference_rad, dtype=float).tolist():
        tracker.update(position)
    if tracker.reversals == 0:
        return "never reverses (a friction table and a GMS fit are made of the motion after one)"
    model = np.abs(np.asarray(motor_torque_Nm) - np.asarray(friction_Nm))
    peak = float(np.max(np.abs(motor_torque_Nm)))
    share = float(np.max(model)) / peak if peak > 0 else math.inf
    if share > SLOW_FRACTION:
        return (
            f"moves so fast that its inertial and viscous torque J_n a_r + D_n v_r reaches "
            f"{float(np.max(model)):.3g} N m, {100 * share:.0f} % of the motor torque (a slow "
            f"reversal keeps it under {100 * SLOW_FRACTION:.0f} %, so that the command is the friction)"
        )
    return None


def table_from_run(
    run_dir: Path, *, bin_width_m: float = 0.5e-6, max_displacement_m: float = 40e-6
) -> FrictionTable:
    """Build the friction table from a recorded ``friction_id`` run directory."""
    measured = measured_friction(run_dir)
    return build_friction_table(
        position_m=measured.position_m,
        torque_Nm=measured.torque_Nm,
        bin_width_m=bin_width_m,
        max_displacement_m=max_displacement_m,
    )
