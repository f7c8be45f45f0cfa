"""Standard iterative learning control with a ZPETC learning filter (paper 001, Sect. III-A).

Paper 001 (Hayashi, Fujimoto, Isaoka, Terada), Sect. III-A and IV-A:
trials of ``N`` control samples, each starting and ending at rest; the
feedforward current of the next trial is ``f_{j+1} = Q (f_j + L e_j)``
(eq. (3)), with

* ``L`` the zero-phase-error tracking controller (ZPETC, Tomizuka 1987,
  001 ref. [13]) of the nominal process sensitivity ``S_n P_n`` (A -> m);
* ``Q = ((z + 2 + z^-1)/4)^Nq`` the zero-phase robust filter (eq. (24)),
  realised causally as ``Q_r = z^-Nq Q`` (eq. (25)) by ``Nq`` samples of
  delay compensation in the memory: over a stored trial that is the
  symmetric FIR filter :func:`trial_q`.

The tracking error is ``e = r - x`` at the table in m (eq. (2)); the
feedforward is a current in A added to the control input
(``side = "input"``, ``period = "trial"`` of :mod:`.base`). The error obeys
``e_{j+1} = Q (1 - S P L) e_j + (1 - Q)(S r - S P d)`` (eq. (6)) and falls
monotonically if ``max_w |Q (1 - S L P)| < 1`` (eq. (7)): the laws refuse to
be built when the nominal loop violates it.

The loop the filters are designed on: ``P(s) = R K_T / (J s^2 + D s)``
(eq. (1), (8)) driven by a zero-order hold of the current and sampled at
the control instants without extra delay; the PID ``C(s)`` of
:class:`~servo_axis.core.feedback.pid.PidGains` acts on the motor-angle
error (A/rad), Tustin-discretised at the control period (as
:class:`~servo_axis.core.feedback.pid.DiscretePid`), i.e. ``C / R`` on the
table error in m. Then ``S P = P_zoh / (1 + C_tustin P_zoh / R)``.

All filtering of a trial is done by recursive and FIR filtering with zero
initial conditions (no ``N x N`` lifted matrices).

Trials run back to back (the axis does not stop between them): eq. (4)-(5),
``e_j = S r - S P (f_j - d)``, describe a loop that starts every trial from
rest with zero controller state. The running loop starts trial ``j`` from
the equilibrium trial ``j - 1`` left: the table at rest, the PID's
integrator holding the friction minus the constant ``f_{j-1}[N-1]`` the
learned input ended with. By linearity that is eq. (4) with the input
``f_j - f_{j-1}[N-1]``: the loop sees only the input relative to the level it
starts from. :class:`StandardIlc` therefore applies eq. (3) to that relative
input (see :meth:`StandardIlc.learn`). Applied to the absolute ``f`` (as
before), a constant level in ``f`` is invisible at rest (``S P`` has a zero
at ``z = 1``, the PID's integrator) but its change from one trial to the
next is a step at the trial's start that ``L`` (whose running sum inverts
that zero) learns back in full: the level ``a`` obeys ``a_{j+2} = a_j``, a
trial-to-trial eigenvalue of -1 that eq. (6)-(7) do not contain. After a
reference that reverses the last move (the friction held at rest flips
from ``-T_c`` to ``+T_c``, 2 T_c / K_T = 9 A on the 001 axis) the learned
input at rest alternated between +9.0 and -4.5 A from trial to trial and
the error stayed at 3.9 um RMS (docs/explanation/paper-001.md, S-ILC and the trial boundary).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.polynomial import polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, require_positive
from servo_axis.core.feedback.discrete import tustin
from servo_axis.core.feedback.pid import PidGains
from servo_axis.core.learning.filters import q_filter_taps, q_gain
from servo_axis.core.models.base import NominalModel

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

#: A zero of the ZPETC model is cancelled only if ``|z| < ZERO_RADIUS`` ...
ZERO_RADIUS = 0.98
#: ... and ``Re z > ZERO_MIN_REAL`` (not in the neighbourhood of -1, the Nyquist frequency).
ZERO_MIN_REAL = -0.5
#: A zero within this distance of ``z = 1`` is the integrator of ``C_FB`` (see :class:`Zpetc`).
UNIT_ZERO_TOL = 1e-6
#: Frequency points (0 .. Nyquist) of :func:`convergence_measure`.
CONVERGENCE_POINTS = 4097
#: A nominal measure of eq. (7) above ``1 - MEASURE_TOL`` counts as 1: a zero on the unit
#: circle (e.g. the ZOH zero of an undamped plant, ``D_n = 0``, at ``z = -1``) is computed
#: with rounding error, which must not decide between converging and not.
MEASURE_TOL = 1e-9


@dataclass(frozen=True, kw_only=True)
class IlcParams:
    """Parameters of the ILC laws of paper 001.

    Parameters
    ----------
    samples_per_trial : int
        ``N``, control samples per trial, >= 8.
    nq : int
        ``N_Q`` of the robust filter ``Q`` (eq. (24)), >= 0, with
        ``2 Nq + 1 <= N // 2``: the filter spans at most half the trial, so
        that most of the trial is filtered without touching its ends.
        The paper uses 16 (Sect. IV-A-3).
    period_s : float
        Control period ``T_s``, s, > 0 (1 ms in the paper).
    lead_m_per_rad : float
        Ball-screw lead ``R``, m/rad, > 0 (1.91e-3 in Table I).
    nominal : NominalModel
        ``J_n``, ``D_n``, ``K_T`` of eq. (1) (Table I).
    pid : PidGains
        The feedback controller ``C_FB`` (rad -> A), as run in the loop.
    """

    samples_per_trial: int
    nq: int = 16
    period_s: float
    lead_m_per_rad: float
    nominal: NominalModel
    pid: PidGains

    def __post_init__(self) -> None:
        n = self.samples_per_trial
        if isinstance(n, bool) or not isinstance(n, int) or n < 8:
            raise ConfigError(f"samples_per_trial: expected an integer >= 8, got {n!r}")
        if isinstance(self.nq, bool) or not isinstance(self.nq, int) or self.nq < 0:
            raise ConfigError(f"nq: expected an integer >= 0, got {self.nq!r}")
        if 2 * self.nq + 1 > n // 2:
            raise ConfigError(
                f"nq: Nq too large for the trial: Q of eq. (24) has 2 Nq + 1 = {2 * self.nq + 1} "
                f"taps, expected at most N // 2 = {n // 2} (N = samples_per_trial = {n})"
            )
        require_positive("period_s", self.period_s)
        require_positive("lead_m_per_rad", self.lead_m_per_rad)
        if not isinstance(self.nominal, NominalModel):
            raise ConfigError(
                f"nominal: expected a NominalModel, got {type(self.nominal).__name__}"
            )
        if not isinstance(self.pid, PidGains):
            raise ConfigError(f"pid: expected PidGains, got {type(self.pid).__name__}")

    def identity(self) -> dict[str, Any]:
        """The values a learning memory must match: ``N``, ``Nq``, ``T_s``, ``R``, model, PID."""
        g = self.pid
        return {
            "samples_per_trial": self.samples_per_trial,
            "nq": self.nq,
            "period_s": self.period_s,
            "lead_m_per_rad": self.lead_m_per_rad,
            **{f"nominal_{k}": v for k, v in self.nominal.as_kwargs().items()},
            "pid_kp_A_per_rad": g.kp_A_per_rad,
            "pid_ki_A_per_rad_s": g.ki_A_per_rad_s,
            "pid_kd_A_s_per_rad": g.kd_A_s_per_rad,
            "pid_derivative_tau_s": g.derivative_tau_s,
        }


# -- the loop ----------------------------------------------------------------


def _padd(a: FloatArray, b: FloatArray) -> FloatArray:
    """Sum of two polynomials in ``z^-1`` (ascending coefficients)."""
    n = max(len(a), len(b))
    return np.pad(a, (0, n - len(a))) + np.pad(b, (0, n - len(b)))


def _loop_polynomials(
    params: IlcParams, plant: NominalModel | None
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``(Bp, Ap, Bc, Ac)``: ``P_zoh = Bp / Ap`` (A -> m), ``C_tustin = Bc / Ac`` (rad -> A).

    Polynomials in ``z^-1`` (ascending powers), ``Bp[0] = 0`` (the hold
    delays the current by one sample).
    """
    model = params.nominal if plant is None else plant
    gain = params.lead_m_per_rad * model.torque_constant_Nm_per_A
    import scipy.signal  # here: it costs a node ~1 s at start-up

    num_d, den_d, _ = scipy.signal.cont2discrete(
        (np.array([gain]), np.array([model.inertia_kgm2, model.damping_Nms_per_rad, 0.0])),
        params.period_s,
        method="zoh",
    )
    bp = np.asarray(num_d, dtype=float).ravel()
    ap = np.asarray(den_d, dtype=float).ravel()
    # cont2discrete returns equal-length polynomials in z; divided by z^n they
    # are the same coefficients in ascending powers of z^-1.
    bp, ap = bp / ap[0], ap / ap[0]
    bp[0] = 0.0  # exactly: a strictly proper plant has no direct feed-through
    num_c, den_c = params.pid.transfer_function()
    ctl = tustin(num_c, den_c, params.period_s)
    return bp, ap, np.asarray(ctl.b, dtype=float), np.asarray(ctl.a, dtype=float)


