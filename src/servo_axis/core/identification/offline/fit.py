"""Parametric fits of the plant models' own keys, each value with a standard error.

Frequency domain (:func:`fit_response`): weighted nonlinear least squares on
the log of the response, ``r = log(P_model / P_meas) / sigma_rel`` (real part:
the magnitude error in neper, imaginary: the phase error in rad), at the
lines whose coherence is at least ``min_coherence``; ``sigma_rel = std / |P|``
from the spread of the periods (:mod:`servo_axis.core.identification.offline.frf`), with a
floor so that no line dominates. The log makes a decade of magnitude weigh
as much as another (a rigid body falls 40 dB/decade), and the per-line
weight is the measurement's own uncertainty (the maximum-likelihood weight
for small errors; Pintelon & Schoukens 2012 Ch. 9). Positive keys are
fitted as their logarithm. Standard errors from the Jacobian at the
solution: ``cov = s^2 (J^T J)^-1`` with ``s^2`` the residual variance per
degree of freedom, so that model error widens them too.

Time domain (:func:`fit_tilting_table`): paper 003 eq. (2) is linear in
``J, D, U, C`` but nonlinear in the angle (``sin th``, ``sgn th'``):
``J th'' + D th' + U sin th + C sgn th' = T``. Every regressor and the
torque pass the same zero-phase low-pass (so the relation holds filtered),
the samples where the table sticks are left out, ordinary least squares,
and a moving-block bootstrap for the standard errors (the residuals of
filtered signals are correlated, which the OLS formula ignores).

The friction fits of a slow reversal are in
:mod:`servo_axis.core.identification.offline.friction_fit`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import median_filter
from scipy.optimize import least_squares
from scipy.signal import butter, find_peaks, sosfiltfilt

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.identification.offline.frf import FrequencyResponse
from servo_axis.core.identification.offline.models import rigid_modes, sampled_response, two_inertia

FloatArray = NDArray[np.float64]

#: Lines below this coherence are not fitted (and not compared).
MIN_COHERENCE = 0.9
#: Floor of the relative uncertainty of a line in the weights.
SIGMA_FLOOR = 2e-3
#: A resonance is looked for at lines measured to this relative standard deviation.
MODE_MAX_STD = 0.1
#: At most this many modes are fitted (the highest peaks).
MAX_MODES = 6
#: A key whose standard error exceeds this fraction of its value is not determined.
UNDETERMINED = 0.5


class IdentificationError(ConfigError):
    """The data cannot determine what was asked (the message says which key and why)."""


@dataclass(frozen=True)
class Fit:
    """Fitted values with their standard errors.

    Attributes
    ----------
    names : tuple of str
        The keys, in order.
    values, std : ndarray
        Value and standard error of each key (its own unit).
    rms_residual : float
        RMS of the weighted residuals (about 1 when the model explains the
        data to its noise).
    points : int
        Residuals fitted (two per line and response).
    dropped : tuple of float
        Frequencies (Hz) of peaks tried as modes and left out: the data did
        not determine them (:func:`fit_rigid_modes`).
    """

    names: tuple[str, ...]
    values: FloatArray
    std: FloatArray
    rms_residual: float
    points: int
    dropped: tuple[float, ...] = ()

    def value(self, name: str) -> float:
        """The fitted value of ``name``."""
        return float(self.values[self.names.index(name)])

    def error(self, name: str) -> float:
        """The standard error of ``name``."""
        return float(self.std[self.names.index(name)])


@dataclass(frozen=True)
class Parameter:
    """A fitted parameter: its name, its start, ``log`` (positive) or linear, bounds."""

    name: str
    start: float
    log: bool = True
    lower: float = -np.inf
    upper: float = np.inf


def _weights(frf: FrequencyResponse, min_coherence: float) -> tuple[NDArray[np.bool_], FloatArray]:
    keep = frf.coherence >= min_coherence
    rel = frf.std / np.abs(frf.response)
    rel = np.where(np.isfinite(rel), rel, 0.05)
    # A spread from a few periods is itself noisy (with 4, a line's variance is
    # chi-square with 6 degrees of freedom): the noise's spectrum is smooth, so the
    # weights take the median of 9 neighbouring lines, and no single line with a
    # small spread by chance dominates the fit.
    rel = median_filter(rel, size=9, mode="nearest")
    # std is that of the complex value: each of log-magnitude and phase has std / sqrt(2).
    return keep, math.sqrt(2.0) / np.maximum(rel, SIGMA_FLOOR)


def fit_response(
    model: Callable[[dict[str, float]], Sequence[NDArray[np.complex128]]],
    parameters: Sequence[Parameter],
    data: Sequence[FrequencyResponse],
    *,
    min_coherence: float = MIN_COHERENCE,
    max_frequency_hz: float = np.inf,
) -> Fit:
    """Fit ``model`` to measured responses by weighted least squares on the log.

    Parameters
    ----------
    model : callable
        ``model(values) -> [P_1, P_2, ...]``: the response at each of
        ``data``'s line frequencies, one array per measured response.
    parameters : sequence of Parameter
        The keys fitted, with start values.
    data : sequence of FrequencyResponse
        The measured responses.
    min_coherence : float
        Lines below it are left out.
    max_frequency_hz : float
        Lines above it are left out, Hz.
    """
    masks, weights = [], []
    for frf in data:
        keep, w = _weights(frf, min_coherence)
        keep = keep & (frf.frequency_hz <= max_frequency_hz)
        masks.append(keep)
        weights.append(w)
    points = 2 * int(sum(m.sum() for m in masks))
    if points <= len(parameters):
        raise IdentificationError(
            f"coherence: expected more than {len(parameters) // 2} lines with coherence >= "
            f"{min_coherence:g}, got {points // 2}: more excitation amplitude or periods"
        )

    def values_of(theta: FloatArray) -> dict[str, float]:
        return {
            p.name: float(math.exp(t) if p.log else t)
            for p, t in zip(parameters, theta, strict=True)
        }

    def residual(theta: FloatArray) -> FloatArray:
        out = []
        for frf, keep, w, p in zip(data, masks, weights, model(values_of(theta)), strict=True):
            r = np.log(p[keep] / frf.response[keep]) * w[keep]
            out.append(r.real)
            out.append(r.imag)
        return np.concatenate(out)

    def bound(p: Parameter, x: float) -> float:
        if not p.log:
            return x
        return math.log(x) if 0.0 < x < np.inf else (-np.inf if x <= 0.0 else np.inf)

    lo = np.array([bound(p, p.lower) for p in parameters])
    hi = np.array([bound(p, p.upper) for p in parameters])
    x0 = np.array([math.log(p.start) if p.log else p.start for p in parameters])
    # A start on a bound is moved just inside it.
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    x0 = np.minimum(np.maximum(x0, lo + 1e-6 * span), hi - 1e-6 * span)
    sol = least_squares(residual, x0, bounds=(lo, hi), x_scale="jac", max_nfev=400)
    theta = sol.x
    jac = sol.jac
    dof = max(points - len(parameters), 1)
    s2 = float(2.0 * sol.cost / dof)
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
        se_theta = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        se_theta = np.full(theta.size, np.inf)
    vals = values_of(theta)
    values = np.array([vals[p.name] for p in parameters])
    std = np.array(
        [abs(v) * s if p.log else s for p, v, s in zip(parameters, values, se_theta, strict=True)]
    )
    return Fit(
        names=tuple(p.name for p in parameters),
        values=values,
        std=std,
        rms_residual=math.sqrt(s2 * dof / points),
        points=points,
    )


# ----------------------------------------------------------------------- rigid body with modes


def _mode_keys(i: int) -> tuple[str, str, str]:
    return (f"modes.frequency_hz[{i}]", f"modes.zeta[{i}]", f"modes.a[{i}]")


def rigid_modes_response(
    values: dict[str, float], frequency_hz: ArrayLike, *, modes: int, control_period_s: float
) -> NDArray[np.complex128]:
    """The sampled response of :func:`~servo_axis.core.identification.offline.models.rigid_modes` from fit values."""
    listed = tuple(tuple(values[k] for k in _mode_keys(i)) for i in range(modes))
    a, b, c = rigid_modes(
        inertia_kgm2=values["inertia_kgm2"],
        damping_Nms_per_rad=values["damping_Nms_per_rad"],
        modes=listed,  # type: ignore[arg-type]
    )
    out = sampled_response(
        a,
        b,
        c,
        frequency_hz=frequency_hz,
        control_period_s=control_period_s,
        dead_time_s=values.get("dead_time_s", 0.0),
    )
    return np.asarray(out[0], dtype=np.complex128)


def rigid_start(frf: FrequencyResponse, *, below_hz: float) -> tuple[float, float]:
    """``(J, D)`` from ``1 / P = -w^2 J + j w D`` by linear least squares below ``below_hz``."""
    keep = (frf.frequency_hz <= below_hz) & (frf.coherence >= MIN_COHERENCE)
    if keep.sum() < 2:
        keep = frf.coherence >= MIN_COHERENCE
    if keep.sum() < 2:
        raise IdentificationError(
            "inertia_kgm2: expected at least 2 lines with coherence >= "
            f"{MIN_COHERENCE:g} to start the rigid body from, got {int(keep.sum())}"
        )
    w = 2.0 * math.pi * frf.frequency_hz[keep]
    inv = 1.0 / frf.response[keep]
    # Re(1/P) = -w^2 J (the sampling's half-sample delay aside), Im(1/P) = w D.
    j = float(-np.sum(inv.real * w**2) / np.sum(w**4))
    d = float(np.sum(inv.imag * w) / np.sum(w**2))
    return abs(j), max(abs(d), 1e-6 * abs(j))


def find_modes(
    frf: FrequencyResponse,
    *,
    inertia_kgm2: float,
    damping_Nms_per_rad: float,
    min_ratio: float = 1.5,
) -> list[tuple[float, float, float]]:
    """Resonances of the measured response against the rigid body: start values of the modes.

    A mode shows as a peak of ``|P / P_rigid|`` (``1 + j a / (2 zeta)`` at its
    frequency); peaks above ``min_ratio`` at lines of good coherence and a
    relative standard deviation of at most :data:`MODE_MAX_STD` are taken
    (the :data:`MAX_MODES` highest), with ``zeta`` from the half-power width
    and ``a`` from the peak.
    """
    s = 2j * math.pi * frf.frequency_hz
    ratio = frf.response * (inertia_kgm2 * s * s + damping_Nms_per_rad * s)
    # Only lines measured well enough that a peak is the plant's, not the noise's.
    rel = frf.std / np.abs(frf.response)
    good = (frf.coherence >= MIN_COHERENCE) & np.where(np.isfinite(rel), rel <= MODE_MAX_STD, True)
    # A resonance spans lines (its half-power width 2 zeta f); a spike of one line is
    # the noise's: the peaks are looked for in the median of 5 lines.
    mag = median_filter(np.where(good, np.abs(ratio), 0.0), size=5, mode="nearest")
    peaks, _ = find_peaks(mag, height=min_ratio, prominence=0.3 * min_ratio)
    peaks = sorted(sorted(peaks, key=lambda p: -mag[p])[:MAX_MODES])
    modes = []
    for p in peaks:
        f0 = float(frf.frequency_hz[p])
        half = mag[p] / math.sqrt(2.0)
        lo, hi = p, p
        while lo > 0 and mag[lo] > half:
            lo -= 1
        while hi < mag.size - 1 and mag[hi] > half:
            hi += 1
        width = float(frf.frequency_hz[hi] - frf.frequency_hz[lo])
        zeta = float(np.clip(width / (2.0 * f0), 0.005, 0.3))
        gain = 2.0 * zeta * float(mag[p]) * (1.0 if ratio[p].imag > 0 else -1.0)
        modes.append((f0, zeta, gain))
    return modes


def fit_rigid_modes(
    frf: FrequencyResponse,
    *,
    control_period_s: float,
    modes: list[tuple[float, float, float]] | None = None,
    dead_time: bool = True,
    max_frequency_hz: float = np.inf,
) -> Fit:
    """Fit ``J, D``, the modes ``(f_i, zeta_i, a_i)`` and the dead time of 000 eq. (30).

    ``modes`` are start values (None: :func:`find_modes` finds them in the
    measured response). A mode whose keys come out with a standard error
    above half their value is left out and the rest fitted again (its
    frequency in :attr:`Fit.dropped`): a peak of the noise, or a mode the
    data cannot pin.
    """
    first = frf.frequency_hz[0]
    j0, d0 = rigid_start(frf, below_hz=max(5.0 * first, 0.3 * frf.frequency_hz[-1] / 3))
    if modes is None:
        modes = find_modes(frf, inertia_kgm2=j0, damping_Nms_per_rad=d0)
        if modes:
            j0, d0 = rigid_start(frf, below_hz=0.5 * modes[0][0])
            modes = find_modes(frf, inertia_kgm2=j0, damping_Nms_per_rad=d0)
    params = [
        Parameter("inertia_kgm2", j0),
        Parameter("damping_Nms_per_rad", d0),
    ]
    nyquist = 0.5 / control_period_s
    for i, (f, zeta, gain) in enumerate(modes):
        kf, kz, ka = _mode_keys(i)
        params += [
            Parameter(kf, f, lower=0.2 * f, upper=nyquist),
            Parameter(kz, zeta, lower=1e-4, upper=1.0),
            Parameter(ka, gain, log=False, lower=-5.0, upper=5.0),
        ]
    if dead_time:
        params.append(
            Parameter(
                "dead_time_s",
                0.1 * control_period_s,
                log=False,
                lower=0.0,
                upper=5 * control_period_s,
            )
        )
    n = len(modes)
    f_lines = frf.frequency_hz

    def model(values: dict[str, float]) -> list[NDArray[np.complex128]]:
        return [rigid_modes_response(values, f_lines, modes=n, control_period_s=control_period_s)]

    fit = fit_response(model, params, [frf], max_frequency_hz=max_frequency_hz)
    loose = [
        i
        for i in range(n)
        if any(not fit.error(k) <= UNDETERMINED * abs(fit.value(k)) for k in _mode_keys(i))
    ]
    if not loose:
        return fit
    # The loosest first (its largest relative error), one at a time.
    worst = max(
        loose,
        key=lambda i: max(fit.error(k) / max(abs(fit.value(k)), 1e-300) for k in _mode_keys(i)),
    )
    kept = [tuple(fit.value(k) for k in _mode_keys(i)) for i in range(n) if i != worst]
    again = fit_rigid_modes(
        frf,
        control_period_s=control_period_s,
        modes=kept,  # type: ignore[arg-type]
        dead_time=dead_time,
        max_frequency_hz=max_frequency_hz,
    )
    return Fit(
        names=again.names,
        values=again.values,
        std=again.std,
        rms_residual=again.rms_residual,
        points=again.points,
        dropped=(*again.dropped, fit.value(_mode_keys(worst)[0])),
    )


# ----------------------------------------------------------------------- two-inertia (004)


TWO_INERTIA_KEYS = (
    "motor_inertia_kgm2",
    "motor_damping_Nms_per_rad",
    "table_mass_kg",
    "table_damping_Ns_per_m",
    "stiffness_N_per_m",
    "screw_damping_Ns_per_m",
    "current_bandwidth_hz",
)


def two_inertia_response(
    values: dict[str, float],
    frequency_hz: ArrayLike,
    *,
    lead_m_per_rad: float,
    control_period_s: float,
) -> NDArray[np.complex128]:
    """Sampled responses (motor angle, table position) of the two-inertia model from fit values."""
    a, b, c = two_inertia(**{k: values[k] for k in TWO_INERTIA_KEYS}, lead_m_per_rad=lead_m_per_rad)
    return sampled_response(a, b, c, frequency_hz=frequency_hz, control_period_s=control_period_s)


def fit_two_inertia(
    encoder: FrequencyResponse,
    scale: FrequencyResponse,
    *,
    lead_m_per_rad: float,
    control_period_s: float,
) -> Fit:
    """Fit the elastic screw's keys to the responses of the motor angle and the table position.

    Starts: the rigid body ``J_n = J_m + M R^2``, ``B_n`` from the encoder
    at low frequency; the axial mode ``w_r`` and the table's anti-resonance
    ``w_a = sqrt(k_h / M)`` (the dip of the encoder's response) give ``M =
    k_h / w_a^2`` and ``J_m = M R^2 / (w_r^2 / w_a^2 - 1)``.
    """
    r = lead_m_per_rad
    jn, bn = rigid_start(encoder, below_hz=0.2 * encoder.frequency_hz[-1])
    modes = find_modes(encoder, inertia_kgm2=jn, damping_Nms_per_rad=bn)
    if not modes:
        raise IdentificationError(
            "stiffness_N_per_m: expected the axial mode in the band (a resonance of the motor "
            "angle's response above the rigid body), got none: raise max_frequency_hz of the "
            "excitation or its amplitude"
        )
    jn, bn = rigid_start(encoder, below_hz=0.4 * modes[0][0])
    fr = modes[0][0]
    s = 2j * math.pi * encoder.frequency_hz
    rel = np.abs(encoder.response * (jn * s * s + bn * s))
    below = (encoder.frequency_hz < fr) & (encoder.coherence >= 0.5)
    fa = float(encoder.frequency_hz[below][np.argmin(rel[below])]) if below.any() else 0.7 * fr
    fa = min(fa, 0.95 * fr)
    wa, wr = 2 * math.pi * fa, 2 * math.pi * fr
    mr2 = jn * (1.0 - wa * wa / (wr * wr))
    m0 = mr2 / (r * r)
    k0 = m0 * wa * wa
    jm0 = max(jn - mr2, 0.05 * jn)
    meff = 1.0 / (1.0 / m0 + r * r / jm0)
    params = [
        Parameter("motor_inertia_kgm2", jm0),
        Parameter("motor_damping_Nms_per_rad", 0.5 * bn),
        Parameter("table_mass_kg", m0),
        Parameter("table_damping_Ns_per_m", 0.5 * bn / (r * r)),
        Parameter("stiffness_N_per_m", k0),
        Parameter("screw_damping_Ns_per_m", 2.0 * 0.05 * math.sqrt(k0 * meff)),
        Parameter(
            "current_bandwidth_hz",
            0.5 / control_period_s,
            lower=0.01 / control_period_s,
            upper=100.0 / control_period_s,
        ),
    ]
    f_lines = encoder.frequency_hz
    if not np.array_equal(f_lines, scale.frequency_hz):
        raise SignalError("scale: expected the encoder's lines, got other frequencies")

    def model(values: dict[str, float]) -> list[NDArray[np.complex128]]:
        both = two_inertia_response(
            values, f_lines, lead_m_per_rad=r, control_period_s=control_period_s
        )
        return [both[0], both[1]]

    return fit_response(model, params, [encoder, scale])


# ----------------------------------------------------------------------- tilting table (003)


TILTING_KEYS = ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm", "coulomb_Nm")


def _lowpass(x: FloatArray, cutoff_hz: float, period_s: float) -> FloatArray:
    sos = butter(4, cutoff_hz, fs=1.0 / period_s, output="sos")
    return np.asarray(sosfiltfilt(sos, x), dtype=np.float64)


def fit_tilting_table(
    *,
    angle_rad: ArrayLike,
    torque_Nm: ArrayLike,
    control_period_s: float,
    cutoff_hz: float = 20.0,
    min_velocity_rad_s: float = 0.02,
    blocks: int = 20,
    resamples: int = 200,
    seed: int = 0,
) -> Fit:
    """``J, D, U, C`` of paper 003 eq. (2) by filtered time-domain least squares.

    The fit at ``cutoff_hz`` (:func:`tilting_table_ls`), its standard errors
    the moving-block bootstrap's and, in quadrature, the change of each value
    when the cut-off is doubled: what the filter leaves of the model's and
    the sampling's approximations, which the bootstrap does not see.
    """
    kw = {
        "angle_rad": angle_rad,
        "torque_Nm": torque_Nm,
        "control_period_s": control_period_s,
        "min_velocity_rad_s": min_velocity_rad_s,
        "blocks": blocks,
        "seed": seed,
    }
    fit = tilting_table_ls(cutoff_hz=cutoff_hz, resamples=resamples, **kw)  # type: ignore[arg-type]
    wide = tilting_table_ls(cutoff_hz=2.0 * cutoff_hz, resamples=2, **kw)  # type: ignore[arg-type]
    return Fit(
        names=fit.names,
        values=fit.values,
        std=np.hypot(fit.std, fit.values - wide.values),
        rms_residual=fit.rms_residual,
        points=fit.points,
    )


def tilting_table_ls(
    *,
    angle_rad: ArrayLike,
    torque_Nm: ArrayLike,
    control_period_s: float,
    cutoff_hz: float = 20.0,
    min_velocity_rad_s: float = 0.02,
    blocks: int = 20,
    resamples: int = 200,
    seed: int = 0,
) -> Fit:
    """``J, D, U, C`` of paper 003 eq. (2) by filtered time-domain least squares.

    Parameters
    ----------
    angle_rad, torque_Nm : array_like
        The encoder angle and the motor torque (``command``) per control sample.
    control_period_s : float
        ``T``, s.
    cutoff_hz : float
        Of the zero-phase fourth-order Butterworth low-pass every signal passes, Hz.
    min_velocity_rad_s : float
        Samples slower than this (sticking, or near a reversal) are left out, rad/s.
    blocks, resamples, seed : int
        The moving-block bootstrap: blocks of the kept samples, resamples, seed.
    """
    th = np.asarray(angle_rad, dtype=float)
    tau = np.asarray(torque_Nm, dtype=float)
    if th.size != tau.size or th.size < 100:
        raise SignalError(
            f"angle_rad: expected at least 100 samples, as many as torque_Nm, got {th.size} "
            f"and {tau.size}"
        )
    t = control_period_s
    th_f = _lowpass(th, cutoff_hz, t)
    vel = np.gradient(th_f, t)
    acc = np.gradient(vel, t)
    # The friction's sign follows the true velocity, excitation included: its sign
    # from a wider low-pass (5 times the cut-off) than the one every regressor passes.
    fast = np.gradient(_lowpass(th, min(5.0 * cutoff_hz, 0.4 / t), t), t)
    reg = np.column_stack(
        [
            acc,
            vel,
            _lowpass(np.sin(th), cutoff_hz, t),
            _lowpass(np.sign(fast), cutoff_hz, t),
        ]
    )
    # The torque is held over each period (zero-order hold): the motion at k T follows
    # the held torque of about (k - 1/2) T, half a sample before tau[k]; without the
    # shift the inertia term carries a phase lead that reads as a damping of
    # -J w^2 T / 2 (at 20 Hz and 003's J, as large as D itself).
    half = np.concatenate([tau[:1], 0.5 * (tau[1:] + tau[:-1])])
    y = _lowpass(half, cutoff_hz, t)
    edge = int(2.0 / (cutoff_hz * t))
    keep = np.zeros(th.size, dtype=bool)
    keep[edge:-edge] = True
    # A sign change nearby smears the filtered sgn: keep the samples well away from it.
    moving = np.abs(fast) >= min_velocity_rad_s
    near = np.convolve(~moving, np.ones(2 * edge + 1), mode="same") > 0
    keep &= ~near
    rows = np.flatnonzero(keep)
    if rows.size < 50:
        raise IdentificationError(
            f"coulomb_Nm: expected at least 50 samples moving faster than {min_velocity_rad_s:g} "
            f"rad/s, got {rows.size}"
        )
    a, b = reg[rows], y[rows]
    span = np.ptp(np.sin(th[rows]))
    if span < 0.05:
        raise IdentificationError(
            f"unbalance_Nm: expected an angle range whose sin varies by >= 0.05, got {span:.3g}: "
            "move the table through a wider range"
        )
    if np.all(fast[rows] > 0) or np.all(fast[rows] < 0):
        raise IdentificationError(
            "coulomb_Nm: expected motion in both directions, got one: C and the offset of U "
            "cannot be told apart"
        )
    coef, *_ = np.linalg.lstsq(a, b, rcond=None)
    resid = b - a @ coef
    rng = np.random.default_rng(seed)
    size = max(rows.size // blocks, 1)
    starts = np.arange(0, rows.size - size + 1)
    boot = []
    for _ in range(resamples):
        pick = rng.choice(starts, size=blocks)
        idx = (pick[:, None] + np.arange(size)).ravel()
        c_b, *_ = np.linalg.lstsq(a[idx], b[idx], rcond=None)
        boot.append(c_b)
    std = np.std(np.array(boot), axis=0, ddof=1)
    return Fit(
        names=TILTING_KEYS,
        values=np.asarray(coef, dtype=float),
        std=np.asarray(std, dtype=float),
        rms_residual=float(np.sqrt(np.mean(resid**2))),
        points=int(rows.size),
    )
