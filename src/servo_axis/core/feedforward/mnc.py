"""The multirate nonlinearity compensator of paper 003 (MNC, eqs. (12)-(15), (17)).

A feedforward term (:mod:`.terms`) for the tilting table of 003 eq. (2):
the unbalance torque ``U sin(theta_d)`` (eq. (13)) and, unless it is the
previous MARC (eq. (17): unbalance only), the friction model of eq. (14)

    T_f(w_d) = C / pi (atan(alpha (w_d - w_th)) + atan(alpha (w_d + w_th))),

divided by ``K_T`` to give a current. It runs at ``T_r``: for the two
control samples ``k = 2i`` and ``k + 1`` of reference interval ``i`` the
lifted vector of eq. (13)/(15) is ``[f(theta_d[k]), f(theta_d[k + 2])]``,
i.e. the first sample takes the reference at the interval's start and the
second at its end (the next reference instant); with ``T_r = r T_u`` every
sample after the first takes the interval's end.

``U`` and ``C`` can change while the axis runs (the adaptive case: the
estimates of the identifier, 003 Fig. 3): each takes effect from a control
sample, forwards in time only (:meth:`set_parameters`), so that what a
sample gets depends only on the estimates scheduled for it.

The reference is read in the suite's unit of the table side (m); for the
rotary table the lead is 1 m/rad, so it is the angle in rad (the scenario
says so).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.errors import (
    ConfigError,
    require_finite,
    require_nonnegative,
    require_positive,
)
from servo_axis.core.feedforward.terms import ReferenceBlock
from servo_axis.core.reference import GridSamples, Reference

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class MncParams:
    """Parameters of the compensator.

    Parameters
    ----------
    unbalance_Nm : float
        Initial ``U`` (N m, >= 0): 003 Table I gives 0.1 as the initial estimate.
    coulomb_Nm : float
        Initial ``C`` (N m, >= 0), 0.01 in 003 Table I.
    friction : bool
        Compensate friction with eq. (14) (the proposal) or not (the previous
        MARC, eq. (17)).
    alpha : float
        ``alpha`` of eq. (14), s/rad, > 0 (1e4).
    omega_th_rad_s : float
        ``w_th`` of eq. (14), the dead zone, rad/s, >= 0 (0.05).
    torque_constant_Nm_per_A : float
        Nominal ``K_T``, N m/A, > 0.
    lead_m_per_rad : float
        The reference's unit per rad of angle, > 0 (1.0 for a rotary axis).
    ratio : int
        ``T_r / T_u``, >= 1.
    control_period_s : float
        ``T_u``, s, > 0.
    """

    unbalance_Nm: float = 0.1
    coulomb_Nm: float = 0.01
    friction: bool = True
    alpha: float = 1e4
    omega_th_rad_s: float = 0.05
    torque_constant_Nm_per_A: float = 1.0
    lead_m_per_rad: float = 1.0
    ratio: int = 2
    control_period_s: float = 4e-4

    def __post_init__(self) -> None:
        require_nonnegative("unbalance_Nm", self.unbalance_Nm)
        require_nonnegative("coulomb_Nm", self.coulomb_Nm)
        require_positive("alpha", self.alpha)
        require_nonnegative("omega_th_rad_s", self.omega_th_rad_s)
        require_positive("torque_constant_Nm_per_A", self.torque_constant_Nm_per_A)
        require_positive("lead_m_per_rad", self.lead_m_per_rad)
        require_positive("control_period_s", self.control_period_s)
        if isinstance(self.ratio, bool) or not isinstance(self.ratio, int) or self.ratio < 1:
            raise ConfigError(f"ratio: expected an integer >= 1, got {self.ratio!r}")


def friction_model_Nm(
    omega_rad_s: FloatArray, *, coulomb_Nm: float, alpha: float, omega_th_rad_s: float
) -> FloatArray:
    """``T_f(w)`` of 003 eq. (14), N m: ``+-C`` beyond the dead zone, 0 at ``w = 0``."""
    w = np.asarray(omega_rad_s, dtype=float)
    return np.asarray(
        coulomb_Nm
        / math.pi
        * (np.arctan(alpha * (w - omega_th_rad_s)) + np.arctan(alpha * (w + omega_th_rad_s))),
        dtype=float,
    )


class NonlinearityCompensator:
    """The MNC as a feedforward term; see the module docstring.

    Parameters
    ----------
    params : MncParams
        Initial ``U``, ``C`` and the model's constants.
    reference : Reference
        The trajectory (it is sampled at the reference instants around each
        control sample, which may lie outside the block asked for).
    """

    def __init__(self, params: MncParams, *, reference: Reference) -> None:
        self.params = params
        self._reference = reference
        # The reference at the control samples, computed a chunk at a time
        # (the same numbers as sampling each block: GridSamples).
        self._samples = GridSamples(reference, params.control_period_s)
        # (from_step, U, C), from_step increasing.
        self._schedule: list[tuple[int, float, float]] = [
            (0, params.unbalance_Nm, params.coulomb_Nm)
        ]
        # sin(theta) and the friction model's shape (C = 1) at every step of the
        # samples GridSamples keeps, computed once per chunk instead of once per
        # block (one block per online estimate): elementwise, the same numbers.
        self._derived_of: FloatArray | None = None
        self._sin: list[float] = []
        self._shape: list[float] = []

    def set_parameters(self, *, from_step: int, unbalance_Nm: float, coulomb_Nm: float) -> None:
        """Use ``U``, ``C`` from control sample ``from_step`` on (after the last one set).

        Raises
        ------
        ConfigError
            A step not after the last one scheduled, or a negative / non-finite value.
        """
        last = self._schedule[-1][0]
        if isinstance(from_step, bool) or not isinstance(from_step, int) or from_step <= last:
            raise ConfigError(f"from_step: expected an integer after {last}, got {from_step!r}")
        u = require_nonnegative("unbalance_Nm", require_finite("unbalance_Nm", unbalance_Nm))
        c = require_nonnegative("coulomb_Nm", require_finite("coulomb_Nm", coulomb_Nm))
        self._schedule.append((from_step, u, c))

    def forget_before(self, step: int) -> None:
        """Drop the entries no sample from ``step`` on can use (keeps the one in force)."""
        while len(self._schedule) > 1 and self._schedule[1][0] <= step:
            self._schedule.pop(0)

    def parameters_at(self, steps: NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
        """``U`` and ``C`` in force at each control sample of ``steps``."""
        starts = np.array([s for s, _, _ in self._schedule])
        idx = np.searchsorted(starts, np.asarray(steps), side="right") - 1
        if np.any(idx < 0):
            raise ConfigError("steps: expected samples at or after the first scheduled one")
        u = np.array([v for _, v, _ in self._schedule])[idx]
        c = np.array([v for _, _, v in self._schedule])[idx]
        return u, c

    def currents(self, block: ReferenceBlock) -> FloatArray:
        p = self.params
        k = np.asarray(block.step, dtype=np.int64)
        steps: list[int] = k.tolist() if k.ndim == 1 else []
        if not steps:
            return self._currents(k)
        k0, n = steps[0], len(steps)
        schedule = self._schedule
        # Consecutive steps from the schedule's first on (what the generator
        # gives); anything else, or its error, is _currents'.
        if k0 < schedule[0][0] or steps != list(range(k0, k0 + n)):
            return self._currents(k)
        r = p.ratio
        # eq. (13)/(15): the interval's start for its first sample, its end after.
        at = [s if s % r == 0 else s - s % r + r for s in steps]
        start, values = self._samples.kept(at[0], at[-1])
        if values is not self._derived_of:
            # theta, sin(theta), omega and T_f(omega) / C as _currents forms them,
            # for the whole kept range (elementwise: the same numbers), as floats.
            self._sin = np.sin(values[0] / p.lead_m_per_rad).tolist()
            if p.friction:
                self._shape = friction_model_Nm(
                    values[1] / p.lead_m_per_rad,
                    coulomb_Nm=1.0,
                    alpha=p.alpha,
                    omega_th_rad_s=p.omega_th_rad_s,
                ).tolist()
            self._derived_of = values
        # Per entry of the schedule in force over the block (the one
        # parameters_at finds for each step), _currents' operations on floats,
        # in its order: (U sin(theta) + T_f(omega) / C * C) / K_T.
        kt = p.torque_constant_Nm_per_A
        sin, shape = self._sin, self._shape
        out: list[float] = []
        end = k0 + n
        for m, (from_step, u, c) in enumerate(schedule):
            until = schedule[m + 1][0] if m + 1 < len(schedule) else end
            lo, hi = max(from_step, k0) - k0, min(until, end) - k0
            if lo >= hi:
                continue
            rows = [a - start for a in at[lo:hi]]
            if p.friction:
                out += [(u * sin[i] + shape[i] * c) / kt for i in rows]
            else:
                out += [u * sin[i] / kt for i in rows]
        return np.array(out, dtype=float)

    def _currents(self, k: NDArray[np.int64]) -> FloatArray:
        """:meth:`currents` computed from the block's own samples (eqs. (13)-(15))."""
        p = self.params
        phase = k % p.ratio
        at = np.where(phase == 0, k, k - phase + p.ratio)
        pos, vel, _ = self._samples.steps(at)
        theta = pos / p.lead_m_per_rad
        omega = vel / p.lead_m_per_rad
        u, c = self.parameters_at(k)
        torque = u * np.sin(theta)
        if p.friction:
            torque = (
                torque
                + friction_model_Nm(
                    omega, coulomb_Nm=1.0, alpha=p.alpha, omega_th_rad_s=p.omega_th_rad_s
                )
                * c
            )
        return np.asarray(torque / p.torque_constant_Nm_per_A, dtype=float)