def process_sensitivity(
    params: IlcParams, *, plant: NominalModel | None = None
) -> tuple[FloatArray, FloatArray]:
    """Discrete process sensitivity ``S P`` (A -> m) of the loop, eq. (2).

    ``S P = P_zoh / (1 + C_tustin P_zoh / R) = R Bp Ac / (R Ap Ac + Bp Bc)``
    with ``P_zoh = Bp / Ap`` the zero-order-hold discretisation of
    ``R K_T / (J s^2 + D s)`` and ``C_tustin = Bc / Ac`` the Tustin PID.

    Parameters
    ----------
    params : IlcParams
        Period, lead, nominal model and PID.
    plant : NominalModel, optional
        A true linear plant (other ``J``, ``D``, ``K_T``) in the same loop
        (same PID, hold and sampling); ``None``: the nominal ``S_n P_n``.

    Returns
    -------
    num, den : ndarray
        Coefficients in ascending powers of ``z^-1`` (``den[0] = 1``; both
        of the same length, so they are also the coefficients of the
        rational function in descending powers of ``z``), as taken by
        ``scipy.signal.lfilter``.
    """
    bp, ap, bc, ac = _loop_polynomials(params, plant)
    r = params.lead_m_per_rad
    num = r * np.convolve(bp, ac)
    den = _padd(r * np.convolve(ap, ac), np.convolve(bp, bc))
    num = np.pad(num, (0, len(den) - len(num)))
    return num / den[0], den / den[0]


