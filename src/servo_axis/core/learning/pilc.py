"""Projection-based ILC with basis functions and a data-based friction model (paper 001).

Paper 001 (Hayashi, Fujimoto, Isaoka, Terada), Sect. III-B, III-C, IV-A:
the feedforward current is parameterised, ``f^p = Psi(r) theta``
(eq. (10)), so that what is learned carries over to another reference:

1. ``f^np_{j+1} = Q (f_j + L e_j)`` (eq. (3)), as if ``r_j`` were repeated
   (``Q``, ``L`` of :mod:`.ilc`);
2. ``theta_{j+1}`` by least squares of eq. (19)
   (``min || S_n P_n f^np - S_n P_n Psi(r_j) theta ||``) or, for the
   proposal, eq. (23) with the weighting ``W_j`` of eq. (26)-(27), which
   keeps only the samples more than ``threshold_m`` from a velocity reversal
   (where rolling friction is Coulomb friction);
3. (proposal) the rolling friction ``T_rf_hat`` of eq. (20);
4. (proposal) the friction table of Fig. 8: ``T_rf_hat`` against the
   displacement ``x_r`` from the last velocity reversal, within the
   threshold;
5. the next feedforward from ``r_{j+1}``: ``Psi(r_{j+1}) theta_{j+1}``
   (eq. (11), P-ILC (B.F.)) or the inertia and viscous terms plus the table
   within the threshold and the estimated Coulomb friction beyond it
   (P-ILC (B.F.+F.T.), Sect. IV-A-6).

Basis (eq. (13)-(14)): ``Psi(r) = [r'', r', b_rf]`` with
``b_rf = sign(r') min(2 x_r / x_mu - 1, 1)`` and
``theta = [J/(R K_T), D/(R K_T), T_c/K_T]``. Units: ``r`` in m at the table,
``f`` in A, torques in N m.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import ConfigError, SignalError, TableError, require_positive
from servo_axis.core.learning.ilc import (
    IlcParams,
    check_count,
    check_trial_signal,
    learning_filter,
    process_sensitivity,
    require_convergence,
    trial_q,
)

FloatArray = NDArray[np.float64]
#: ``reference_of(trial)``: position (m), velocity (m/s), acceleration (m/s^2) of a 1-based trial.
ReferenceOf = Callable[[int], tuple[ArrayLike, ArrayLike, ArrayLike]]


def _signal(name: str, value: ArrayLike, samples: int | None = None) -> FloatArray:
    try:
        x = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SignalError(f"{name}: expected an array of numbers") from None
    if x.ndim != 1 or (samples is not None and x.size != samples):
        expected = "a 1-D array" if samples is None else f"{samples} samples"
        raise SignalError(f"{name}: expected {expected}, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise SignalError(f"{name}: expected finite values")
    return x


# -- basis functions ----------------------------------------------------------------


def reversal_state(position_m: ArrayLike, velocity_m_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Displacement ``x_r`` (m, >= 0) from the last velocity reversal, and the direction of motion.

    A reversal is a change of the sign of the velocity, exact zeros (rest)
    skipped. Rolling friction is a function of the displacement from the
    last reversal and of the direction (001 Fig. 2), not of the speed, so
    while the reference rests both are held: ``direction`` is the sign of
    the last non-zero velocity, and a rest ends with no reversal unless the
    motion resumes the other way. A trial starts and ends at rest at the same
    position, so it is taken as one period of a repeated motion: before its
    first move it is in the state its own end leaves (the previous trial
    ended that way), and its first move is a reversal when it goes the other
    way. The reversal point is the position of the last sample before the
    new direction (the turning point as sampled), so
    ``x_r[k] = |r[k] - r[k_rev - 1]|``.

    Parameters
    ----------
    position_m, velocity_m_s : array, shape (N,)
        Reference position (m) and velocity (m/s) at the table.

    Returns
    -------
    x_r : ndarray, shape (N,)
        m; 0 throughout for a trial without motion.
    direction : ndarray, shape (N,)
        +1, -1 (0 throughout for a trial without motion).
    """
    pos = _signal("position_m", position_m)
    vel = _signal("velocity_m_s", velocity_m_s, pos.size)
    signs = np.sign(vel)

    def sweep(direction: float, anchor: float) -> tuple[FloatArray, FloatArray, float, float]:
        x_r = np.empty(pos.size)
        held = np.empty(pos.size)
        for k, s in enumerate(signs):
            if s != 0.0 and s != direction:
                anchor = float(pos[k - 1])  # pos[-1]: the end of the trial before
                direction = float(s)
            x_r[k] = abs(pos[k] - anchor)
            held[k] = direction
        return x_r, held, direction, anchor

    # First pass: the state at the end of the trial, which is the state at
    # its start; second pass: the trial from that state.
    _, _, direction, anchor = sweep(0.0, float(pos[0]))
    x_r, held, _, _ = sweep(direction, anchor)
    return x_r, held


