"""The identification's errors for a study point (``sweep`` with the plain backend).

A point whose scenario has the ``excitation`` term on is identified from its
own trajectory (the plant model of its plant section, no friction run) and
each fitted key compared with the point's plant value: the ``sysid`` block of
the point's summary, so that a study sweeps the excitation and the noise
against the identification error (docs/how-to/identify-your-axis.md, the study
``identification_excitation``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.identify.data import Record
from servo_axis.identify.driver import IdentifyError, identify


def _true_value(plant: dict[str, Any], key: str) -> float | None:
    """The plant's value of a fitted key (``modes.a[1]``, ``series_stiffness_N_per_m``), or None."""
    m = re.fullmatch(r"(modes\.\w+)\[(\d+)\]", key)
    if m:
        listed = plant[m.group(1)]
        i = int(m.group(2))
        return float(listed[i]) if i < len(listed) else None
    if key == "series_stiffness_N_per_m":
        r = plant["lead_m_per_rad"]
        return 1.0 / (
            1.0 / plant["axial_stiffness_N_per_m"] + r * r / plant["torsional_stiffness_Nm_per_rad"]
        )
    value = plant.get(key)
    return float(value) if isinstance(value, (int, float)) else None


def _unknown(plant: dict[str, Any]) -> dict[str, float]:
    """Every numeric key of the plant (each element of a list its own), NaN.

    So that the study's figures exist at every point, identified or not.
    """
    keys: dict[str, float] = {}
    for key, value in plant.items():
        if isinstance(value, list):
            keys.update({_name(f"{key}[{i}]"): math.nan for i in range(len(value))})
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            keys[_name(key)] = math.nan
    return keys


def _name(key: str) -> str:
    return re.sub(r"\W+", "_", key).strip("_")


def sysid_block(scenario: dict[str, Any], scenario_path: Path, traj: Any) -> dict[str, Any] | None:
    """``{"identified", "error", "max_key_error", "missing", "keys": {key: relative error}, "bode_db", "bode_deg"}``.

    The fitted modes are matched to the plant's by frequency (the nearest,
    within 20 %); ``max_key_error`` is over the keys matched, ``missing``
    names the plant's mode keys the fit did not give, ``spurious_hz`` the
    fitted modes that match none.

    None when the scenario has no excitation. A point whose data cannot be
    identified has ``identified`` false, the reason in ``error`` and NaN
    figures (a result, not a failure of the point).
    """
    record = Record(
        source=f"plain:{scenario_path}",
        scenario=scenario,
        scenario_path=Path(scenario_path),
        step=np.arange(traj.encoder_rad.size),
        encoder_rad=traj.encoder_rad,
        scale_m=traj.scale_m,
        reference_rad=traj.reference_rad,
        feedforward_Nm=traj.feedforward_Nm,
        command_Nm=traj.command_Nm,
    )
    if record.excitation() is None:
        return None
    plant = record.plant_values()
    keys: dict[str, float] = {}
    try:
        ident = identify(plant["model"], [record])
    except IdentifyError as err:
        return {
            "identified": False,
            "error": str(err),
            "max_key_error": math.nan,
            "missing": [],
            "spurious_hz": [],
            "keys": _unknown(plant),
            "bode_db": math.nan,
            "bode_deg": math.nan,
        }
    # The fitted modes matched to the plant's by frequency (the nearest within 20 %).
    fitted_f = {
        int(m.group(1)): k.value
        for k in ident.keys
        if (m := re.fullmatch(r"modes\.frequency_hz\[(\d+)\]", k.key))
    }
    true_f = [f for f in plant.get("modes.frequency_hz", []) if f > 0.0]
    match: dict[int, int] = {}
    for i, f in sorted(fitted_f.items(), key=lambda item: item[1]):
        free = [j for j in range(len(true_f)) if j not in match.values()]
        if free:
            j = min(free, key=lambda j: abs(true_f[j] - f))
            if abs(true_f[j] - f) <= 0.2 * true_f[j]:
                match[i] = j
    spurious = sorted(fitted_f[i] for i in fitted_f if i not in match)
    for k in ident.keys:
        m = re.fullmatch(r"(modes\.\w+)\[(\d+)\]", k.key)
        if m:
            if int(m.group(2)) not in match:
                continue
            key = f"{m.group(1)}[{match[int(m.group(2))]}]"
        else:
            key = k.key
        true = _true_value(plant, key)
        if true is not None and true != 0.0:
            keys[_name(key)] = abs(k.value / true - 1.0)
    # A mode the plant has and the fit did not give: NaN, and named.
    missing = sorted(k for k in _unknown(plant) if k.startswith("modes_") and k not in keys)
    bode = list(ident.bode.values())
    return {
        "identified": True,
        "error": "",
        "max_key_error": max(keys.values()) if keys else math.nan,
        "missing": missing,
        "spurious_hz": spurious,
        "keys": {**_unknown(plant), **keys},
        "bode_db": max(b.db for b in bode) if bode else math.nan,
        "bode_deg": max(b.deg for b in bode) if bode else math.nan,
    }