def _polyval_zinv(coeffs: ArrayLike, zinv: ComplexArray) -> ComplexArray:
    """Polynomial in ``z^-1`` with ascending ``coeffs`` at the points ``zinv``."""
    result: ComplexArray = npoly.polyval(zinv, np.asarray(coeffs, dtype=float))
    return result


def _zinv(freq_hz: ArrayLike, period_s: float) -> ComplexArray:
    result: ComplexArray = np.exp(-2j * np.pi * np.asarray(freq_hz, dtype=float) * period_s)
    return result


def process_sensitivity_response(
    freq_hz: ArrayLike, *, params: IlcParams, plant: NominalModel | None = None
) -> ComplexArray:
    """``S P (e^{j w T_s})`` (m/A) of :func:`process_sensitivity` at ``freq_hz`` (Hz, 0 .. 1/(2 T_s))."""
    num, den = process_sensitivity(params, plant=plant)
    zinv = _zinv(freq_hz, params.period_s)
    result: ComplexArray = _polyval_zinv(num, zinv) / _polyval_zinv(den, zinv)
    return result


# -- ZPETC ---------------------------------------------------------------------


class Zpetc:
    """Zero-phase-error tracking controller (Tomizuka 1987) of ``G = z^-d B / A``.

    ``G(z) = z^-d B(z^-1) / A(z^-1)`` with ``B(z^-1) = B_a(z^-1) B_u(z^-1)``
    split into the zeros it cancels (``B_a``) and those it does not
    (``B_u``, monic in ``z^-1``). The ZPETC is

    ``L(z) = z^d A(z^-1) B_u(z) / (B_a(z^-1) B_u(1)^2)``

    so that ``G L = B_u(z^-1) B_u(z) / B_u(1)^2 = |B_u(e^{jw})|^2 / B_u(1)^2``:
    real and >= 0 (zero phase), 1 at DC, exactly 1 at every frequency when
    all zeros are cancelled.

    Zero classification: a zero ``z_i`` is cancelled (acceptable) if
    ``|z_i| < radius`` and ``Re z_i > min_real``: stable with a margin, and
    not in the neighbourhood of ``-1``, where its inverse would ring at the
    Nyquist frequency with a large gain (the ZOH zero of a double
    integrator, near ``-1``, is therefore kept in ``B_u``). A zero within
    :data:`UNIT_ZERO_TOL` of ``z = 1`` is cancelled as well and snapped to
    1: in ``S_n P_n`` it is the integrator of ``C_FB`` (``S P = 1 / (1/P + C)``
    vanishes at DC), known exactly because the controller is implemented as
    designed, so the cancellation is exact for the true loop too; its inverse
    is a running sum, bounded over a finite trial; and left in ``B_u`` it
    would make the gain compensation ``1 / B_u(1)^2`` infinite.

    Parameters
    ----------
    num, den : array_like
        ``G`` in ascending powers of ``z^-1`` (``den[0] != 0``); the leading
        zeros of ``num`` are the delay ``d``.
    period_s : float
        Sampling period, s, > 0 (for the frequency responses).
    radius : float
        Largest ``|z|`` of a cancelled zero, in (0, 1).
    min_real : float
        Cancelled zeros have ``Re z > min_real``, in [-1, 1).
    """

    def __init__(
        self,
        num: ArrayLike,
        den: ArrayLike,
        *,
        period_s: float,
        radius: float = ZERO_RADIUS,
        min_real: float = ZERO_MIN_REAL,
    ) -> None:
        b = np.atleast_1d(np.asarray(num, dtype=float))
        a = np.atleast_1d(np.asarray(den, dtype=float))
        if b.ndim != 1 or a.ndim != 1 or not (np.all(np.isfinite(b)) and np.all(np.isfinite(a))):
            raise ConfigError("num, den: expected 1-D arrays of finite coefficients")
        if a[0] == 0.0:
            raise ConfigError("den: expected a non-zero leading coefficient (a causal model)")
        nonzero = np.flatnonzero(b)
        if nonzero.size == 0:
            raise ConfigError(
                "num: expected a non-zero numerator (a model with zero gain has no inverse)"
            )
        self.period_s = require_positive("period_s", period_s)
        if not 0.0 < radius < 1.0:
            raise ConfigError(f"radius: expected a value in (0, 1), got {radius!r}")
        if not -1.0 <= min_real < 1.0:
            raise ConfigError(f"min_real: expected a value in [-1, 1), got {min_real!r}")
        #: Delay ``d`` of the model, samples.
        self.delay = int(nonzero[0])
        b = b[nonzero[0] : nonzero[-1] + 1]  # trailing zeros are zeros at z = 0: dropped
        zeros = np.asarray(np.roots(b) if len(b) > 1 else np.zeros(0), dtype=complex)
        unit = np.abs(zeros - 1.0) < UNIT_ZERO_TOL
        zeros = np.where(unit, 1.0 + 0.0j, zeros)
        accept = unit | ((np.abs(zeros) < radius) & (zeros.real > min_real))
        #: Cancelled and kept zeros (z-plane).
        self.acceptable_zeros = np.asarray(zeros[accept], dtype=complex)
        self.unacceptable_zeros = np.asarray(zeros[~accept], dtype=complex)
        # B(z^-1) = b0 prod (1 - z_i z^-1); np.poly gives the coefficients of
        # prod (z - z_i) in descending powers of z, i.e. of prod (1 - z_i z^-1)
        # in ascending powers of z^-1. Conjugate pairs stay together, so the
        # coefficients are real.
        self._b_a = b[0] * np.atleast_1d(np.real(np.poly(self.acceptable_zeros)))
        self._b_u = np.atleast_1d(np.real(np.poly(self.unacceptable_zeros)))
        self._a = a / a[0]
        self._gain = float(np.sum(self._b_u)) ** 2  # B_u(1)^2
        #: Samples of the future the filter reads: ``d + deg B_u``.
        self.preview = self.delay + len(self._b_u) - 1

    def apply(self, signal: ArrayLike) -> FloatArray:
        """``L`` applied to one finite trial (zero outside the trial).

        The signal is extended by ``preview`` zeros and its initial
        conditions are zero (the trial is taken as zero before and after
        it); ``A / B_a`` is run causally (``lfilter``), then the
        anticausal FIR ``z^d B_u(z) / B_u(1)^2`` reads ``d .. d + deg B_u``
        samples ahead (an explicit index shift). The result is the
        non-causal LTI operator applied to the zero-padded signal, restricted
        to the trial.

        Parameters
        ----------
        signal : array, shape (N,)
            Finite samples.

        Returns
        -------
        ndarray, shape (N,)
        """
        x = np.asarray(signal, dtype=float)
        if x.ndim != 1 or not np.all(np.isfinite(x)):
            raise SignalError(f"signal: expected a 1-D array of finite values, got shape {x.shape}")
        n, p = len(x), self.preview
        import scipy.signal  # here: it costs a node ~1 s at start-up

        stable = scipy.signal.lfilter(self._a, self._b_a, np.concatenate((x, np.zeros(p))))
        # y[k] = sum_m u_m stable[k + d + m]: convolution with the reversed
        # taps, shifted by the preview d + deg B_u.
        out = np.convolve(stable, self._b_u[::-1])[p : p + n] / self._gain
        return np.asarray(out, dtype=float)

    def response(self, freq_hz: ArrayLike) -> ComplexArray:
        """``L(e^{j w T})`` at ``freq_hz`` (Hz); infinite at DC when a zero at ``z = 1`` is cancelled."""
        zinv = _zinv(freq_hz, self.period_s)
        with np.errstate(divide="ignore", invalid="ignore"):
            result: ComplexArray = (
                zinv ** (-self.delay)
                * _polyval_zinv(self._a, zinv)
                * _polyval_zinv(self._b_u, 1.0 / zinv)
                / (_polyval_zinv(self._b_a, zinv) * self._gain)
            )
        return result

    def compensated_response(self, freq_hz: ArrayLike) -> FloatArray:
        """``G L = |B_u(e^{j w T})|^2 / B_u(1)^2`` for the model ``G`` it was designed on (real, >= 0)."""
        zinv = _zinv(freq_hz, self.period_s)
        result: FloatArray = np.abs(_polyval_zinv(self._b_u, zinv)) ** 2 / self._gain
        return result