def reversal_displacement(position_m: ArrayLike, velocity_m_s: ArrayLike) -> FloatArray:
    """``x_r`` of :func:`reversal_state` (m, >= 0)."""
    return reversal_state(position_m, velocity_m_s)[0]


def friction_basis(position_m: ArrayLike, velocity_m_s: ArrayLike, *, x_mu_m: float) -> FloatArray:
    """``b_rf = sign(r') min(2 x_r / x_mu - 1, 1)`` of eq. (13).

    ``sign(r')`` is the direction of :func:`reversal_state`: held through a
    rest, where rolling friction keeps the value its displacement gives
    (measured on this suite's axis: after a move the PID holds the Coulomb
    level at standstill, and eq. (13) read with ``sign(0) = 0`` put an error
    of the whole Coulomb current into every rest sample of ``W``).

    Parameters
    ----------
    position_m, velocity_m_s : array, shape (N,)
        Reference position (m) and velocity (m/s).
    x_mu_m : float
        ``x_mu``, m, > 0 (5e-6 in 001 Sect. IV-A-4).
    """
    x_mu = require_positive("x_mu_m", x_mu_m)
    x_r, direction = reversal_state(position_m, velocity_m_s)
    return np.asarray(direction * np.minimum(2.0 * x_r / x_mu - 1.0, 1.0), dtype=float)


def basis(
    position_m: ArrayLike,
    velocity_m_s: ArrayLike,
    acceleration_m_s2: ArrayLike,
    *,
    x_mu_m: float,
) -> FloatArray:
    """``Psi(r)`` of eq. (14a), shape (N, 3): columns ``[r'', r', b_rf]``.

    ``Psi(r) theta`` with ``theta = [J/(R K_T), D/(R K_T), T_c/K_T]``
    (eq. (14b)) is a current in A.
    """
    vel = _signal("velocity_m_s", velocity_m_s)
    acc = _signal("acceleration_m_s2", acceleration_m_s2, vel.size)
    return np.column_stack((acc, vel, friction_basis(position_m, vel, x_mu_m=x_mu_m)))


def weighting(
    x_r_m: ArrayLike, *, threshold_m: float, velocity_m_s: ArrayLike | None = None
) -> FloatArray:
    """Diagonal of ``W`` (eq. (26)-(27)): 1 where ``x_r > threshold_m``, else 0.

    With ``velocity_m_s``, also 0 where the reference rests: eq. (27) keeps
    the samples where rolling friction is Coulomb friction, and at rest it is
    not (the stage does not roll; what holds it there is the PID's integrator,
    which the error, 0 at rest, does not show, so ``f^np`` at rest only
    repeats the previous estimate). Measured on this suite's axis: with the
    rest samples in ``W`` the Coulomb and viscous estimates swung by 30 %
    from trial to trial; without them J, D and T_c land within 1 % of the
    plant's.

    Raises
    ------
    SignalError
        Naming ``threshold_m`` when no sample is left: ``W`` all zero
        leaves nothing to estimate ``theta`` from (eq. (23)).
    """
    threshold = require_positive("threshold_m", threshold_m)
    x_r = _signal("x_r_m", x_r_m)
    w = (x_r > threshold).astype(float)
    if velocity_m_s is not None:
        w *= _signal("velocity_m_s", velocity_m_s, x_r.size) != 0.0
    if not np.any(w):
        raise SignalError(
            f"threshold_m: no sample of the trial is more than threshold_m = {threshold!r} m "
            "from a velocity reversal while moving: W of eq. (27) is all zero"
        )
    return w


