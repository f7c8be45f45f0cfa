"""The one unit each quantity is shown in, for every table and figure of the suite.

Data files keep SI units, the unit in each name (``summary.json``'s
``rms_m``, a rotary run's ``rms_rad``, ``results.csv`` of a study, the
wire). What a person reads (the tables ``run``, ``summary``, ``compare``,
``identify``, ``gms-fit`` print and every figure's axes) shows each quantity
in the one unit of :data:`QUANTITIES`, whatever the size of the values: a
tracking error is in um on an axis whose table moves along a line and in rad
on one whose table turns (a plant model with ``rotary=True``: the tilting
table of paper 003, whose RMSD the paper gives in rad, Fig. 9), in every
command. The table is documented in ``docs/reference/units.md``
(``test/unit/analysis/test_units.py`` holds the page to it).

Nothing here imports more than numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Quantity:
    """A quantity as the suite shows it.

    Attributes
    ----------
    name : str
        What it is, as a header or an axis label names it.
    si : str
        The unit it is stored in: the data files and the code name it
        (``rms_m``, ``tick_late_us``); SI but for a realtime run's latencies.
    unit : str
        The unit it is shown in.
    factor : float
        ``shown = factor * stored``; for a level in dB (``decibel``) the
        reference value, ``shown = 20 log10 (|stored| / factor)``.
    decibel : bool
        Shown as a level, ``20 log10`` of the magnitude.
    """

    name: str
    si: str
    unit: str
    factor: float
    decibel: bool = False

    def shown(self, value: Any) -> Any:
        """A stored (SI) value, or an array of them, in the unit shown."""
        if self.decibel:
            with np.errstate(divide="ignore"):
                level = 20.0 * np.log10(np.abs(np.asarray(value)) / self.factor)
            return float(level) if np.ndim(level) == 0 else level
        return self.factor * value

    def label(self, text: str | None = None) -> str:
        """``text (unit)``: a header or an axis label (``text`` defaults to the name)."""
        return f"{text or self.name} ({self.unit})"

    def format(self, value: float | None, spec: str = ".6g") -> str:
        """A stored value as a table shows it, in the unit shown; ``-`` when not finite."""
        if value is None or not math.isfinite(value):
            return "-"
        return format(self.shown(value), spec)


#: Every quantity a table or a figure shows, by key: its unit and the factor from SI.
QUANTITIES: dict[str, Quantity] = {
    "position_error": Quantity("tracking error (linear axis)", "m", "um", 1e6),
    "position_error_rotary": Quantity("tracking error (rotary axis)", "rad", "rad", 1.0),
    "contour_error": Quantity("circular deviation, radial error", "m", "um", 1e6),
    "position": Quantity("table position (linear axis)", "m", "mm", 1e3),
    "position_rotary": Quantity("table angle (rotary axis)", "rad", "rad", 1.0),
    "circle_radius": Quantity("radius of a circle", "m", "mm", 1e3),
    "displacement": Quantity(
        "small displacement (pre-sliding, break-away, after a reversal)", "m", "um", 1e6
    ),
    "motor_angle": Quantity("motor angle", "rad", "rad", 1.0),
    "deformation_ratio": Quantity("deformation ratio d_r", "m/rad", "um/rad", 1e6),
    "acceleration": Quantity("acceleration, deceleration", "m/s^2", "m/s^2", 1.0),
    "torque": Quantity("torque", "N m", "N m", 1.0),
    "force": Quantity("force", "N", "N", 1.0),
    "time": Quantity("time", "s", "s", 1.0),
    "time_from_stop": Quantity("time from a stop of the reference", "s", "ms", 1e3),
    "latency": Quantity("lateness of a tick or a command (realtime)", "us", "us", 1.0),
    "frequency": Quantity("frequency", "Hz", "Hz", 1.0),
    "frf_magnitude": Quantity(
        "magnitude of a frequency response P, 20 log10 abs(P) re 1 rad/(N m) (encoder) or "
        "1 m/(N m) (scale)",
        "rad/(N m), m/(N m)",
        "dB",
        1.0,
        decibel=True,
    ),
    "frf_phase": Quantity("phase of a frequency response", "rad", "deg", 180.0 / math.pi),
    "frf_misfit_magnitude": Quantity(
        "fitted against measured response, 20 log10 abs(P_fit / P)", "dB", "dB", 1.0
    ),
    "frf_misfit_phase": Quantity("fitted against measured response, phase", "deg", "deg", 1.0),
    "coherence": Quantity("coherence", "1", "1", 1.0),
    "reduction": Quantity("reduction, 100 (1 - value / base)", "1", "%", 100.0),
}

#: The tracking error of a linear axis: um.
POSITION_ERROR = QUANTITIES["position_error"]
#: The tracking error of a rotary axis: rad.
POSITION_ERROR_ROTARY = QUANTITIES["position_error_rotary"]
#: The contour error of two axes (circular deviation, radial error): um.
CONTOUR_ERROR = QUANTITIES["contour_error"]
#: A small displacement: pre-sliding width, break-away, displacement after a reversal: um.
DISPLACEMENT = QUANTITIES["displacement"]
#: The deformation ratio ``d_r`` of paper 004: um/rad.
DEFORMATION_RATIO = QUANTITIES["deformation_ratio"]
#: Time from a stop of the reference (paper 004's windows): ms.
TIME_FROM_STOP = QUANTITIES["time_from_stop"]


def position_error(unit: str) -> Quantity:
    """The tracking error of a run whose error is stored in ``unit``: um for m, rad for rad.

    Raises
    ------
    ValueError
        For a unit that is neither.
    """
    if unit == "m":
        return POSITION_ERROR
    if unit == "rad":
        return POSITION_ERROR_ROTARY
    raise ValueError(f"error unit: expected 'm' or 'rad', got {unit!r}")


def position(unit: str) -> Quantity:
    """The table's position of a run whose error is in ``unit``: mm for m, rad for rad."""
    return QUANTITIES["position_rotary" if unit == "rad" else "position"]