def learning_filter(params: IlcParams) -> Zpetc:
    """``L``: the ZPETC of the nominal ``S_n P_n`` (001 Sect. IV-A-3)."""
    num, den = process_sensitivity(params)
    return Zpetc(num, den, period_s=params.period_s)


# -- Q ---------------------------------------------------------------------------


def trial_q(signal: ArrayLike, nq: int) -> FloatArray:
    """The zero-phase robust filter ``Q`` of eq. (24) applied over one trial.

    Eq. (25) realises ``Q`` causally with ``Nq`` samples of delay
    compensation in the memory; over a stored trial that is the symmetric
    FIR ``y[k] = sum_{m=-Nq..Nq} q_m x[k + m]`` (taps of
    :func:`~servo_axis.core.learning.filters.q_filter_taps`). Not circular:
    outside the trial the signal is extended with its end values (a trial
    starts and ends at rest, so the signals are constant there; a constant
    passes ``Q`` unchanged, DC gain 1).

    Parameters
    ----------
    signal : array, shape (N,)
        Finite samples, N >= 1.
    nq : int
        ``Nq`` >= 0.

    Returns
    -------
    ndarray, shape (N,)
    """
    taps = q_filter_taps(nq)
    x = np.asarray(signal, dtype=float)
    if x.ndim != 1 or x.size == 0 or not np.all(np.isfinite(x)):
        raise SignalError(
            f"signal: expected a non-empty 1-D array of finite values, got shape {x.shape}"
        )
    padded = np.concatenate((np.full(nq, x[0]), x, np.full(nq, x[-1])))
    return np.asarray(np.convolve(padded, taps, mode="valid"), dtype=float)


