"""Friction table from a slow-reversal run (scenario ``friction_id``, DESIGN 7).

In a slow reversing motion the inertial and viscous torques are tiny, so the
motor torque the loop supplies is the friction: ``T_f ~ K_T i - J_n a_r -
D_n v_r`` with the nominal model and the reference's acceleration and
velocity. Binned against the displacement from the reference's last
reversal, it is the data-based friction table of paper 000 Fig. 17 (and the
table of paper 001) that the feedforward generator reads.

``python -m servo_axis friction-table runs/<friction_id run> --out table.csv``
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from servo_axis.analysis.signals import load_signals
from servo_axis.analysis.summary import SUMMARY_FILE, RunSummary
from servo_axis.core.feedforward.friction_table import FrictionTable, build_friction_table
from servo_axis.params.factories import node_values
from servo_axis.params.scenario import load_scenario


def estimate_friction_torque(
    *,
    reference_rad: np.ndarray,
    current_A: np.ndarray,
    period_s: float,
    torque_constant_Nm_per_A: float,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
) -> np.ndarray:
    """Friction torque estimate ``K_T i - J a_r - D v_r`` per sample, N m."""
    vel = np.gradient(reference_rad, period_s)
    acc = np.gradient(vel, period_s)
    return torque_constant_Nm_per_A * current_A - inertia_kgm2 * acc - damping_Nms_per_rad * vel


def table_from_run(
    run_dir: Path, *, bin_width_m: float = 0.5e-6, max_displacement_m: float = 40e-6
) -> FrictionTable:
    """Build the friction table from a recorded ``friction_id`` run directory.

    The control period, the lead and the nominal model are the checked
    feedforward parameters of the run's scenario (their defaults where it
    does not set them).
    """
    summary = RunSummary.from_json(Path(run_dir) / SUMMARY_FILE)
    scenario = load_scenario(Path(summary.scenario_file))
    values = node_values(scenario, "feedforward")
    period = values["control_period_s"]
    sig = load_signals(Path(run_dir) / "bag", period, scenario=scenario)
    torque = estimate_friction_torque(
        reference_rad=sig.reference_rad,
        current_A=sig.command_A,
        period_s=period,
        torque_constant_Nm_per_A=values["nominal.torque_constant_Nm_per_A"],
        inertia_kgm2=values["nominal.inertia_kgm2"],
        damping_Nms_per_rad=values["nominal.damping_Nms_per_rad"],
    )
    return build_friction_table(
        position_m=sig.reference_rad * values["lead_m_per_rad"],
        torque_Nm=torque,
        bin_width_m=bin_width_m,
        max_displacement_m=max_displacement_m,
    )