#: The magnitude of a frequency response: dB.
FRF_MAGNITUDE = QUANTITIES["frf_magnitude"]
#: The phase of a frequency response: deg.
FRF_PHASE = QUANTITIES["frf_phase"]


def summary_quantity(path: str) -> Quantity | None:
    """The quantity of a value of ``summary.json`` by its path (a study's figure), if it has a unit.

    ``tracking_error...rms_m`` is a tracking error (um), ``..._rad`` of a
    rotary one (rad); a contour's ``_m`` is a contour error (um) but its
    ``radius_m`` (mm); ``_m_per_rad`` is ``d_r`` (um/rad); ``sysid.bode_db``
    and ``bode_deg`` a frequency response's level (dB) and phase (deg); any
    other ``_m`` a small displacement (um), ``_rad`` an angle (rad), ``_s`` a
    time (s), ``_hz`` a frequency, ``_Nm`` a torque. None: a ratio, a count,
    anything without a unit (shown as it is).
    """
    last = path.rsplit(".", 1)[-1].split("[", 1)[0]
    parts = [part.split("[", 1)[0] for part in path.split(".")]
    if path.startswith("sysid.keys") or any(part.endswith("ratio") for part in parts):
        return None  # relative errors, estimate / true
    if path.startswith("tracking_error"):
        if last.endswith("_m"):
            return POSITION_ERROR
        if last.endswith("_rad"):
            return POSITION_ERROR_ROTARY
    if path.startswith("contour") and last.endswith("_m"):
        return QUANTITIES["circle_radius"] if last == "radius_m" else CONTOUR_ERROR
    if last == "bode_db":
        return QUANTITIES["frf_misfit_magnitude"]
    if last == "bode_deg":
        return QUANTITIES["frf_misfit_phase"]
    for suffix, key in (
        ("_m_per_rad", "deformation_ratio"),
        ("_m_s2", "acceleration"),
        ("_m", "displacement"),
        ("_rad", "motor_angle"),
        ("_s", "time"),
        ("_hz", "frequency"),
        ("_Nm", "torque"),
    ):
        if last.endswith(suffix):
            return QUANTITIES[key]
    return None