# -- estimation ---------------------------------------------------------------------------


def estimate_parameters(
    f_np: ArrayLike,
    psi: ArrayLike,
    *,
    sensitivity: tuple[ArrayLike, ArrayLike],
    weights: ArrayLike | None = None,
) -> FloatArray:
    """``theta`` by least squares of eq. (19) (``weights`` None) or eq. (23) (``W`` given).

    ``min || S_n P_n W f^np - S_n P_n W Psi theta ||_2``: ``W f^np`` and each
    column of ``W Psi`` are filtered through ``S_n P_n`` over the trial
    (``lfilter``, zero initial conditions) and the columns are scaled to unit
    norm before ``numpy.linalg.lstsq`` (their units differ by orders of
    magnitude).

    Parameters
    ----------
    f_np : array, shape (N,)
        ``f^np_{j+1}``, A.
    psi : array, shape (N, n_theta)
        ``Psi(r_j)``.
    sensitivity : (num, den)
        ``S_n P_n`` in powers of ``z^-1`` (:func:`.ilc.process_sensitivity`).
    weights : array, shape (N,), optional
        Diagonal of ``W_j`` (:func:`weighting`).

    Returns
    -------
    ndarray, shape (n_theta,)

    Raises
    ------
    SignalError
        Wrong shapes or values, ``W`` all zero, or columns of ``Psi`` that
        are linearly dependent over the (weighted) trial (a parameter the
        trial does not excite).
    """
    f = _signal("f_np", f_np)
    try:
        x = np.asarray(psi, dtype=float)
    except (TypeError, ValueError):
        raise SignalError("psi: expected an array of numbers") from None
    if x.ndim != 2 or x.shape[0] != f.size or x.shape[1] < 1:
        raise SignalError(f"psi: expected shape ({f.size}, n_theta), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise SignalError("psi: expected finite values")
    if weights is not None:
        w = _signal("weights", weights, f.size)
        if not np.any(w):
            raise SignalError("weights: W of eq. (23) is all zero: no sample to estimate from")
        f = w * f
        x = w[:, None] * x
    num, den = (np.asarray(v, dtype=float) for v in sensitivity)
    import scipy.signal  # here: it costs a node ~1 s at start-up

    y = scipy.signal.lfilter(num, den, f)
    a = scipy.signal.lfilter(num, den, x, axis=0)
    norms = np.linalg.norm(a, axis=0)
    if not np.all(norms > 0.0):
        raise SignalError(
            f"psi: columns {np.flatnonzero(norms == 0.0).tolist()} of Psi are zero over the "
            "(weighted) trial: their parameters are not excited"
        )
    solution, _, rank, _ = np.linalg.lstsq(a / norms, y, rcond=None)
    if rank < a.shape[1]:
        raise SignalError(
            f"psi: the columns of Psi are linearly dependent over the (weighted) trial "
            f"(rank {rank} < {a.shape[1]}): the trial does not excite every parameter"
        )
    return np.asarray(solution / norms, dtype=float)


def estimate_friction(
    f_np: ArrayLike,
    acceleration_m_s2: ArrayLike,
    velocity_m_s: ArrayLike,
    *,
    theta: ArrayLike,
    torque_constant_Nm_per_A: float,
) -> FloatArray:
    """Rolling friction ``T_rf_hat = (f^np - J/(R K_T) r'' - D/(R K_T) r') K_T`` (eq. (20)), N m.

    ``theta[0] = J_hat/(R K_T)``, ``theta[1] = D_hat/(R K_T)`` (eq. (14b)).
    """
    f = _signal("f_np", f_np)
    acc = _signal("acceleration_m_s2", acceleration_m_s2, f.size)
    vel = _signal("velocity_m_s", velocity_m_s, f.size)
    th = _signal("theta", theta)
    if th.size < 2:
        raise SignalError(f"theta: expected at least 2 values, got {th.size}")
    kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
    return np.asarray((f - th[0] * acc - th[1] * vel) * kt, dtype=float)


class LearnedFrictionTable:
    """The data-based friction model of 001 Fig. 8 (Takemura & Fujimoto, 001 ref. [11]).

    Entries ``(x_r, T)``: displacement from the last velocity reversal (m)
    and rolling friction normalised to the direction of motion
    (``T = sign(r') T_rf``, N m), which runs from about ``-T_c`` right after
    a reversal to about ``+T_c``; sorted by ``x_r`` (stable: entries of
    equal ``x_r`` keep their order).

    Not the feedforward's :class:`~servo_axis.core.feedforward.friction_table.FrictionTable`:
    this one is learned by the PILC from each trial's friction estimate
    (:meth:`from_trial`), keeps repeated displacements and lives in the
    learning law's memory; that one is a file's strictly increasing table
    from 0, read once and applied as a feedforward term.

    Parameters
    ----------
    x_r_m : array, shape (M,)
        Displacements, m, >= 0, M >= 1.
    torque_Nm : array, shape (M,)
        Normalised friction, N m.

    Raises
    ------
    TableError
        An empty table, different lengths, negative or non-finite values.
    """

    def __init__(self, x_r_m: ArrayLike, torque_Nm: ArrayLike) -> None:
        try:
            x = np.asarray(x_r_m, dtype=float)
            t = np.asarray(torque_Nm, dtype=float)
        except (TypeError, ValueError):
            raise TableError("x_r_m, torque_Nm: expected arrays of numbers") from None
        if x.ndim != 1 or t.shape != x.shape:
            raise TableError(
                f"x_r_m, torque_Nm: expected two 1-D arrays of one length, got {x.shape}, {t.shape}"
            )
        if x.size == 0:
            raise TableError("x_r_m: the friction table is empty (no entry to look up)")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(t))):
            raise TableError("x_r_m, torque_Nm: expected finite values")
        if np.any(x < 0.0):
            raise TableError("x_r_m: expected displacements >= 0")
        order = np.argsort(x, kind="stable")
        self._x = x[order]
        self._t = t[order]

    @classmethod
    def from_trial(
        cls,
        x_r_m: ArrayLike,
        velocity_m_s: ArrayLike,
        friction_Nm: ArrayLike,
        *,
        threshold_m: float,
    ) -> LearnedFrictionTable:
        """The table of one trial (001 Sect. III-C step 4, IV-A-6).

        Keeps the moving samples (``r' != 0``) with ``x_r <= threshold_m``,
        normalised to the direction of motion: ``T = sign(r') T_rf_hat``.
        Each reversal of the trial gives a curve of ``T`` against ``x_r``; the
        table holds their mean, at every ``x_r`` any of them was sampled at
        (each curve interpolated linearly within the range it covers), so
        that it is one value per displacement as in Fig. 8. Kept side by
        side, the curves of two reversals alternated in the table and the
        closest-entry lookup jumped between them (measured: up to 0.6 N m,
        error spikes of 10 um on this suite's axis).

        Parameters
        ----------
        x_r_m : array, shape (N,)
            :func:`reversal_displacement` of ``r_j``, m.
        velocity_m_s : array, shape (N,)
            ``r_j'``, m/s.
        friction_Nm : array, shape (N,)
            ``T_rf_hat`` of eq. (20), N m.
        threshold_m : float
            m, > 0.
        """
        threshold = require_positive("threshold_m", threshold_m)
        x = _signal("x_r_m", x_r_m)
        vel = _signal("velocity_m_s", velocity_m_s, x.size)
        t = _signal("friction_Nm", friction_Nm, x.size)
        keep = (x <= threshold) & (vel != 0.0)
        if not np.any(keep):
            raise TableError(
                f"threshold_m: no moving sample of the trial is within threshold_m = {threshold!r} m "
                "of a velocity reversal: the friction table would be empty"
            )
        # x_r grows from each reversal on and falls back at the next one.
        segment = np.concatenate(([0], np.cumsum(np.diff(x) < 0.0)))
        curves = []
        for seg in np.unique(segment[keep]):
            mine = keep & (segment == seg)
            order = np.argsort(x[mine], kind="stable")
            curves.append((x[mine][order], (np.sign(vel[mine]) * t[mine])[order]))
        grid = np.unique(np.concatenate([c[0] for c in curves]))
        total = np.zeros(grid.size)
        count = np.zeros(grid.size)
        for cx, ct in curves:
            inside = (grid >= cx[0]) & (grid <= cx[-1])
            total[inside] += np.interp(grid[inside], cx, ct)
            count[inside] += 1.0
        return cls(grid, total / count)

    def __len__(self) -> int:
        return int(self._x.size)

    def lookup(self, x_r_m: ArrayLike) -> FloatArray:
        """The value of the closest entry (closest ``x_r``; on a tie the smaller ``x_r``), N m.

        Beyond the ends of the table the end entries are used.
        """
        q = np.asarray(x_r_m, dtype=float)
        if not np.all(np.isfinite(q)):
            raise SignalError("x_r_m: expected finite values")
        n = self._x.size
        idx = np.searchsorted(self._x, q, side="left")
        right = np.clip(idx, 0, n - 1)
        left = np.clip(idx - 1, 0, n - 1)
        use_right = np.abs(self._x[right] - q) < np.abs(q - self._x[left])
        return np.asarray(self._t[np.where(use_right, right, left)], dtype=float)

    def arrays(self) -> tuple[FloatArray, FloatArray]:
        """``(x_r_m, torque_Nm)``: copies of the sorted entries."""
        return self._x.copy(), self._t.copy()


