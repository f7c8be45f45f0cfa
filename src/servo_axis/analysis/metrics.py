"""Tracking- and contour-error arithmetic: pure functions of arrays.

The tracking error is ``e[k] = R (r[k] - y[k])`` at the table (m). With PTC
the reference instants ``T_r = ratio T_u`` (every ``ratio``-th control
sample, :class:`~servo_axis.core.timing.SampleGrid`) are where perfect
tracking holds; :func:`error_statistics` gives statistics over every sample
and over those instants, for the whole run and per cycle of a periodic
reference. :func:`contour_error` measures a two-axis path against the
least-squares circle through its target (000 Fig. 18).

The results are in the layout of ``summary.json``
(:mod:`servo_axis.analysis.summary` types them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from servo_axis.analysis.serial import Serial, to_plain
from servo_axis.core.timing import SampleGrid


def _stats(e: NDArray[np.float64]) -> dict[str, float]:
    """RMS and largest magnitude of ``e`` (``rms_m``, ``max_m``); NaN when empty."""
    if e.size == 0:
        return {"rms_m": math.nan, "max_m": math.nan}
    return {"rms_m": float(np.sqrt(np.mean(e**2))), "max_m": float(np.max(np.abs(e)))}


def error_statistics(
    error_m: NDArray[np.float64],
    step: NDArray[np.int_],
    *,
    period_s: float,
    cycle_s: float | None,
    ratio: int = 2,
) -> dict[str, Any]:
    """Whole-run, reference-instant and per-cycle statistics of the error.

    Parameters
    ----------
    error_m : ndarray
        Tracking error per recorded step, m.
    step : ndarray of int
        The control sample of each element of ``error_m``.
    period_s : float
        Control period ``T_u``, s.
    cycle_s : float or None
        Period of the reference (or learning cycle), s; None if not periodic.
    ratio : int
        ``T_r / T_u``: the reference instants are the steps ``k`` with
        ``k % ratio == 0``.

    Returns
    -------
    dict
        ``all_samples`` and ``reference_instants`` (each ``{"rms_m",
        "max_m"}``), ``cycles`` (a row per complete cycle: ``cycle`` from 1,
        ``rms_m``, ``max_m``, ``reference_instants``) and, for a periodic
        reference, ``after_first_cycle``.
    """
    at_tr = SampleGrid(control_period_s=period_s, ratio=ratio).reference_instants(step)
    out: dict[str, Any] = {
        "all_samples": _stats(error_m),
        "reference_instants": _stats(error_m[at_tr]),
        "cycles": [],
    }
    if cycle_s:
        per_cycle = round(cycle_s / period_s)
        cycle = step // per_cycle
        for c in range(int(cycle.max()) + 1 if step.size else 0):
            sel = cycle == c
            if np.count_nonzero(sel) < per_cycle:
                continue  # incomplete last cycle
            out["cycles"].append(
                {
                    "cycle": c + 1,
                    **_stats(error_m[sel]),
                    "reference_instants": _stats(error_m[sel & at_tr]),
                }
            )
        after_first = step >= per_cycle
        out["after_first_cycle"] = {
            "all_samples": _stats(error_m[after_first]),
            "reference_instants": _stats(error_m[after_first & at_tr]),
        }
    return out


@dataclass(frozen=True)
class ContourCycle(Serial):
    """Contour error of one cycle of the reference.

    Attributes
    ----------
    cycle : int
        Cycle number, from 1.
    circular_deviation_m : float
        Largest minus smallest radial deviation in the cycle (ISO 230-4), m.
    max_radial_m : float
        Largest magnitude of the radial deviation in the cycle, m.
    """

    cycle: int
    circular_deviation_m: float
    max_radial_m: float


@dataclass(frozen=True, eq=False)
class ContourResult:
    """Contour error of a two-axis path against the circle through its target.

    Attributes
    ----------
    centre_m : tuple of float
        Centre ``(x, y)`` of the least-squares circle through the target, m.
    radius_m : float
        Its radius, m.
    target_radial_deviation_m : float
        Largest distance of the target itself from that circle, m (shows a
        target that is not a circle).
    circular_deviation_m : float
        Largest minus smallest radial deviation of the measured path, m.
    max_radial_m : float
        Largest magnitude of the radial deviation of the measured path, m.
    cycles : tuple of ContourCycle
        Per cycle of the reference (empty when it is not periodic).
    steps : ndarray of int
        The control samples of the series below.
    target, measured : ndarray, shape (n, 2)
        Target and measured position ``(x, y)`` per step, m.
    radial : ndarray
        Radial deviation ``|p - c| - R`` of the measured path per step, m.
    """

    centre_m: tuple[float, float]
    radius_m: float
    target_radial_deviation_m: float
    circular_deviation_m: float
    max_radial_m: float
    cycles: tuple[ContourCycle, ...]
    steps: NDArray[np.int_] = field(metadata={"summary": False})
    target: NDArray[np.float64] = field(metadata={"summary": False})
    measured: NDArray[np.float64] = field(metadata={"summary": False})
    radial: NDArray[np.float64] = field(metadata={"summary": False})

    def to_summary(self) -> dict[str, Any]:
        """The scalar results as in ``summary.json`` (no series)."""
        plain: dict[str, Any] = to_plain(self)
        return plain


def contour_error(
    target_xy: NDArray[np.float64],
    measured_xy: NDArray[np.float64],
    steps: NDArray[np.int_],
    per_cycle: int | None,
) -> ContourResult:
    """Contour error of a two-axis circle run (000 Fig. 18).

    The target circle is the least-squares (Kasa) circle through the target
    points, exact for points on a circle however they are sampled; the
    target's own largest distance from it is reported, so that a path that
    is not a circle shows. The radial deviation of the measured path is
    ``|p - c| - R``; per cycle of the reference its circular deviation (max -
    min, as ISO 230-4 defines it for a circular test) and its largest
    magnitude.

    Parameters
    ----------
    target_xy, measured_xy : ndarray, shape (n, 2)
        Target and measured positions, m.
    steps : ndarray of int, shape (n,)
        Control sample of each row.
    per_cycle : int or None
        Control samples per cycle of the reference; None (or 0) for no cycles.
    """
    target = np.asarray(target_xy, dtype=float)
    measured = np.asarray(measured_xy, dtype=float)
    steps = np.asarray(steps)
    lhs = np.column_stack((2 * target, np.ones(len(target))))
    (cx, cy, c0), *_ = np.linalg.lstsq(lhs, np.sum(target**2, axis=1), rcond=None)
    centre = np.array([cx, cy])
    radius = float(np.sqrt(c0 + cx * cx + cy * cy))
    radial = np.hypot(*(measured - centre).T) - radius
    target_radial = np.hypot(*(target - centre).T) - radius
    cycles = []
    if per_cycle:
        for c in range(int(steps.max() + 1) // per_cycle):
            inside = (steps >= c * per_cycle) & (steps < (c + 1) * per_cycle)
            if inside.any():
                r = radial[inside]
                cycles.append(
                    ContourCycle(
                        cycle=c + 1,
                        circular_deviation_m=float(r.max() - r.min()),
                        max_radial_m=float(np.max(np.abs(r))),
                    )
                )
    cx_m, cy_m = centre.tolist()
    return ContourResult(
        centre_m=(cx_m, cy_m),
        radius_m=radius,
        target_radial_deviation_m=float(np.max(np.abs(target_radial))),
        circular_deviation_m=float(radial.max() - radial.min()),
        max_radial_m=float(np.max(np.abs(radial))),
        cycles=tuple(cycles),
        steps=steps,
        target=target,
        measured=measured,
        radial=radial,
    )