# -- convergence -------------------------------------------------------------------


def _sp_ratio(freq_hz: ArrayLike, params: IlcParams, plant: NominalModel) -> ComplexArray:
    """``S P / S_n P_n`` with the common factor ``Ac`` (the controller's poles) cancelled.

    ``S P = R Bp Ac / (R Ap Ac + Bp Bc)``; both share ``Ac``, whose zero at
    ``z = 1`` would make the plain ratio 0/0 at DC.
    """
    bp_n, ap_n, bc, ac = _loop_polynomials(params, None)
    bp_t, ap_t, _, _ = _loop_polynomials(params, plant)
    r = params.lead_m_per_rad
    zinv = _zinv(freq_hz, params.period_s)
    # Bp has a leading zero (one-sample delay): divide it out of both Bp so the
    # ratio stays finite wherever the delayed polynomials are.
    num = _polyval_zinv(bp_t[1:], zinv) * _polyval_zinv(
        _padd(r * np.convolve(ap_n, ac), np.convolve(bp_n, bc)), zinv
    )
    den = _polyval_zinv(bp_n[1:], zinv) * _polyval_zinv(
        _padd(r * np.convolve(ap_t, ac), np.convolve(bp_t, bc)), zinv
    )
    result: ComplexArray = num / den
    return result


