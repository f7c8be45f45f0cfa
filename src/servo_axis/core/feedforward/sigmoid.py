"""Sigmoid friction compensation for fast reverse motions (paper 004 Sect. IV, eqs. (8)-(9)).

Near a reversal of a fast motion the deformation ratio ``d_r`` of eq. (7)
(:mod:`servo_axis.core.deformation`) behaves like the power law of eq. (8),

    d_r^ = sigma / z,

with ``z`` the displacement from the reversal point (m) and ``sigma`` a
factor (m^2/rad). The compensation of eq. (9) is

    F_c = sgn(v) sqrt((gamma / d_r^)^2 / (1 + (gamma / d_r^)^2)) F_0
        = sgn(v) F_0 r / sqrt(1 + r^2),     r = gamma z / sigma,

which is 0 at the reversal (``z = 0``, where ``d_r^`` would be infinite:
the limit is taken, ``d_r^`` is never formed there) and tends to ``+-F_0``,
the Coulomb level, away from it. ``gamma`` (m/rad, the unit of ``d_r``)
sets, together with ``sigma``, the width of the switch: the paper designs
them so that ``F_c`` goes from ``F_0`` to ``-F_0`` mainly within
``[-x_s/2, x_s/2]``, ``x_s`` the pre-sliding region (15 um on its stage);
:func:`gamma_for_width` gives ``gamma`` for such a width in closed form.

Units: SI throughout. The paper's ``sigma = 0.04`` with ``z`` in mm and
``d_r`` in mm/rad is ``0.04 mm^2/rad = 0.04e-6 m^2/rad``
(:data:`PAPER_SIGMA_M2_PER_RAD`). ``F_0`` is a motor torque (N m); the
feedforward current is ``F_c / K_T`` (A).

:class:`SigmoidTerm` applies the law as a feedforward term
(:class:`servo_axis.core.feedforward.terms.FeedforwardTerm`): the reversals
of the reference are known ahead, so ``F_c`` starts falling before a
reversal (the braking the paper asks for) and rises in the new direction
after it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, require_finite, require_positive
from servo_axis.core.feedforward.terms import ReferenceBlock
from servo_axis.core.reference import Reference

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: ``sigma`` of paper 004 Fig. 13(a): 0.04 mm^2/rad, in m^2/rad.
PAPER_SIGMA_M2_PER_RAD = 0.04e-6
#: The pre-sliding region ``x_s`` of paper 004 Fig. 4(b), m.
PAPER_PRESLIDING_M = 15e-6
#: Control samples of the reference evaluated at a time when looking for
#: reversals; chunks start at multiples of it, so the values (and the
#: reversals found) never depend on how the samples are asked for.
SCAN_CHUNK_STEPS = 1024


@dataclass(frozen=True, kw_only=True)
class SigmoidParams:
    """Parameters of the sigmoid law, eqs. (8)-(9).

    Parameters
    ----------
    sigma_m2_per_rad : float
        ``sigma`` of eq. (8), m^2/rad, > 0 (the paper's 0.04 mm^2/rad is
        0.04e-6 m^2/rad, :data:`PAPER_SIGMA_M2_PER_RAD`).
    gamma_m_per_rad : float
        ``gamma`` of eq. (9), m/rad (the unit of ``d_r``), > 0; see
        :func:`gamma_for_width`.
    coulomb_Nm : float
        ``F_0`` of eq. (9), the Coulomb level as a motor torque, N m, > 0.

    Raises
    ------
    ConfigError
        Naming the field that is not finite and > 0.
    """

    sigma_m2_per_rad: float
    gamma_m_per_rad: float
    coulomb_Nm: float

    def __post_init__(self) -> None:
        for name in ("sigma_m2_per_rad", "gamma_m_per_rad", "coulomb_Nm"):
            object.__setattr__(self, name, require_positive(name, getattr(self, name)))


def _check_sigma(sigma_m2_per_rad: float) -> float:
    return require_positive("sigma_m2_per_rad", sigma_m2_per_rad)


def estimated_deformation_ratio(z_m: ArrayLike, sigma_m2_per_rad: float) -> FloatArray:
    """``d_r^ = sigma / z``, eq. (8), m/rad.

    Parameters
    ----------
    z_m : array_like
        Distance from the reversal point, m, > 0 (``inf`` gives 0).
    sigma_m2_per_rad : float
        ``sigma``, m^2/rad, > 0.

    Returns
    -------
    ndarray
        ``d_r^`` (m/rad), the broadcast shape of ``z_m``.

    Raises
    ------
    SignalError
        ``z_m`` not > 0 (NaN included). The power law is infinite at the
        reversal point; eq. (9) is taken at its limit there instead
        (:func:`sigmoid_torque` gives 0 at ``z = 0`` without forming ``d_r^``).
    ConfigError
        ``sigma_m2_per_rad`` not finite and > 0.
    """
    sigma = _check_sigma(sigma_m2_per_rad)
    z = np.asarray(z_m, dtype=float)
    if not np.all(z > 0.0):
        raise SignalError(
            "z_m: expected distances > 0 from the reversal point (eq. (8) is infinite at 0; "
            "use sigmoid_torque, which takes the limit)"
        )
    return np.asarray(sigma / z, dtype=float)


def sigmoid_torque(z_m: ArrayLike, direction: ArrayLike, params: SigmoidParams) -> FloatArray:
    """``F_c`` of eq. (9), N m (motor torque), vectorised.

    ``F_c = sgn(direction) F_0 r / sqrt(1 + r^2)`` with ``r = gamma z / sigma``,
    which is eq. (9) with ``d_r^ = sigma / z`` of eq. (8) substituted
    (``gamma / d_r^ = r``). Computed as ``r / hypot(1, r)``, which neither
    overflows for large ``r`` nor divides by zero at ``z = 0``.

    Parameters
    ----------
    z_m : array_like
        Distance from the reversal point, m, >= 0; ``inf`` (no reversal)
        gives ``+-F_0``.
    direction : array_like
        Direction of motion; only its sign is used (+1, -1, or 0 for none),
        so the reference velocity itself may be passed (``sgn(v_t)``).
    params : SigmoidParams
        ``sigma``, ``gamma``, ``F_0``.

    Returns
    -------
    ndarray
        ``F_c`` (N m) in the broadcast shape of ``z_m`` and ``direction``:
        exactly 0 at ``z = 0``, increasing in ``z`` towards ``F_0`` in
        magnitude, odd in ``direction``.

    Raises
    ------
    SignalError
        ``z_m`` negative or NaN, or ``direction`` not finite.
    """
    z = np.asarray(z_m, dtype=float)
    d = np.asarray(direction, dtype=float)
    if not np.all(z >= 0.0):
        raise SignalError("z_m: expected distances >= 0 from the reversal point (inf allowed)")
    if not np.all(np.isfinite(d)):
        raise SignalError("direction: expected finite values (their sign is used)")
    r = (params.gamma_m_per_rad / params.sigma_m2_per_rad) * z
    frac = np.ones(r.shape, dtype=float)
    finite = np.isfinite(r)
    # r = inf is the limit z -> inf: fraction 1 (inf / hypot(1, inf) would be NaN).
    np.divide(r, np.hypot(1.0, r), out=frac, where=finite)
    # + 0.0 turns the -0.0 of a negative direction at z = 0 into 0.0.
    return np.asarray(params.coulomb_Nm * np.sign(d) * frac + 0.0, dtype=float)


def gamma_for_width(
    *, sigma_m2_per_rad: float, half_width_m: float, fraction: float = 0.9
) -> float:
    """``gamma`` (m/rad) with which ``|F_c| = fraction F_0`` at ``z = half_width_m``.

    From eq. (9), ``|F_c| / F_0 = r / sqrt(1 + r^2)`` with ``r = gamma z / sigma``,
    so ``r = f / sqrt(1 - f^2)`` at ``z = w`` and

        gamma = sigma f / (w sqrt((1 - f)(1 + f))).

    The paper's design rule ("F_c varies from F_0 to -F_0 mainly in
    [-x_s/2, x_s/2]") is ``half_width_m = x_s / 2`` (7.5 um on its stage).

    Parameters
    ----------
    sigma_m2_per_rad : float
        ``sigma`` of eq. (8), m^2/rad, > 0.
    half_width_m : float
        ``w``, m, > 0.
    fraction : float
        ``f``, in (0, 1); 0.9 by default.

    Returns
    -------
    float
        ``gamma``, m/rad.

    Raises
    ------
    ConfigError
        Naming the argument out of range.
    """
    sigma = _check_sigma(sigma_m2_per_rad)
    w = require_positive("half_width_m", half_width_m)
    f = require_finite("fraction", fraction)
    if not 0.0 < f < 1.0:
        raise ConfigError(f"fraction: expected a value in (0, 1), got {fraction!r}")
    return sigma * f / (w * math.sqrt((1.0 - f) * (1.0 + f)))


@dataclass(frozen=True)
class Reversal:
    """A reversal of the reference (a sign change of its velocity).

    Attributes
    ----------
    time_s : float
        Where the velocity crosses 0 (``brentq`` between the two control
        samples around the sign change), s.
    position_m : float
        The reference there (the extremum), m.
    detected_step : int
        The first control sample after the sign change (the first with the
        new direction); the reversal counts for sample ``k`` once
        ``detected_step <= k + horizon_steps``.
    """

    time_s: float
    position_m: float
    detected_step: int


class SigmoidTerm:
    """The sigmoid law of eq. (9) as a feedforward term (paper 004 Sect. IV).

    For control sample ``k`` at ``t = k T_u``, with ``x``, ``v`` the reference
    there (table side, m, m/s):

    * ``z = min(|x - x_prev|, |x - x_next|)``: the distance to the previous
      reversal of the reference (``time_s <= t``) and to the next one
      (``time_s > t``), the next counting only if it is found within the
      horizon (its first sample after the sign change no later than
      ``k + horizon_steps``); with neither, ``z = inf`` (``|F_c| = F_0``);
    * ``direction = sgn(v)``; at exactly ``v = 0``, the sign of the next
      non-zero velocity if it comes within the horizon and the reference
      has moved before; else 0 (no current at rest before the first motion,
      nor at a standstill with no motion ahead);
    * current ``= F_c(z, direction) / K_T`` (A): it pushes in the direction
      of motion, like a friction compensation.

    So ``F_c`` falls to 0 while the reference brakes into a reversal and
    rises in the new direction after it. A stop followed by motion in the
    same direction (a touch of ``v = 0`` without a sign change, the
    "non-reverse motion" of Sect. III) is not a reversal.

    Reversals are sign changes of the velocity between control samples
    (exact zeros skipped, so a dwell between opposite motions is one
    reversal), located by ``scipy.optimize.brentq`` on the velocity. The
    reference is scanned once, forwards, in chunks of
    :data:`SCAN_CHUNK_STEPS` samples aligned to multiples of it; the list of
    reversals is kept and extended as blocks advance. The current of a
    sample depends only on the reference up to ``horizon_steps`` ahead, never
    on how the samples are split into blocks (any order works; samples
    behind the retained chunks are recomputed).

    Parameters
    ----------
    params : SigmoidParams
        ``sigma``, ``gamma``, ``F_0`` (N m).
    reference : Reference
        The trajectory (table side, m); sampled at ``k T_u``.
    control_period_s : float
        ``T_u``, s, > 0.
    torque_constant_Nm_per_A : float
        Nominal ``K_T``, N m/A, > 0.
    search_horizon_s : float
        How far ahead (s, > 0) a next reversal (or the end of a standstill)
        is looked for; ``horizon_steps = max(1, round(search_horizon_s / T_u))``.
        1 s by default: a fast reversal is seen long before ``F_c`` starts
        to fall. A reversal further ahead is missed until it comes within
        the horizon, so ``|F_c|`` steps down there if the reference creeps
        within a few ``x_s`` of it for longer than the horizon.

    Raises
    ------
    ConfigError
        Naming ``control_period_s``, ``torque_constant_Nm_per_A`` or
        ``search_horizon_s`` when not finite and > 0.
    """

    def __init__(
        self,
        params: SigmoidParams,
        *,
        reference: Reference,
        control_period_s: float,
        torque_constant_Nm_per_A: float,
        search_horizon_s: float = 1.0,
    ) -> None:
        self.params = params
        self._reference = reference
        self._tu = require_positive("control_period_s", control_period_s)
        self._kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
        horizon = require_positive("search_horizon_s", search_horizon_s)
        self.horizon_steps = max(1, round(horizon / self._tu))
        # Grid values (position, velocity) per chunk index; old chunks are dropped.
        self._chunks: dict[int, tuple[FloatArray, FloatArray]] = {}
        # Scan state: chunks [0, _scanned) looked at.
        self._scanned = 0
        self._last_nonzero_step = -2  # -2: none yet (a start at step 0 still counts)
        self._last_nonzero_sign = 0
        self._first_motion_step: int | None = None
        self._reversals: list[Reversal] = []
        self._rev_arrays: tuple[FloatArray, FloatArray, IntArray] | None = None
        # Non-zero samples that follow a zero (the end of a standstill) and their sign.
        self._start_steps: list[int] = []
        self._start_signs: list[int] = []
        self._start_arrays: tuple[IntArray, IntArray] | None = None

    @property
    def reversals(self) -> tuple[Reversal, ...]:
        """The reversals found so far (up to the furthest sample scanned)."""
        return tuple(self._reversals)

    # -- the reference on the control grid -----------------------------------

    def _chunk(self, index: int) -> tuple[FloatArray, FloatArray]:
        cached = self._chunks.get(index)
        if cached is not None:
            return cached
        steps = np.arange(index * SCAN_CHUNK_STEPS, (index + 1) * SCAN_CHUNK_STEPS)
        pos, vel, _ = self._reference.sample(steps * self._tu)
        pos = np.asarray(pos, dtype=float)
        vel = np.asarray(vel, dtype=float)
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            raise SignalError(
                f"reference: expected finite position and velocity, got a non-finite value "
                f"between t = {steps[0] * self._tu!r} s and {steps[-1] * self._tu!r} s"
            )
        self._chunks[index] = (pos, vel)
        return pos, vel

    def _velocity_at(self, t_s: float) -> float:
        return float(self._reference.sample(t_s)[1])

    def _locate(self, a_step: int, b_step: int) -> Reversal:
        """The zero of the velocity between samples ``a`` and ``b`` of opposite signs."""
        ta, tb = a_step * self._tu, b_step * self._tu
        fa, fb = self._velocity_at(ta), self._velocity_at(tb)
        if fa == 0.0:
            t_rev = ta
        elif fb == 0.0:
            t_rev = tb
        elif (fa > 0.0) == (fb > 0.0):
            # The grid's array evaluation and this scalar one disagree in the
            # last bit at a velocity of ~0: the smaller end is the zero.
            t_rev = ta if abs(fa) <= abs(fb) else tb
        else:
            # Imported here: scipy.optimize costs every node process ~0.4 s at start-up.
            from scipy.optimize import brentq

            t_rev = float(brentq(self._velocity_at, ta, tb, xtol=1e-13, maxiter=200))
        x_rev = float(self._reference.sample(t_rev)[0])
        return Reversal(time_s=t_rev, position_m=x_rev, detected_step=b_step)

    def _scan_chunk(self, index: int) -> None:
        _, vel = self._chunk(index)
        nz = np.flatnonzero(vel != 0.0)
        if nz.size == 0:
            return
        steps = (index * SCAN_CHUNK_STEPS + nz).astype(np.int64)
        signs = np.where(vel[nz] > 0.0, 1, -1).astype(np.int64)
        prev_steps = np.concatenate(([self._last_nonzero_step], steps[:-1]))
        prev_signs = np.concatenate(([self._last_nonzero_sign], signs[:-1]))
        starts = steps - prev_steps > 1
        if np.any(starts):
            self._start_steps.extend(int(s) for s in steps[starts])
            self._start_signs.extend(int(s) for s in signs[starts])
            self._start_arrays = None
        flips = np.flatnonzero((prev_signs != 0) & (prev_signs != signs))
        for i in flips:
            self._reversals.append(self._locate(int(prev_steps[i]), int(steps[i])))
            self._rev_arrays = None
        if self._first_motion_step is None:
            self._first_motion_step = int(steps[0])
        self._last_nonzero_step = int(steps[-1])
        self._last_nonzero_sign = int(signs[-1])

    def _scan_to(self, step: int) -> None:
        """Look at every sample up to ``step`` (whole chunks)."""
        while self._scanned * SCAN_CHUNK_STEPS <= step:
            self._scan_chunk(self._scanned)
            self._scanned += 1

    def _reversal_arrays(self) -> tuple[FloatArray, FloatArray, IntArray]:
        if self._rev_arrays is None:
            self._rev_arrays = (
                np.array([r.time_s for r in self._reversals], dtype=float),
                np.array([r.position_m for r in self._reversals], dtype=float),
                np.array([r.detected_step for r in self._reversals], dtype=np.int64),
            )
        return self._rev_arrays

    def _standstill_direction(self, steps: IntArray) -> FloatArray:
        """Direction at samples of zero velocity: the motion that follows (see the class)."""
        if self._start_arrays is None:
            self._start_arrays = (
                np.array(self._start_steps, dtype=np.int64),
                np.array(self._start_signs, dtype=np.int64),
            )
        start_steps, start_signs = self._start_arrays
        first = self._first_motion_step
        if first is None or start_steps.size == 0:
            return np.zeros(steps.shape)
        j = np.searchsorted(start_steps, steps, side="right")
        jj = np.minimum(j, start_steps.size - 1)
        follows = (j < start_steps.size) & (start_steps[jj] <= steps + self.horizon_steps)
        # No current at rest before the reference first moves.
        follows &= steps > first
        return np.where(follows, start_signs[jj], 0).astype(float)

    def _grid(self, steps: IntArray) -> tuple[FloatArray, FloatArray]:
        """Position and velocity at ``steps`` from the chunks (the scan's own values)."""
        chunk_of = steps // SCAN_CHUNK_STEPS
        pos = np.empty(steps.shape, dtype=float)
        vel = np.empty(steps.shape, dtype=float)
        for index in np.unique(chunk_of):
            sel = chunk_of == index
            cp, cv = self._chunk(int(index))
            offset = steps[sel] - int(index) * SCAN_CHUNK_STEPS
            pos[sel] = cp[offset]
            vel[sel] = cv[offset]
        return pos, vel

    # -- the term --------------------------------------------------------------

    def distance_and_direction(self, steps: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``z`` (m, ``inf`` with no reversal) and the direction (+1, -1, 0) at control samples.

        Parameters
        ----------
        steps : array_like of int
            Control samples ``k >= 0``.

        Raises
        ------
        SignalError
            Negative or non-integer samples.
        """
        k_in = np.asarray(steps)
        if k_in.size and (not np.issubdtype(k_in.dtype, np.integer) or np.min(k_in) < 0):
            raise SignalError("steps: expected control samples as integers >= 0")
        k = k_in.astype(np.int64).reshape(-1)
        if k.size == 0:
            return np.zeros(0), np.zeros(0)
        h = self.horizon_steps
        self._scan_to(int(k.max()) + h)
        x, v = self._grid(k)
        t = k * self._tu

        rev_t, rev_x, rev_b = self._reversal_arrays()
        known = np.searchsorted(rev_b, k + h, side="right")
        before = np.searchsorted(rev_t, t, side="right")
        prev_idx = np.minimum(before, known) - 1
        has_next = before < known
        z = np.full(k.shape, np.inf)
        if rev_t.size:
            has_prev = prev_idx >= 0
            z[has_prev] = np.abs(x[has_prev] - rev_x[prev_idx[has_prev]])
            nxt = np.abs(x[has_next] - rev_x[before[has_next]])
            z[has_next] = np.minimum(z[has_next], nxt)

        direction = np.sign(v)
        still = v == 0.0
        if np.any(still):
            direction[still] = self._standstill_direction(k[still])

        self._forget_before(int(k.min()))
        return z.reshape(k_in.shape), direction.reshape(k_in.shape)

    def _forget_before(self, step: int) -> None:
        first_kept = step // SCAN_CHUNK_STEPS
        for index in [i for i in self._chunks if i < first_kept]:
            del self._chunks[index]

    def torque_Nm(self, steps: ArrayLike) -> FloatArray:
        """``F_c`` of eq. (9) at control samples, motor torque, N m."""
        z, direction = self.distance_and_direction(steps)
        return sigmoid_torque(z, direction, self.params)

    def currents(self, block: ReferenceBlock) -> FloatArray:
        """``F_c / K_T`` (A) at each sample of ``block`` (only its steps are used)."""
        return np.asarray(self.torque_Nm(block.step) / self._kt, dtype=float)
