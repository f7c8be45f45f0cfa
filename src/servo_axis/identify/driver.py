"""The identification of one axis: responses, the model's keys, friction, validation.

:func:`identify` takes the excitation runs (the ``measure_frf_*`` scenarios),
optionally a slow-reversal run (friction) and a held-out run (validation),
and returns an :class:`OfflineIdentification`: the plant section to write (the
model's own key names), each key's value, standard error and where it came
from, what could not be identified and why, the measured and fitted
responses and the validation figures. Nothing here imports rclpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.core.errors import ConfigError
from servo_axis.core.identification.offline import fit as sysfit
from servo_axis.core.identification.offline import friction_fit
from servo_axis.core.identification.offline.excitation import Excitation
from servo_axis.core.identification.offline.frf import FrequencyResponse, closed_loop_frf
from servo_axis.identify import MODELS
from servo_axis.identify.data import Record
from servo_axis.params.registry import PLANT_MODELS
from servo_axis.params.values import FeedforwardValues

#: A key whose standard error exceeds this fraction of its value is not determined.
UNDETERMINED = sysfit.UNDETERMINED


class IdentifyError(ConfigError):
    """Input the identification cannot use (the message says what and what to do)."""


@dataclass(frozen=True)
class KeyResult:
    """One plant key: value, standard error (NaN: not estimated), unit and how it was found."""

    key: str
    value: Any
    std: float
    source: str


@dataclass(frozen=True)
class Validation:
    """The fitted plant against the measured axis on a held-out run.

    ``nrmse_position``: ``rms(y_fit - y_meas) / rms(y_meas - mean)`` of the
    controlled output; ``nrmse_error``: the same of the tracking error;
    ``rms_error_measured`` / ``rms_error_fitted``: the tracking error of the
    same controller on each, and ``error_measured`` / ``error_fitted`` per
    step: at the table as a run's summary has it, ``R (r - y)`` in m, or
    ``r - y`` in rad for a rotary table (``unit``).
    """

    source: str
    nrmse_position: float
    nrmse_error: float
    rms_error_measured: float
    rms_error_fitted: float
    time_s: np.ndarray
    error_measured: np.ndarray
    error_fitted: np.ndarray
    unit: str = "m"


@dataclass(frozen=True)
class BodeFit:
    """The fitted response against the measured one, on the lines compared.

    Attributes
    ----------
    db, deg : float
        Largest ``|20 log10 |P_fit / P||`` (dB) and ``|angle(P_fit / P)|``
        (deg) over the lines compared (NaN: none).
    from_hz, to_hz : float
        The lowest and the highest line compared, Hz: the band the claim covers.
    lines : int
        How many lines were compared: the well-measured ones
        (:func:`well_measured`) of the band.
    """

    db: float
    deg: float
    from_hz: float
    to_hz: float
    lines: int


@dataclass
class OfflineIdentification:
    """What :func:`identify` found: the keys of a plant model fitted offline, from an axis's runs.

    Not the summary of paper 003's online identifier during a run
    (:class:`servo_axis.analysis.identification_summary.OnlineIdentification`).
    """

    model: str
    shared: dict[str, Any]
    plant: dict[str, Any]
    keys: list[KeyResult]
    notes: list[str]
    responses: dict[str, FrequencyResponse] = field(default_factory=dict)
    fitted: dict[str, np.ndarray] = field(default_factory=dict)
    friction: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    validation: Validation | None = None
    bode: dict[str, BodeFit] = field(default_factory=dict)

    def key(self, name: str) -> KeyResult:
        """The result of ``name``."""
        for k in self.keys:
            if k.key == name:
                return k
        raise KeyError(name)


def _excited(records: list[Record]) -> tuple[Record, Excitation]:
    if not records:
        raise IdentifyError("RUN_DIR: expected at least one excitation run (measure_frf_*)")
    record = records[0]
    for r in records:
        exc = r.excitation()
        if exc is None:
            raise IdentifyError(
                f"{r.source}: no excitation (feedforward excitation.enabled is false): identify "
                "fits runs of a measure_frf_* scenario; give a slow-reversal run with --friction "
                "and a held-out run with --validate"
            )
    if len(records) > 1:
        raise IdentifyError(
            f"RUN_DIR: expected one excitation run, got {len(records)}: give the others with "
            "--friction or --validate"
        )
    exc = record.excitation()
    assert exc is not None
    return record, exc


def responses(
    record: Record, exc: Excitation, sensors: tuple[str, ...]
) -> dict[str, FrequencyResponse]:
    """The closed-loop responses from the command torque to each sensor over the averaged periods.

    The responses are those of the sensor less the reference (at the motor,
    or at the table for the scale): the reference is known and independent
    of the excitation, and a move at constant velocity would otherwise leak
    into every line.
    """
    first, stop = exc.window
    win = record.window(first, stop)
    d = exc.torque_Nm(np.arange(first, stop))
    out = {}
    # Less the reference (the move the loop follows, not periodic): what is left is
    # the response to the excitation, the tracking error and the noise.
    for sensor in sensors:
        if sensor == "encoder":
            y = record.encoder_rad - record.reference_rad
        else:
            y = record.scale_m - record.lead_m_per_rad * record.reference_rad
        out[sensor] = closed_loop_frf(
            excitation=d,
            plant_input=record.command_Nm[win],
            output=y[win],
            period_samples=exc.period_samples,
            lines=exc.lines,
            control_period_s=exc.control_period_s,
        )
    return out


def _require_scale(record: Record, model: str) -> None:
    scale = record.scale_m
    if scale.size == 0 or float(np.ptp(scale)) == 0.0:
        raise IdentifyError(
            f"{record.source}: no linear scale in the data (scale_m is constant): model "
            f"{model!r} needs the table position for its table keys; record the scale or fit "
            "--model ball_screw"
        )


#: The Bode comparison takes the lines measured to this relative standard deviation.
BODE_MAX_STD = 0.02


def well_measured(frf: FrequencyResponse) -> np.ndarray:
    """Lines of coherence >= :data:`~servo_axis.core.identification.offline.fit.MIN_COHERENCE` and relative
    standard deviation <= :data:`BODE_MAX_STD` (a coherence from a few periods is biased
    high; the spread of the periods is the measurement's own error)."""
    rel = frf.std / np.abs(frf.response)
    ok = np.where(np.isfinite(rel), rel <= BODE_MAX_STD, True)
    return np.asarray((frf.coherence >= sysfit.MIN_COHERENCE) & ok)


def bode_errors(
    frf: FrequencyResponse, model: np.ndarray, up_to_hz: float, from_hz: float = 0.0
) -> BodeFit:
    """The model against the measurement on the well-measured lines of ``from_hz .. up_to_hz``.

    The band the claim covers is that of the lines compared
    (:attr:`BodeFit.from_hz` .. :attr:`BodeFit.to_hz`).
    """
    keep = well_measured(frf) & (frf.frequency_hz <= up_to_hz) & (frf.frequency_hz >= from_hz)
    if not keep.any():
        return BodeFit(math.nan, math.nan, from_hz, up_to_hz, 0)
    ratio = model[keep] / frf.response[keep]
    compared = frf.frequency_hz[keep]
    return BodeFit(
        db=float(np.max(np.abs(20 * np.log10(np.abs(ratio))))),
        deg=float(np.max(np.abs(np.degrees(np.angle(ratio))))),
        from_hz=float(compared.min()),
        to_hz=float(compared.max()),
        lines=int(keep.sum()),
    )


def modes_outside_claim(
    sensor: str, frf: FrequencyResponse, model: np.ndarray, fit: BodeFit, modes_hz: list[float]
) -> str | None:
    """A note on fitted modes outside the band of the accuracy claim, or None.

    Near a lightly damped mode the periods' spread may exceed 2 % on every
    line, so the claim (:func:`bode_errors`) stops short of it. What the
    lines there do show is said instead: the largest residual of the fit on
    the lines of coherence >= 0.9 outside the claim's band, in units of each
    line's own standard deviation.
    """
    outside = [f for f in modes_hz if not fit.from_hz <= f <= fit.to_hz]
    if not outside or fit.lines == 0:
        return None
    f = frf.frequency_hz
    coherent = (frf.coherence >= sysfit.MIN_COHERENCE) & ((f < fit.from_hz) | (f > fit.to_hz))
    relative = frf.std / np.abs(frf.response)
    coherent &= np.isfinite(relative) & (relative > 0)
    modes = ", ".join(f"{m:.4g}" for m in outside)
    head = (
        f"Bode {sensor}: the fitted mode(s) at {modes} Hz lie outside the lines of the claim "
        f"({fit.from_hz:.4g} to {fit.to_hz:.4g} Hz), where the periods' spread is above 2 %"
    )
    if not coherent.any():
        return head + "; no line there has a coherence >= 0.9"
    misfit = np.abs(model[coherent] / frf.response[coherent] - 1.0) / relative[coherent]
    return (
        f"{head}; there the fit is within {float(np.max(misfit)):.2g} standard deviations of "
        f"each of the {int(coherent.sum())} lines of coherence >= 0.9 "
        f"({float(f[coherent].min()):.4g} to {float(f[coherent].max()):.4g} Hz; the residual "
        "panel of the report shows each with its error bar)"
    )


def _template(record: Record, model: str) -> dict[str, Any]:
    """The run's plant values when its model is ``model`` (a template for the keys not fitted)."""
    values = record.plant_values()
    schema = PLANT_MODELS.lookup(model, "--model").schema  # a broken one: one line
    if values.model == model:
        return {k: values[k] for k in schema}
    return {k: p.default for k, p in schema.items()}


def _ball_screw(
    record: Record, exc: Excitation, ident: OfflineIdentification, template: dict[str, Any]
) -> None:
    t = exc.control_period_s
    frf = responses(record, exc, ("encoder",))["encoder"]
    ident.responses["encoder"] = frf
    fit = sysfit.fit_rigid_modes(frf, control_period_s=t)
    n = sum(1 for name in fit.names if name.startswith("modes.frequency_hz"))
    source = f"frequency response ({frf.periods} periods, {int((frf.coherence >= sysfit.MIN_COHERENCE).sum())} lines)"
    for name in ("inertia_kgm2", "damping_Nms_per_rad"):
        ident.keys.append(KeyResult(name, fit.value(name), fit.error(name), source))
        ident.plant[name] = fit.value(name)
    lists: dict[str, list[float]] = {"frequency_hz": [], "zeta": [], "a": []}
    order = sorted(range(n), key=lambda i: fit.value(f"modes.frequency_hz[{i}]"))
    for rank, i in enumerate(order):
        for part in ("frequency_hz", "zeta", "a"):
            key = f"modes.{part}[{i}]"
            lists[part].append(fit.value(key))
            ident.keys.append(
                KeyResult(f"modes.{part}[{rank}]", fit.value(key), fit.error(key), source)
            )
    for part, listed in lists.items():
        ident.plant[f"modes.{part}"] = listed if listed else [0.0]
    band = exc.max_frequency_hz
    nyquist = 0.5 / t
    beyond = [
        f
        for f, z in zip(template["modes.frequency_hz"], template["modes.zeta"], strict=False)
        if f > 0 and z > 0 and f > band
    ]
    if beyond:
        ident.notes.append(
            f"modes.*: the template's modes at {', '.join(f'{f:g}' for f in beyond)} Hz lie above "
            f"the excitation band (max {band:g} Hz"
            + (f", Nyquist {nyquist:g} Hz" if any(f > nyquist for f in beyond) else "")
            + "): not identified and not written; measure with a shorter control period and a "
            "wider band to get them"
        )
    if fit.dropped:
        ident.notes.append(
            "modes.*: peaks at "
            + ", ".join(f"{f:.4g}" for f in sorted(fit.dropped))
            + " Hz looked like modes but the data do not determine them (standard error above "
            "half the value): left out; more amplitude or periods to resolve them"
        )
    if n == 0:
        ident.notes.append(
            f"modes.*: no resonance above the rigid body in {exc.min_frequency_hz:g} .. {band:g} Hz: "
            "none written"
        )
    td = fit.value("dead_time_s")
    h = template["sim_step_s"]
    if td > 0 and abs(t / 1e-5 - round(t / 1e-5)) < 1e-9:
        h = 1e-5
    ident.plant["sim_step_s"] = h
    ident.plant["dead_time_s"] = round(td / h) * h
    ident.keys.append(KeyResult("dead_time_s", td, fit.error("dead_time_s"), source))
    model_resp = sysfit.rigid_modes_response(
        {name: fit.value(name) for name in fit.names}, frf.frequency_hz, modes=n, control_period_s=t
    )
    ident.fitted["encoder"] = model_resp
    # Over the whole band measured, which holds every fitted mode.
    ident.bode["encoder"] = bode_errors(frf, model_resp, band, from_hz=exc.min_frequency_hz)
    note = modes_outside_claim(
        "encoder", frf, model_resp, ident.bode["encoder"], lists["frequency_hz"]
    )
    if note:
        ident.notes.append(note)


def _elastic(
    record: Record, exc: Excitation, ident: OfflineIdentification, template: dict[str, Any]
) -> None:
    _require_scale(record, "elastic_ball_screw")
    t = exc.control_period_s
    r = record.lead_m_per_rad
    both = responses(record, exc, ("encoder", "scale"))
    ident.responses.update(both)
    fit = sysfit.fit_two_inertia(
        both["encoder"], both["scale"], lead_m_per_rad=r, control_period_s=t
    )
    source = f"frequency responses of encoder and scale ({both['encoder'].periods} periods)"
    for name in sysfit.TWO_INERTIA_KEYS:
        if name == "stiffness_N_per_m":
            continue
        ident.keys.append(KeyResult(name, fit.value(name), fit.error(name), source))
        ident.plant[name] = fit.value(name)
    kh, kh_std = fit.value("stiffness_N_per_m"), fit.error("stiffness_N_per_m")
    kt = template["torsional_stiffness_Nm_per_rad"]
    inv = 1.0 / kh - r * r / kt
    if inv <= 0:
        kt = 1e3 * kh * r * r
        inv = 1.0 / kh - r * r / kt
        ident.notes.append(
            "torsional_stiffness_Nm_per_rad: the template's is softer than the measured "
            f"series stiffness; written as {kt:.4g} (1000 times the measured)"
        )
    ka = 1.0 / inv
    ident.plant["axial_stiffness_N_per_m"] = ka
    ident.plant["torsional_stiffness_Nm_per_rad"] = kt
    ident.keys.append(KeyResult("series_stiffness_N_per_m", kh, kh_std, source))
    ident.keys.append(KeyResult("axial_stiffness_N_per_m", ka, kh_std * (ka / kh) ** 2, source))
    ident.notes.append(
        "axial_stiffness_N_per_m, torsional_stiffness_Nm_per_rad: only their series "
        f"k_h = 1 / (1/k_a + R^2/k_t) = {kh:.4g} N/m is in the data; k_t is the template's "
        f"({kt:.4g} N m/rad) and k_a follows from k_h"
    )
    if template.get("contact_zone_m", 0.0) > 0.0:
        ident.notes.append(
            "contact_zone_m, contact_stiffness_ratio: the soft zone of the ball contacts makes "
            "the response amplitude dependent; the fit is the loaded (linear) stiffness, the "
            "contact keys are the template's"
        )
    model = sysfit.two_inertia_response(
        {n: fit.value(n) for n in fit.names},
        both["encoder"].frequency_hz,
        lead_m_per_rad=r,
        control_period_s=t,
    )
    ident.fitted["encoder"], ident.fitted["scale"] = model[0], model[1]
    for sensor in ("encoder", "scale"):
        ident.bode[sensor] = bode_errors(
            both[sensor],
            ident.fitted[sensor],
            exc.max_frequency_hz,
            from_hz=exc.min_frequency_hz,
        )


def _tilting(
    record: Record, exc: Excitation, ident: OfflineIdentification, template: dict[str, Any]
) -> None:
    t = exc.control_period_s
    fit = sysfit.fit_tilting_table(
        angle_rad=record.encoder_rad, torque_Nm=record.command_Nm, control_period_s=t
    )
    source = f"time-domain least squares of 003 eq. (2) ({fit.points} samples, block bootstrap)"
    for name in sysfit.TILTING_KEYS:
        ident.keys.append(KeyResult(name, fit.value(name), fit.error(name), source))
        ident.plant[name] = fit.value(name)
        if fit.value(name) <= 0.0:
            raise IdentifyError(
                f"{name}: the fit gives {fit.value(name):.4g} +- {fit.error(name):.2g}, not > 0: "
                "the data do not determine it (more motion, a wider angle range)"
            )
    frf = responses(record, exc, ("encoder",))["encoder"]
    ident.responses["encoder"] = frf
    # The linearised table about the run's angles: 1 / (J s^2 + D s + U cos th).
    first, stop = exc.window
    cos_mean = float(np.mean(np.cos(record.encoder_rad[record.window(first, stop)])))
    from servo_axis.core.identification.offline.models import sampled_response

    j, d, u = fit.value("inertia_kgm2"), fit.value("damping_Nms_per_rad"), fit.value("unbalance_Nm")
    a = np.array([[0.0, 1.0], [-u * cos_mean / j, -d / j]])
    b = np.array([[0.0], [1.0 / j]])
    c = np.array([[1.0, 0.0]])
    ident.fitted["encoder"] = sampled_response(
        a, b, c, frequency_hz=frf.frequency_hz, control_period_s=t
    )[0]
    # The swing's own harmonics are periodic in the excitation's period too when the
    # two periods are commensurate: the lowest lines carry them. Compared from its
    # fourth harmonic on.
    ref = _ff_values(record).reference
    swing_hz = ref.frequency_hz if ref.kind == "sine" else 0.0
    ident.bode["encoder"] = bode_errors(
        frf,
        ident.fitted["encoder"],
        exc.max_frequency_hz,
        from_hz=max(4.0 * swing_hz, exc.min_frequency_hz),
    )
    ident.notes.append(
        "tilting table: the keys come from the time-domain fit (the model is nonlinear in the "
        "angle); the Bode comparison is the model linearised about the run's mean cos(angle) "
        f"= {cos_mean:.3f}, with the Coulomb friction left out, from {4.0 * swing_hz:g} Hz "
        "(4 times the swing's frequency) on"
    )


def _friction_data(
    runs: list[Record], inertia_kgm2: float, damping_Nms_per_rad: float
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Angle, direction and friction torque ``K_T i - J a_r - D v_r`` of each slow-reversal run.

    The estimate of :func:`servo_axis.identify.friction.estimate_friction_torque`
    (the friction identification of ``friction-table`` and ``gms-fit``),
    with the identified ``J, D`` instead of the run's nominal ones.
    """
    from servo_axis.identify.friction import estimate_friction_torque

    angles, directions, torques = [], [], []
    for rec in runs:
        if rec.excitation() is not None:
            raise IdentifyError(
                f"--friction {rec.source}: an excitation run, expected a slow reversal"
            )
        torques.append(
            estimate_friction_torque(
                reference_rad=rec.reference_rad,
                motor_torque_Nm=rec.command_Nm,
                period_s=rec.period_s,
                inertia_kgm2=inertia_kgm2,
                damping_Nms_per_rad=damping_Nms_per_rad,
            )
        )
        angles.append(rec.encoder_rad)
        directions.append(np.sign(np.gradient(rec.reference_rad)))
    return angles, directions, torques


def _friction_curve(
    ident: OfflineIdentification,
    runs: list[Record],
    angles: list[np.ndarray],
    directions: list[np.ndarray],
    torques: list[np.ndarray],
    fit: sysfit.Fit,
    elements: int,
) -> None:
    r = runs[0].lead_m_per_rad
    model = friction_fit.maxwell_slip_torque(
        angles[0],
        directions[0],
        rolling_coulomb_Nm=fit.value("rolling_coulomb_Nm"),
        presliding_width_m=fit.value("presliding_width_m"),
        coulomb_Nm=fit.value("coulomb_Nm"),
        lead_m_per_rad=r,
        elements=elements,
    )
    ident.friction = (runs[0].reference_rad * r, torques[0], model)


def _friction_ball_screw(
    runs: list[Record], ident: OfflineIdentification, template: dict[str, Any]
) -> None:
    r = runs[0].lead_m_per_rad
    angles, directions, torques = _friction_data(
        runs, ident.plant["inertia_kgm2"], ident.plant["damping_Nms_per_rad"]
    )
    elements = int(template["friction.elements"])
    fit = friction_fit.fit_maxwell_slip(
        angle_rad=angles,
        direction=directions,
        torque_Nm=torques,
        lead_m_per_rad=r,
        elements=elements,
    )
    source = (
        f"{len(runs)} slow-reversal run(s) (Maxwell-slip + Coulomb law along the measured angle)"
    )
    names = {
        "rolling_coulomb_Nm": "friction.rolling_coulomb_Nm",
        "presliding_width_m": "friction.presliding_width_m",
        "coulomb_Nm": "friction.coulomb_Nm",
    }
    for name, key in names.items():
        ident.keys.append(KeyResult(key, fit.value(name), fit.error(name), source))
        ident.plant[key] = fit.value(name)
    ident.plant["friction.elements"] = elements
    ident.plant["friction.viscous_Nms_per_rad"] = 0.0
    ident.notes.append(
        "friction.viscous_Nms_per_rad: viscous friction and the damping D are one term in the "
        "data; D holds both, the viscous key is written 0"
    )
    _friction_curve(ident, runs, angles, directions, torques, fit, elements)


def _friction_elastic(
    runs: list[Record], ident: OfflineIdentification, template: dict[str, Any]
) -> None:
    """Nut and guide friction: the total from the motor torque, the guide's share from the deformation."""
    for rec in runs:
        _require_scale(rec, "elastic_ball_screw")
    r = runs[0].lead_m_per_rad
    jn = ident.plant["motor_inertia_kgm2"] + ident.plant["table_mass_kg"] * r * r
    bn = ident.plant["motor_damping_Nms_per_rad"] + ident.plant["table_damping_Ns_per_m"] * r * r
    angles, directions, torques = _friction_data(runs, jn, bn)
    elements = int(template["friction_elements"])
    # The guide's friction loads the screw: F_s = k_h (R th - x) = f_g + C_t v on a slow move;
    # the deformation's offset (quantisation, the start) drops out of the branches' difference.
    kh = ident.key("series_stiffness_N_per_m").value
    ct = ident.plant["table_damping_Ns_per_m"]
    up_force, down_force = [], []
    for rec, sgn in zip(runs, directions, strict=True):
        force = kh * (r * rec.encoder_rad - rec.scale_m) - ct * np.gradient(
            rec.scale_m, rec.period_s
        )
        speed = np.abs(np.gradient(rec.reference_rad))
        sliding = speed > 0.85 * speed.max()  # past the pre-sliding of a 2 A stroke
        up_force.append(force[sliding & (sgn > 0)])
        down_force.append(force[sliding & (sgn < 0)])
    up, down = np.concatenate(up_force), np.concatenate(down_force)
    if up.size < 10 or down.size < 10:
        raise IdentifyError(
            f"--friction {runs[0].source}: expected sliding in both directions, got "
            f"{up.size} and {down.size} samples"
        )
    guide = max(0.5 * float(np.mean(up) - np.mean(down)), 0.0)
    guide_std = 0.5 * math.sqrt(np.var(up) / up.size + np.var(down) / down.size)
    fit = friction_fit.fit_nut_and_guide(
        angle_rad=angles,
        table_m=[rec.scale_m for rec in runs],
        torque_Nm=torques,
        guide_friction_N=guide,
        lead_m_per_rad=r,
        elements=elements,
    )
    nut, width = fit.value("nut_friction_Nm"), fit.value("presliding_width_m")
    source = f"{len(runs)} slow-reversal run(s)"
    ident.plant.update(
        nut_friction_Nm=nut,
        nut_presliding_m=width,
        guide_friction_N=guide,
        guide_presliding_m=width,
        friction_elements=elements,
    )
    ident.keys += [
        KeyResult("nut_friction_Nm", nut, fit.error("nut_friction_Nm"), source),
        KeyResult("guide_friction_N", guide, guide_std, source + " (deformation k_h (R th - x))"),
        KeyResult("nut_presliding_m", width, fit.error("presliding_width_m"), source),
        KeyResult("guide_presliding_m", width, fit.error("presliding_width_m"), source),
    ]
    ident.notes.append(
        "nut_presliding_m, guide_presliding_m: a slow reversal moves nut and table nearly "
        "together, so one pre-sliding width is fitted for both (the nut's set on the motor "
        "angle, the guide's on the table position)"
    )
    model = friction_fit.maxwell_slip_torque(
        angles[0],
        np.zeros(angles[0].size),
        rolling_coulomb_Nm=nut,
        presliding_width_m=width,
        coulomb_Nm=0.0,
        lead_m_per_rad=r,
        elements=elements,
    ) + friction_fit.maxwell_slip_torque(
        runs[0].scale_m / r,
        np.zeros(angles[0].size),
        rolling_coulomb_Nm=r * guide,
        presliding_width_m=width,
        coulomb_Nm=0.0,
        lead_m_per_rad=r,
        elements=elements,
    )
    ident.friction = (runs[0].reference_rad * r, torques[0], model)


def _ff_values(rec: Record) -> FeedforwardValues:
    return rec.checked.feedforward


def identify(
    model: str,
    runs: list[Record],
    *,
    friction: list[Record] | None = None,
    validation: Record | None = None,
) -> OfflineIdentification:
    """Identify ``model``'s keys from the excitation run, the friction run and validate.

    Raises IdentifyError (one line) for input that cannot be used.
    """
    if model not in MODELS:
        raise IdentifyError(f"--model: expected one of {list(MODELS)}, got {model!r}")
    record, exc = _excited(runs)
    if not np.all(np.isfinite(record.command_Nm)):
        raise IdentifyError(f"{record.source}: no command torque recorded (the command topic)")
    template = _template(record, model)
    shared = {
        k: v
        for k, v in record.plant_values().items()
        if k in ("control_period_s", "lead_m_per_rad", "axis")
    }
    ident = OfflineIdentification(
        model=model, shared=shared, plant=dict(template), keys=[], notes=[]
    )
    ident.plant["model"] = model
    try:
        if model == "ball_screw":
            _ball_screw(record, exc, ident, template)
        elif model == "elastic_ball_screw":
            _elastic(record, exc, ident, template)
        else:
            _tilting(record, exc, ident, template)
    except sysfit.IdentificationError as err:
        raise IdentifyError(f"{record.source}: model {model!r}: {err}") from None
    for k in ident.keys:
        if not (math.isfinite(k.std) and k.std <= UNDETERMINED * abs(k.value)):
            raise IdentifyError(
                f"{record.source}: model {model!r}: the data do not determine {k.key} "
                f"({k.value:.4g} +- {k.std:.2g}): the run does not show what the model's keys "
                "need (another --model, a wider band, more amplitude)"
            )
    kt = float(_ff_values(record).nominal.torque_constant_Nm_per_A)
    ident.plant["torque_constant_Nm_per_A"] = kt
    ident.notes.append(
        "torque_constant_Nm_per_A: the data relate the commanded torque to the motion, not "
        f"the current: written as the run's nominal K_T ({kt:g} N m/A)"
    )
    if friction:
        try:
            if model == "ball_screw":
                _friction_ball_screw(friction, ident, template)
            elif model == "elastic_ball_screw":
                _friction_elastic(friction, ident, template)
            else:
                ident.notes.append(
                    "--friction: the tilting table's C comes from its own fit; runs not used"
                )
        except sysfit.IdentificationError as err:
            raise IdentifyError(f"--friction {friction[0].source}: {err}") from None
    elif model != "tilting_table":
        ident.notes.append(
            "friction: no slow-reversal run given (--friction): the template's keys written"
        )
    if validation is not None:
        ident.validation = validate(ident, validation)
    return ident


def fitted_scenario(ident: OfflineIdentification, base: Record) -> dict[str, Any]:
    """``base``'s scenario with its plant section replaced by the identified one."""
    import copy

    scenario = copy.deepcopy(base.scenario)
    plant = scenario.setdefault("plant", {}).setdefault("ros__parameters", {})
    keep = {k: plant[k] for k in ("noise_seed",) if k in plant}
    schema = PLANT_MODELS.lookup(ident.model, "--model").schema
    nested: dict[str, Any] = {}
    for key, value in ident.plant.items():
        if key != "model" and key not in schema:
            continue
        _set(nested, key, _plain(value))
    nested.update(keep)
    scenario["plant"]["ros__parameters"] = nested
    return scenario


def _plain(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    return value


def _set(tree: dict[str, Any], dotted: str, value: Any) -> None:
    parts = dotted.split(".")
    for p in parts[:-1]:
        tree = tree.setdefault(p, {})
    tree[parts[-1]] = value


def validate(ident: OfflineIdentification, held_out: Record) -> Validation:
    """Run ``held_out``'s scenario on the identified plant (plain calls) and compare."""
    import tempfile

    import yaml

    from servo_axis.analysis.signals import tracking
    from servo_axis.analysis.tracking import error_unit, position_scale
    from servo_axis.simulate import simulate

    if held_out.excitation() is not None:
        raise IdentifyError(
            f"--validate {held_out.source}: an excitation run, expected a held-out one"
        )
    scenario = fitted_scenario(ident, held_out)
    absolute_files(scenario, held_out.scenario_path.parent)
    with tempfile.TemporaryDirectory(prefix="servo_axis_identify_") as tmp:
        path = Path(tmp) / "fitted.yaml"
        path.write_text(yaml.safe_dump(scenario, sort_keys=False))
        traj = simulate(path, steps=int(held_out.step[-1]) + 1)

    class _Sig:
        def __init__(self, enc: np.ndarray, scale: np.ndarray, ref: np.ndarray) -> None:
            self.encoder_rad, self.scale_m, self.reference_rad = enc, scale, ref
            self.step = np.arange(enc.size)

    k = held_out.step
    meas = _Sig(held_out.encoder_rad, held_out.scale_m, held_out.reference_rad)
    sim = _Sig(traj.encoder_rad[k], traj.scale_m[k], traj.reference_rad[k])
    target_m, y_m = tracking(held_out.checked, held_out.scenario_path, meas)  # type: ignore[arg-type]
    target_s, y_s = tracking(held_out.checked, held_out.scenario_path, sim)  # type: ignore[arg-type]
    # At the table, as the run's summary has it: R (r - y) in m, r - y in rad on a rotary table.
    values = held_out.plant_values()
    scale = position_scale(values)
    e_m, e_s = scale * (target_m - y_m), scale * (target_s - y_s)

    def nrmse(fit: np.ndarray, meas: np.ndarray) -> float:
        den = float(np.sqrt(np.mean((meas - meas.mean()) ** 2)))
        return float(np.sqrt(np.mean((fit - meas) ** 2)) / den) if den > 0 else math.nan

    return Validation(
        source=held_out.source,
        nrmse_position=nrmse(y_s, y_m),
        nrmse_error=nrmse(e_s, e_m),
        rms_error_measured=float(np.sqrt(np.mean(e_m**2))),
        rms_error_fitted=float(np.sqrt(np.mean(e_s**2))),
        time_s=k * held_out.period_s,
        error_measured=e_m,
        error_fitted=e_s,
        unit=error_unit(values),
    )


def absolute_files(node: Any, directory: Path) -> None:
    """Make every ``file`` key absolute (relative to ``directory``): the copy runs elsewhere."""
    from servo_axis.params.scenario import resolve_table

    if isinstance(node, dict):
        for key, value in node.items():
            if key == "file" and isinstance(value, str):
                node[key] = resolve_table(value, directory)
            else:
                absolute_files(value, directory)