def convergence_gain(
    freq_hz: ArrayLike, *, params: IlcParams, plant: NominalModel | None = None
) -> FloatArray:
    """``|Q (1 - S L P)|`` of eq. (7) at ``freq_hz`` (Hz, 0 .. Nyquist).

    ``Q`` and ``L`` as implemented (eq. (24) and the ZPETC of the nominal
    ``S_n P_n``); ``S P`` is the nominal one (``plant`` None) or that of a
    true linear plant in the same loop (same PID, hold and sampling). ``S L P``
    is evaluated as ``(S P / S_n P_n) (S_n P_n L)`` with the controller's
    poles cancelled analytically, so it is finite at DC.

    Returns
    -------
    ndarray
        Below 1 at every frequency: the error falls monotonically (eq. (6)).
    """
    f = np.asarray(freq_hz, dtype=float)
    zpetc = learning_filter(params)
    spl: ComplexArray = zpetc.compensated_response(f).astype(complex)
    if plant is not None:
        spl = spl * _sp_ratio(f, params, plant)
    q = q_gain(f, nq=params.nq, period_s=params.period_s)
    result: FloatArray = np.abs(q * (1.0 - spl))
    return result


def convergence_measure(
    *, params: IlcParams, plant: NominalModel | None = None, points: int = CONVERGENCE_POINTS
) -> float:
    """``max |Q (1 - S L P)|`` over ``points`` equally spaced frequencies, 0 .. Nyquist (eq. (7))."""
    if isinstance(points, bool) or not isinstance(points, int) or points < 2:
        raise ConfigError(f"points: expected an integer >= 2, got {points!r}")
    f = np.linspace(0.0, 0.5 / params.period_s, points)
    return float(np.max(convergence_gain(f, params=params, plant=plant)))


def require_convergence(params: IlcParams) -> float:
    """The nominal measure of eq. (7), or :class:`ConfigError` naming ``nq`` if it is >= 1.

    Within :data:`MEASURE_TOL` of 1 counts as 1.
    """
    measure = convergence_measure(params=params)
    if not measure < 1.0 - MEASURE_TOL:
        raise ConfigError(
            f"nq: Nq = {params.nq} gives max |Q(1 - S_n L P_n)| = {measure:.6g} >= 1 (eq. (7)); "
            "raise Nq"
        )
    return measure


# -- validation shared with the P-ILC -------------------------------------------------


