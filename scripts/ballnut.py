"""Checks of the elastic ball screw's ball-nut friction against paper 004's own data.

A study's module, not the package's: ``scripts/calibrate_contact.py`` and
``scripts/ballnut_band.py`` calibrate and vary the contact plant with it, and
``test/unit/core/test_ballnut_contact.py`` checks the frozen calibration.

The calibration of ``plant.nut_friction: contact`` (issue 21) pins every free
value with measurements of 004 that do not involve the sigmoid-vs-GMS
comparison; each function here computes one of them from a core-only run (the
plain-call loop of :func:`servo_axis.simulate.simulate`, with the plant's
inner signals kept):

* :func:`presliding_loop`: the slow reversal of Fig. 4(b) (50 um, 0.05 Hz):
  the friction ``K_T u - J_n a_r - B_n v_r`` against the table position, its
  sliding level ``F_0`` and the pre-sliding distance after a reversal;
* :func:`sigma_fit`: eq. (8) ``d_r = sigma / z`` fitted to the plant's own
  deformation ratio (eqs. (5)-(7)) before a stop;
* the rigid model (eq. (1)) and the first axial mode are checked in the
  tests on :mod:`servo_axis.core.models.elastic_ball_screw` directly.

Nothing here imports rclpy.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from servo_axis.core.deformation import deformation_ratio
from servo_axis.core.errors import SignalError
from servo_axis.identify.friction import estimate_friction_torque
from servo_axis.params.resolve import Resolved
from servo_axis.params.scenario import load_scenario
from servo_axis.simulate import simulate

FloatArray = np.ndarray


@dataclass(frozen=True)
class PlantTrace:
    """A core-only run with the plant's inner signals, per control sample.

    Attributes
    ----------
    period_s : float
        ``T_u``, s.
    lead_m_per_rad : float
        ``R``, m/rad.
    reference_m : ndarray
        Feedback reference at the table (``R r``), m.
    scale_m, encoder_rad : ndarray
        The sensors (m, rad).
    position_m, angle_rad : ndarray
        True table position (m) and motor angle (rad).
    command_Nm : ndarray
        Motor torque reference (the ``command`` topic), N m.
    deformation_m, contact_m : ndarray
        ``delta = R th - x`` and the contact deformation ``delta_c``, m.
    nut_Nm, bearing_Nm, guide_N : ndarray
        The nut's and the bearings' friction at the motor (N m), the guide's (N).
    """

    period_s: float
    lead_m_per_rad: float
    reference_m: FloatArray
    scale_m: FloatArray
    encoder_rad: FloatArray
    position_m: FloatArray
    angle_rad: FloatArray
    command_Nm: FloatArray
    deformation_m: FloatArray
    contact_m: FloatArray
    nut_Nm: FloatArray
    bearing_Nm: FloatArray
    guide_N: FloatArray

    @property
    def time_s(self) -> FloatArray:
        """Sample times, s."""
        return np.arange(len(self.scale_m)) * self.period_s

    @property
    def error_m(self) -> FloatArray:
        """Tracking error at the table, reference minus scale, m."""
        return self.reference_m - self.scale_m


def _set(section: dict[str, Any], dotted: str, value: object) -> None:
    keys = dotted.split(".")
    for key in keys[:-1]:
        section = section.setdefault(key, {})
    section[keys[-1]] = value


def scenario_with(
    base: Path, path: Path, overrides: Mapping[str, Mapping[str, object]] | None = None
) -> Path:
    """``base`` written to ``path`` with ``{section: {dotted key: value}}`` set.

    A relative GMS file of the base is made absolute, so the copy runs anywhere.
    """
    data = load_scenario(base)
    gms = data.get("feedforward", {}).get("ros__parameters", {}).get("gms")
    if gms is not None and "file" in gms and not Path(gms["file"]).is_absolute():
        gms["file"] = str((base.parent / gms["file"]).resolve())
    for section, values in (overrides or {}).items():
        params = data.setdefault(section, {}).setdefault("ros__parameters", {})
        for key, value in values.items():
            _set(params, key, value)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def run_trace(scenario_path: Path, *, steps: int | None = None) -> PlantTrace:
    """The loop of :func:`servo_axis.simulate.simulate`, with the plant's inner signals kept.

    The plain-call loop itself (so the same floats as the node graph's), the
    plant asked for its inner signals at each sample before it steps; the plant
    must be ``elastic_ball_screw``.
    """
    pv = Resolved(load_scenario(scenario_path), scenario_path).plant
    if pv.model != "elastic_ball_screw":
        raise SignalError(f"plant.model: expected elastic_ball_screw, got {pv.model!r}")
    inner: list[tuple[float, ...]] = []

    def keep(plant: Any) -> None:
        y = plant.output()
        _, nut, bearing = plant.friction_torques_Nm
        inner.append(
            (
                y.position_m,
                y.angle_rad,
                plant.deformation_m,
                plant.contact_deformation_m,
                nut,
                bearing,
                plant.guide_force_N,
            )
        )

    run = simulate(scenario_path, steps=steps, watch=keep)
    lead = float(pv.lead_m_per_rad)
    cols = np.array(inner, dtype=float).reshape(-1, 7)
    c = [cols[:, i].copy() for i in range(7)]
    return PlantTrace(
        float(pv.control_period_s),
        lead,
        lead * run.reference_rad,
        run.scale_m,
        run.encoder_rad,
        *c[:2],
        run.command_Nm,
        *c[2:],
    )


@dataclass(frozen=True)
class PreslidingLoop:
    """The friction loop of a slow reversal (004 Fig. 4(b)).

    Attributes
    ----------
    coulomb_Nm : float
        ``F_0``: half the swing between the sliding levels of the two
        directions (median of the friction where the reference has moved
        more than ``settle_m`` from its last reversal), N m.
    presliding_m : list of float
        Per reversal, the displacement from it at which the friction has
        covered ``fraction`` of its swing to the new sliding level, m.
    position_m, torque_Nm : ndarray
        The reference at the table and the friction estimate, per sample.
    """

    coulomb_Nm: float
    presliding_m: list[float]
    position_m: FloatArray
    torque_Nm: FloatArray


def presliding_loop(
    trace: PlantTrace,
    *,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
    fraction: float = 0.9,
    settle_m: float = 30e-6,
) -> PreslidingLoop:
    """``F_0`` and the pre-sliding distance of a slow-reversal run (004 Fig. 4(b)).

    The friction is ``K_T u - J_n a_r - B_n v_r`` as for the GMS fit
    (:func:`servo_axis.identify.friction.estimate_friction_torque`) against the
    reference at the table. The pre-sliding distance of a reversal is the
    reference's travel from it until the friction has covered ``fraction``
    of the swing from the old sliding level to the new one (004: "the
    presliding region ... is about 15 um").
    """
    position = trace.reference_m
    torque = estimate_friction_torque(
        reference_rad=position / trace.lead_m_per_rad,
        motor_torque_Nm=trace.command_Nm,
        period_s=trace.period_s,
        inertia_kgm2=inertia_kgm2,
        damping_Nms_per_rad=damping_Nms_per_rad,
    )
    # the direction of motion over +-20 samples (the reference may hold between samples)
    m = 20
    ahead = np.concatenate([position[m:], np.repeat(position[-1], m)])
    behind = np.concatenate([np.repeat(position[0], m), position[:-m]])
    direction = np.sign(ahead - behind)
    turns = []
    previous = 0.0
    for k in range(len(direction)):
        if direction[k] != 0.0:
            if previous != 0.0 and direction[k] != previous:
                turns.append(k)
            previous = direction[k]
    if not turns:
        raise SignalError("presliding_loop: the reference never reverses")
    levels: dict[float, list[float]] = {1.0: [], -1.0: []}
    last = 0
    for k in range(len(position)):
        if last + 1 < len(turns) and k >= turns[last + 1]:
            last += 1
        moved = abs(position[k] - position[turns[last]]) > settle_m
        if k >= turns[0] and direction[k] != 0 and moved:
            levels[float(direction[k])].append(float(torque[k]))
    if not levels[1.0] or not levels[-1.0]:
        raise SignalError("presliding_loop: no sliding in one of the directions")
    high, low = float(np.median(levels[1.0])), float(np.median(levels[-1.0]))
    distances = []
    for j, k in enumerate(turns):
        end = turns[j + 1] if j + 1 < len(turns) else len(position)
        new = high if direction[k] > 0 else low
        old = low if direction[k] > 0 else high
        target = old + fraction * (new - old)
        seg = slice(k, end)
        reached = (torque[seg] - target) * np.sign(new - old) >= 0.0
        if np.any(reached):
            first = k + int(np.argmax(reached))
            distances.append(float(abs(position[first] - position[k])))
    return PreslidingLoop((high - low) / 2.0, distances, position, torque)


@dataclass(frozen=True)
class SigmaFit:
    """Eq. (8) fitted to the deformation ratio before a stop.

    Attributes
    ----------
    sigma_m2_per_rad : float
        ``sigma`` of ``d_r = sigma / z``, m^2/rad (0.04e-6 = 004's 0.04 with z
        in mm and d_r in mm/rad); NaN when no sample qualifies.
    z_m, d_r_m_per_rad : ndarray
        The samples fitted: distance to the stop (m) and ``d_r`` (m/rad).
    """

    sigma_m2_per_rad: float
    z_m: FloatArray
    d_r_m_per_rad: FloatArray


def sigma_fit(
    trace: PlantTrace,
    stop_step: int,
    *,
    window_samples: int = 10,
    min_rotation_rad: float = 1e-3,
    z_range_m: tuple[float, float] = (5e-6, 200e-6),
) -> SigmaFit:
    """Least-squares ``sigma`` of eq. (8) from the plant's ``d_r`` before ``stop_step``.

    ``d_r`` is eqs. (6)-(7) on the sensors (encoder and scale, the window of
    the scenarios); ``z`` is the distance of the table (scale) from where it
    stops, taken at the middle of the window. Only the valid samples (the
    motor turned at least ``min_rotation_rad`` over the window) with ``z``
    in ``z_range_m`` before the stop count; ``sigma`` minimises
    ``sum (d_r - sigma / z)^2 z^2`` (the relative misfit: ``sigma`` is the
    mean of ``d_r z``).
    """
    trace_dr = deformation_ratio(
        trace.encoder_rad,
        trace.scale_m,
        window_samples=window_samples,
        lead_m_per_rad=trace.lead_m_per_rad,
        min_rotation_rad=min_rotation_rad,
    )
    stop_x = trace.scale_m[stop_step]
    half = window_samples // 2
    ks = np.arange(window_samples, stop_step + 1)
    z = np.abs(stop_x - trace.scale_m[ks - half])
    ok = trace_dr.valid[ks] & (z >= z_range_m[0]) & (z <= z_range_m[1])
    # only the approach: the samples after the last time z was above the range
    far = np.nonzero(z > z_range_m[1])[0]
    if far.size:
        ok &= np.arange(len(ks)) > far[-1]
    z_ok, dr_ok = z[ok], trace_dr.d_r_m_per_rad[ks][ok]
    sigma = float(np.mean(dr_ok * z_ok)) if z_ok.size else float("nan")
    return SigmaFit(sigma, z_ok, dr_ok)