@dataclass(frozen=True, kw_only=True)
class ProjectionParams:
    """Parameters of the basis function and the friction table (001 Sect. IV-A-4..6).

    Parameters
    ----------
    x_mu_m : float
        ``x_mu`` of eq. (13), m, > 0.
    threshold_m : float
        Threshold of ``W`` (eq. (27)) and extent of the friction table, m, > 0.
    """

    x_mu_m: float = 5e-6
    threshold_m: float = 1e-4

    def __post_init__(self) -> None:
        require_positive("x_mu_m", self.x_mu_m)
        require_positive("threshold_m", self.threshold_m)


class ProjectionIlc:
    """P-ILC (B.F.) (``pilc_bf``) and P-ILC (B.F.+F.T.) (``pilc_bfft``, the proposal) of 001.

    Parameters
    ----------
    ilc : IlcParams
        ``N``, ``Nq``, period, lead, nominal model and PID (``Q``, ``L`` and
        ``S_n P_n`` as for S-ILC).
    projection : ProjectionParams
        ``x_mu`` and the threshold.
    reference_of : callable
        ``reference_of(trial)``: ``(position_m, velocity_m_s,
        acceleration_m_s2)`` of the 1-based trial, ``N`` samples each; the
        reference may change between trials.
    friction_table : bool
        True: the proposal, eq. (23) and the friction table; False: eq. (19)
        and eq. (11).

    Raises
    ------
    ConfigError
        Naming ``nq`` when the nominal loop violates eq. (7).
    """

    period = "trial"
    side = "input"

    def __init__(
        self,
        *,
        ilc: IlcParams,
        projection: ProjectionParams,
        reference_of: ReferenceOf,
        friction_table: bool,
    ) -> None:
        if not isinstance(ilc, IlcParams):
            raise ConfigError(f"ilc: expected IlcParams, got {type(ilc).__name__}")
        if not isinstance(projection, ProjectionParams):
            raise ConfigError(
                f"projection: expected ProjectionParams, got {type(projection).__name__}"
            )
        if not callable(reference_of):
            raise ConfigError(
                "reference_of: expected a callable trial -> (position, velocity, acceleration)"
            )
        if not isinstance(friction_table, bool):
            raise ConfigError(f"friction_table: expected a bool, got {friction_table!r}")
        self.params = ilc
        self.projection = projection
        self.uses_table = friction_table
        #: ``pilc_bfft`` with the friction table, else ``pilc_bf``.
        self.name: str = "pilc_bfft" if friction_table else "pilc_bf"
        self._reference_of = reference_of
        self.learning_filter = learning_filter(ilc)
        #: Nominal measure of eq. (7) (< 1).
        self.convergence = require_convergence(ilc)
        self._sensitivity = process_sensitivity(ilc)
        self._theta = np.zeros(3)
        self._table: LearnedFrictionTable | None = None
        self._trials_learned = 0
        self._last_trial = 0

    # -- helpers -----------------------------------------------------------------
    @staticmethod
    def _check_period(period: int | None) -> int:
        if period is None:
            raise SignalError(
                "period: expected the 1-based trial number (the reference may change between "
                "trials), got None"
            )
        if isinstance(period, bool) or not isinstance(period, int) or period < 1:
            raise SignalError(f"period: expected an integer >= 1, got {period!r}")
        return period

    def _reference(self, trial: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        value = self._reference_of(trial)
        if not isinstance(value, tuple | list) or len(value) != 3:
            raise SignalError(
                f"reference_of({trial}): expected (position_m, velocity_m_s, acceleration_m_s2)"
            )
        n = self.params.samples_per_trial
        names = ("position_m", "velocity_m_s", "acceleration_m_s2")
        pos, vel, acc = (
            check_trial_signal(f"reference_of({trial}) {name}", v, n)
            for name, v in zip(names, value, strict=True)
        )
        return pos, vel, acc

    def _feedforward(self, pos: FloatArray, vel: FloatArray, acc: FloatArray) -> FloatArray:
        theta = self._theta
        inertial = theta[0] * acc + theta[1] * vel
        if self._table is None:
            # eq. (11): Psi(r) theta (zero before anything is learned).
            return np.asarray(
                inertial + theta[2] * friction_basis(pos, vel, x_mu_m=self.projection.x_mu_m),
                dtype=float,
            )
        # Sect. IV-A-6: the table within the threshold, T_c_hat / K_T = theta[2] beyond.
        x_r, direction = reversal_state(pos, vel)
        kt = self.params.nominal.torque_constant_Nm_per_A
        within = x_r <= self.projection.threshold_m
        friction = np.where(within, self._table.lookup(x_r) / kt, theta[2])
        return np.asarray(inertial + direction * friction, dtype=float)

    # -- LearningLaw -----------------------------------------------------------------
    @property
    def samples_per_period(self) -> int:
        """``N``."""
        return self.params.samples_per_trial

    @property
    def periods_learned(self) -> int:
        """Trials learned so far."""
        return self._trials_learned

    def learn(self, error: ArrayLike, *, period: int | None = None) -> FloatArray:
        """Learn trial ``period`` (steps 1-4 of 001 Sect. III-B / III-C).

        ``f_j`` is the feedforward applied in trial ``j = period``, i.e.
        :meth:`next_correction` for ``j`` from the state before this call
        (zero before anything is learned); then
        ``f^np_{j+1} = Q (f_j + L e_j)`` (eq. (3)), ``theta_{j+1}`` by eq. (19)
        (``pilc_bf``) or eq. (23) with ``W_j`` (``pilc_bfft``), and for
        ``pilc_bfft`` ``T_rf_hat`` (eq. (20)) and the friction table from
        ``r_j``. The state changes only if every step succeeds.

        Parameters
        ----------
        error : array, shape (N,)
            ``e_j = r_j - x``, m, per control sample.
        period : int
            The 1-based trial number ``j`` (required).

        Returns
        -------
        ndarray, shape (N,)
            ``f^np_{j+1}``, A.
        """
        trial = self._check_period(period)
        e = check_trial_signal("error", error, self.params.samples_per_trial)
        pos, vel, acc = self._reference(trial)
        f_j = self._feedforward(pos, vel, acc)
        f_np = trial_q(f_j + self.learning_filter.apply(e), self.params.nq)
        psi = basis(pos, vel, acc, x_mu_m=self.projection.x_mu_m)
        table: LearnedFrictionTable | None = None
        if self.uses_table:
            threshold = self.projection.threshold_m
            x_r = reversal_displacement(pos, vel)
            w = weighting(x_r, threshold_m=threshold, velocity_m_s=vel)
            theta = estimate_parameters(f_np, psi, sensitivity=self._sensitivity, weights=w)
            friction = estimate_friction(
                f_np,
                acc,
                vel,
                theta=theta,
                torque_constant_Nm_per_A=self.params.nominal.torque_constant_Nm_per_A,
            )
            table = LearnedFrictionTable.from_trial(x_r, vel, friction, threshold_m=threshold)
        else:
            theta = estimate_parameters(f_np, psi, sensitivity=self._sensitivity)
        self._theta = theta
        self._table = table
        self._trials_learned += 1
        self._last_trial = trial
        return f_np

    def next_correction(self, *, period: int | None = None) -> tuple[FloatArray]:
        """``(f^p,)``: the feedforward current (A) per control sample of trial ``period``.

        ``pilc_bf``: ``Psi(r) theta`` (eq. (11)); ``pilc_bfft``:
        ``theta_0 r'' + theta_1 r'`` plus ``sign(r') T(x_r) / K_T`` from the
        friction table where ``x_r <= threshold_m`` and
        ``sign(r') T_c_hat / K_T`` beyond (0 where ``r' = 0``); ``r`` is
        ``reference_of(period)``. Zeros before anything is learned. A pure
        function of the state and ``period``.
        """
        trial = self._check_period(period)
        return (self._feedforward(*self._reference(trial)),)

    # -- results ---------------------------------------------------------------------
    def parameters(self) -> FloatArray:
        """``theta = [J/(R K_T), D/(R K_T), T_c/K_T]`` (eq. (14b)); zeros before learning."""
        return self._theta.copy()

    def physical_parameters(self) -> dict[str, float]:
        """``J_hat`` (kg m^2), ``D_hat`` (N m s/rad), ``T_c_hat`` (N m) from ``theta``."""
        kt = self.params.nominal.torque_constant_Nm_per_A
        rkt = self.params.lead_m_per_rad * kt
        return {
            "inertia_kgm2": float(self._theta[0] * rkt),
            "damping_Nms_per_rad": float(self._theta[1] * rkt),
            "coulomb_Nm": float(self._theta[2] * kt),
        }

    def friction_table(self) -> tuple[FloatArray, FloatArray]:
        """``(x_r_m, torque_Nm)`` of the table; empty arrays for ``pilc_bf`` or before learning."""
        if self._table is None:
            return np.zeros(0), np.zeros(0)
        return self._table.arrays()

    # -- memory ------------------------------------------------------------------------
    def identity(self) -> dict[str, Any]:
        """Law, ``N``, ``Nq``, ``T_s``, ``R``, nominal model, PID, ``x_mu`` and threshold."""
        return {
            "law": self.name,
            **self.params.identity(),
            "x_mu_m": self.projection.x_mu_m,
            "threshold_m": self.projection.threshold_m,
        }

    def state(self) -> dict[str, Any]:
        """``theta``, the friction table, trials learned and the last trial learned (exact floats).

        ``f_j`` is not stored: it is :meth:`next_correction` of the stored
        state for trial ``j``.
        """
        x_r, torque = self.friction_table()
        return {
            "theta": self._theta.tolist(),
            "table_x_r_m": x_r.tolist(),
            "table_torque_Nm": torque.tolist(),
            "trials_learned": self._trials_learned,
            "last_trial": self._last_trial,
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state` output (SignalError on a wrong length or value)."""
        trials = check_count("trials_learned", state.get("trials_learned"))
        last = check_count("last_trial", state.get("last_trial"))
        raw_theta = state.get("theta")
        if not isinstance(raw_theta, list):
            raise SignalError("theta: expected a list of 3 numbers")
        theta = check_trial_signal("theta", raw_theta, 3, "J, D and T_c terms of eq. (14b)")
        x_r, torque = state.get("table_x_r_m"), state.get("table_torque_Nm")
        if not isinstance(x_r, list) or not isinstance(torque, list) or len(x_r) != len(torque):
            raise SignalError("table_x_r_m, table_torque_Nm: expected two lists of one length")
        table: LearnedFrictionTable | None = None
        if self.uses_table and trials > 0:
            try:
                table = LearnedFrictionTable(x_r, torque)
            except TableError as err:
                raise SignalError(f"table_x_r_m: {err}") from None
        elif x_r:
            raise SignalError(
                f"table_x_r_m: expected no friction table for {self.name} with "
                f"{trials} trials learned, got {len(x_r)} entries"
            )
        self._theta = theta.copy()
        self._table = table
        self._trials_learned = trials
        self._last_trial = last