def check_trial_signal(
    name: str, value: ArrayLike, samples: int, what: str = "N, one trial"
) -> FloatArray:
    """``value`` as a float array of ``samples`` finite values, or :class:`SignalError` naming ``name``.

    ``what`` says in the message what the count is.
    """
    try:
        x = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SignalError(f"{name}: expected {samples} numbers") from None
    if x.shape != (samples,):
        raise SignalError(f"{name}: expected {samples} values ({what}), got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise SignalError(f"{name}: expected finite values")
    return x


def check_count(name: str, value: object) -> int:
    """``value`` as an int >= 0, or :class:`SignalError` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise SignalError(f"{name}: expected an integer >= 0, got {value!r}")
    return value


# -- the law ---------------------------------------------------------------------------


class StandardIlc:
    """S-ILC of 001: ``f_{j+1} = Q (f_j + L e_j)`` (eq. (3)) on the input relative to the trial's start.

    Parameters
    ----------
    params : IlcParams
        Trial length, ``Nq``, period, lead, nominal model and PID.

    Raises
    ------
    ConfigError
        Naming ``nq`` when the nominal loop violates eq. (7)
        (``max |Q (1 - S_n L P_n)| >= 1``).
    """

    name = "silc"
    period = "trial"
    side = "input"

    def __init__(self, params: IlcParams) -> None:
        self.params = params
        self.learning_filter = learning_filter(params)
        #: Nominal measure of eq. (7) (< 1).
        self.convergence = require_convergence(params)
        self._feedforward = np.zeros(params.samples_per_trial)
        # f_{j-1}[N-1], A: the constant input the loop's equilibrium at the
        # start of the next trial to run (f_j) balances; 0 before trial 1.
        self._start_level = 0.0
        self._trials_learned = 0

    @property
    def samples_per_period(self) -> int:
        """``N``."""
        return self.params.samples_per_trial

    @property
    def periods_learned(self) -> int:
        """Trials learned so far."""
        return self._trials_learned

    def learn(self, error: ArrayLike, *, period: int | None = None) -> FloatArray:
        """Learn one trial: eq. (3) on the input relative to the trial's starting level.

        Trial ``j`` ran ``f_j`` from the equilibrium that ``f_{j-1}[N-1]``
        left (module docstring), so its error is eq. (4) of
        ``g_j = f_j - f_{j-1}[N-1]``; trial ``j + 1`` will start from
        ``f_j[N-1]``. Then

        ``g_{j+1} = Q (g_j + L e_j)`` (eq. (3)),
        ``f_{j+1} = f_j[N-1] + g_{j+1}``,

        and the error obeys eq. (6) from trial to trial. ``f_0[N-1] = 0``:
        trial 1 starts from rest with the loop's states at zero. A trial
        that starts where its predecessor ended (``f_{j+1}[0] = f_j[N-1]``
        once learned) gives the loop the same initial state every trial,
        the premise of eq. (4)-(6).

        Parameters
        ----------
        error : array, shape (N,)
            ``e_j = r - x`` at the table, m, per control sample of the trial.
        period : int, optional
            The trial's number; S-ILC assumes the same reference every
            trial, so it is not used.

        Returns
        -------
        ndarray, shape (N,)
            ``f_{j+1}``, A.
        """
        e = check_trial_signal("error", error, self.params.samples_per_trial)
        relative = self._feedforward - self._start_level
        level = float(self._feedforward[-1])
        self._feedforward = level + trial_q(
            relative + self.learning_filter.apply(e), self.params.nq
        )
        self._start_level = level
        self._trials_learned += 1
        return self._feedforward.copy()

    def next_correction(self, *, period: int | None = None) -> tuple[FloatArray]:
        """``(f,)``: the feedforward current (A) per control sample of the next trial (0 in trial 1)."""
        return (self._feedforward.copy(),)

    def identity(self) -> dict[str, Any]:
        """Law, ``N``, ``Nq``, ``T_s``, ``R``, nominal model and PID gains."""
        return {"law": self.name, **self.params.identity()}

    def state(self) -> dict[str, Any]:
        """The feedforward, its starting level ``f_{j-1}[N-1]`` (exact floats) and the trials learned."""
        return {
            "feedforward_A": self._feedforward.tolist(),
            "start_level_A": self._start_level,
            "trials_learned": self._trials_learned,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state` output (SignalError on a wrong length or value)."""
        trials = check_count("trials_learned", state.get("trials_learned"))
        values = state.get("feedforward_A")
        if not isinstance(values, list):
            raise SignalError("feedforward_A: expected a list of numbers")
        f = check_trial_signal("feedforward_A", values, self.params.samples_per_trial)
        level = state.get("start_level_A")
        if isinstance(level, bool) or not isinstance(level, int | float) or not np.isfinite(level):
            raise SignalError(f"start_level_A: expected a finite number (A), got {level!r}")
        self._feedforward = f.copy()
        self._start_level = float(level)
        self._trials_learned = trials
