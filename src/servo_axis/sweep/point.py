"""One point of a study: its scenario run by a backend, its figures picked from the summary.

``plain`` runs the plain-call loops of :mod:`servo_axis.simulate` (the loop
the node graph reproduces bit for bit): :func:`~servo_axis.simulate.simulate_identification`
for a scenario with an identifier, :func:`~servo_axis.simulate.simulate_learning`
for one with a learning section, :func:`~servo_axis.simulate.simulate` otherwise;
its summary is computed by the same functions as a run's ``summary.json``
(:func:`servo_axis.analysis.signals.tracking`,
:func:`servo_axis.analysis.metrics.error_statistics`,
:func:`servo_axis.identify.study.sysid_block` for a scenario with an excitation,
:func:`servo_axis.analysis.summary.summarise_estimates`,
:func:`servo_axis.analysis.summary.ilc_convergence`), so its fields have the
same paths. ``nodes`` runs ``python -m servo_axis run`` in a ROS domain of
its own and reads its ``summary.json``. Nothing here imports rclpy.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.sweep.spec import dump_scenario, figure, scenario_for

#: The first ROS domain of the ``nodes`` backend; point ``i`` uses ``DOMAIN_BASE + i % 100``.
DOMAIN_BASE = 110


@dataclass(frozen=True)
class _Signals:
    """What :func:`servo_axis.analysis.signals.tracking` reads of a bag's signals."""

    step: np.ndarray
    encoder_rad: np.ndarray
    scale_m: np.ndarray
    reference_rad: np.ndarray


def plain_summary(scenario: dict[str, Any], scenario_path: Path) -> dict[str, Any]:
    """The summary fields of a plain-call run of a scenario file (same paths as ``summary.json``)."""
    from servo_axis.analysis.metrics import error_statistics
    from servo_axis.analysis.signals import learning_enabled, tracking
    from servo_axis.analysis.summary import (
        error_unit,
        ilc_convergence,
        position_scale,
        summarise_estimates,
        true_parameters,
    )
    from servo_axis.analysis.tracking import unit_keys
    from servo_axis.params.factories import build_reference
    from servo_axis.params.resolve import Resolved
    from servo_axis.simulate import simulate, simulate_identification, simulate_learning
    from servo_axis.wire.cdr import EstimateData

    resolved = Resolved(scenario, scenario_path)
    plant, ff = resolved.plant, resolved.feedforward
    period = plant.control_period_s
    identification = None
    reference_period: float | None = None
    learning = learning_enabled(resolved)
    if "feedforward" in scenario and (not learning or "identifier" in scenario):
        reference_period = build_reference(ff).period_s
    if "identifier" in scenario:
        run = simulate_identification(scenario_path)
        traj = run.trajectory
        estimates = [
            EstimateData(
                int(r[0]), int(r[1]), r[2], r[3], r[4], r[5], r[6], tuple(bool(u) for u in r[7:11])
            )
            for r in run.estimates
        ]
        identification = summarise_estimates(
            estimates,
            true=true_parameters(plant),
            control_period_s=period,
            period_s=reference_period,
        ).to_dict()
    elif "learning" in scenario:
        traj = simulate_learning(scenario_path).trajectory
    else:
        traj = simulate(scenario_path)
    steps = np.arange(traj.encoder_rad.size)
    sig = _Signals(steps, traj.encoder_rad, traj.scale_m, traj.reference_rad)
    target, y = tracking(resolved, scenario_path, sig)  # type: ignore[arg-type]
    error = position_scale(plant) * (target - y)
    cycle = ff.learning.cycle_s if learning else reference_period
    summary: dict[str, Any] = {
        "steps": int(steps.size),
        "sim_time_s": steps.size * period,
        "reference_period_s": cycle,
        "tracking_error": unit_keys(
            error_statistics(error, steps, period_s=period, cycle_s=cycle), error_unit(plant)
        ),
    }
    convergence = ilc_convergence(resolved, scenario_path)
    if convergence is not None:
        summary["ilc_convergence"] = convergence
    if identification is not None:
        summary["identification"] = identification
    from servo_axis.identify.study import sysid_block

    sysid = sysid_block(scenario, scenario_path, traj)
    if sysid is not None:
        summary["sysid"] = sysid
    return summary


def nodes_summary(scenario_path: Path, out_dir: Path, *, domain_id: int) -> dict[str, Any]:
    """The ``summary.json`` of ``python -m servo_axis run`` of a scenario in its own ROS domain."""
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "servo_axis",
            "run",
            str(scenario_path),
            "--out",
            str(out_dir),
            "--domain-id",
            str(domain_id),
            "--no-plots",
        ],
        capture_output=True,
        text=True,
        env={**os.environ, "ROS_DOMAIN_ID": str(domain_id)},
        check=False,
    )
    summary_file = out_dir / "summary.json"
    if proc.returncode != 0 or not summary_file.is_file():
        last = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise RuntimeError(f"run exited {proc.returncode}: {last}")
    data: dict[str, Any] = json.loads(summary_file.read_text())
    return data


def cell(value: Any) -> Any:
    """A table cell: numbers and strings as they are, anything else as JSON."""
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float | np.floating):
        return float(value)
    return json.dumps(value, sort_keys=True)


def run_point(
    index: int,
    scenario: str,
    overrides: dict[str, Any],
    figures: dict[str, str],
    backend: str = "plain",
    run_root: str | None = None,
) -> dict[str, Any]:
    """Run one point and return its row; a failure is a row too (``status`` ``failed``).

    Parameters
    ----------
    index : int
        The point's number in the study (from 0).
    scenario : str
        The base scenario (a shipped name or an absolute path).
    overrides : dict
        Dotted keys -> values (:func:`servo_axis.sweep.spec.apply_override`).
    figures : dict
        Column name -> path into the summary.
    backend : str
        ``plain`` or ``nodes``.
    run_root : str or None
        Where the ``nodes`` backend keeps its run directories (a temporary one if None).

    Returns
    -------
    dict
        ``point``, the overrides, the figures (NaN when failed), ``status``,
        ``error`` (empty when ok) and ``wall_time_s`` (s).
    """
    t0 = time.perf_counter()
    row: dict[str, Any] = {"point": index, **{k: cell(v) for k, v in overrides.items()}}
    values: dict[str, Any] = dict.fromkeys(figures, math.nan)
    status, error = "ok", ""
    try:
        with tempfile.TemporaryDirectory(prefix="servo_axis_point_") as tmp:
            data, base = scenario_for(scenario, overrides)
            path = Path(tmp) / f"{base.stem}.yaml"
            dump_scenario(data, path)
            if backend == "plain":
                summary = plain_summary(data, path)
            else:
                out = Path(run_root) / f"point_{index:05d}" if run_root else Path(tmp) / "run"
                summary = nodes_summary(path, out, domain_id=DOMAIN_BASE + index % 100)
            for name, where in figures.items():
                values[name] = cell(figure(summary, where))
    except Exception as err:  # a point's failure is a result: recorded, the study goes on
        status = "failed"
        detail = str(err.args[0]) if isinstance(err, KeyError) and err.args else str(err)
        error = f"{type(err).__name__}: {detail}" if detail else traceback.format_exc(limit=1)
    row.update(values)
    row.update(status=status, error=error, wall_time_s=time.perf_counter() - t0)
    return row
