"""The Generalized Maxwell-Slip friction model (GMS), stepped one sample at a time.

N elementary state models in parallel share the displacement; element ``i``
carries ``F_i`` (Al-Bender et al. 2005, parameters and units in
:mod:`~servo_axis.core.friction.gms_params`):

* sticking: ``dF_i/dt = k_i v`` (an elastic asperity junction);
* slipping: ``dF_i/dt = C (sgn(v) alpha_i s(v) - F_i)``, an exponential
  approach to ``sgn(v) alpha_i s(v)``;
* an element slips once ``|F_i|`` reaches ``alpha_i s(v)`` and sticks again
  when the velocity changes sign or is 0;

and the friction is ``F = sum_i F_i + sigma_2 v`` with the Stribeck curve
``s(v) = F_c + (F_s - F_c) exp(-|v / V_s|^delta)`` (``sum_i alpha_i = 1``).

The slip rule: Al-Bender et al. 2005 write it
``dF_i/dt = sgn(v) C' (1 - F_i / (alpha_i s(v)))`` with ``C'`` in force per
second; taken literally it has no stable fixed point for ``v < 0``, so the
intended approach to ``sgn(v) alpha_i s(v)`` is written here with the rate
normalised by the element's level: ``C = C' / (alpha_i s(v))`` in 1/s, the
same time constant ``1/C`` for every element.

Nothing here reads a file, a clock or a logger.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NoReturn

import numpy as np
from numpy.typing import ArrayLike

from servo_axis.core.errors import SignalError
from servo_axis.core.friction.gms_params import FloatArray, GmsParams


class GmsModel:
    """The GMS model (Al-Bender et al. 2005) stepped one sample at a time.

    Each element keeps its force ``F_i`` (N m) and whether it slips. Per
    sample (:meth:`update`), for the position increment ``dx`` since the
    previous sample and the velocity ``v`` of this one:

    * when ``v`` changes sign or is 0, every element sticks;
    * a sticking element takes ``F_i + k_i dx``; once ``|F_i|`` reaches
      ``alpha_i s(v)`` it is held there and slips from then on (the level is
      the slip rule's fixed point, so this is exact for constant ``v``);
    * a slipping element follows the slip rule integrated exactly over the
      sample for constant ``v``:
      ``F_i <- L + (F_i - L) exp(-C T)``, ``L = sgn(v) alpha_i s(v)``.

    The torque is ``sum_i F_i + sigma_2 v``. Plain float arithmetic on at
    most 20 elements: deterministic and cheap.

    Parameters
    ----------
    params : GmsParams
        The model.
    compiled : bool
        Step :meth:`update_many` with the compiled
        :func:`~servo_axis.core.friction.gms_kernels.gms_block` (the same numbers; it
        loads numba when the model is built), else with :meth:`update`.
    """

    def __init__(self, params: GmsParams, *, compiled: bool = False) -> None:
        self.params = params
        self._k = list(params.stiffness_Nm_per_m)
        self._alpha = list(params.weights)
        self._fc = params.coulomb_Nm
        self._fs = params.coulomb_Nm if params.static_Nm is None else params.static_Nm
        self._vs = params.stribeck_velocity_m_s
        self._delta = params.stribeck_exponent
        self._c = params.attraction_per_s
        self._sigma2 = params.viscous_Nms_per_m
        n = len(self._k)
        self._force = [0.0] * n
        self._slipping = [False] * n
        self._last: float | None = None
        self._sign = 0
        # Per sample the same few values recur: the decay of the slip rule for the
        # period (one period in a run), and the elements' levels alpha_i s(v) for the
        # Stribeck level (F_c without a Stribeck effect). Each is kept with what it
        # was computed from, and computed again (the same floats) when that changes.
        self._decay_period = 0.0
        self._decay = 1.0
        self._levels_of: float | None = None
        self._pairs = [(k, 0.0) for k in self._k]  # (k_i, alpha_i s) once computed
        self._stribeck = self._fs != self._fc
        self._sticking = (False,) * n
        self._block: Callable[..., None] | None = None
        if compiled:
            from servo_axis.core.friction.gms_kernels import gms_block

            self._block = gms_block

    def reset(self) -> None:
        """Relax every element (virgin state); the next :meth:`update` sets the position."""
        n = len(self._k)
        self._force[:] = [0.0] * n
        self._slipping[:] = [False] * n
        self._last = None
        self._sign = 0

    @property
    def forces_Nm(self) -> tuple[float, ...]:
        """The element forces ``F_i``, N m."""
        return tuple(self._force)

    @property
    def slipping(self) -> tuple[bool, ...]:
        """Whether each element slips."""
        return tuple(self._slipping)

    def update(self, position_m: float, velocity_m_s: float, period_s: float) -> float:
        """Advance one sample and return the friction torque, N m.

        Parameters
        ----------
        position_m : float
            Table position at this sample, m. The first call after
            construction or :meth:`reset` only sets it (no increment).
        velocity_m_s : float
            Table velocity at this sample, m/s (its sign decides the
            direction of slip and the re-sticking; its size the Stribeck
            level and the viscous term).
        period_s : float
            Time since the previous sample, s, > 0 (the slip rule's step).

        Raises
        ------
        SignalError
            For a non-finite argument or ``period_s <= 0``, naming it.
        """
        isfinite = math.isfinite
        if not (
            isfinite(position_m) and isfinite(velocity_m_s) and isfinite(period_s) and period_s > 0
        ):
            self._refuse(position_m, velocity_m_s, period_s)
        v = velocity_m_s
        sign = 1 if v > 0.0 else (-1 if v < 0.0 else 0)
        force = self._force
        slipping = self._slipping
        if sign != self._sign or sign == 0:
            slipping[:] = self._sticking
        self._sign = sign
        last = self._last
        self._last = position_m
        if last is None:
            return math.fsum(force) + self._sigma2 * v
        dx = position_m - last
        s = self._fc
        if self._stribeck:
            s += (self._fs - self._fc) * math.exp(-(abs(v / self._vs) ** self._delta))
        if period_s != self._decay_period:
            self._decay = math.exp(-self._c * period_s)
            self._decay_period = period_s
        decay = self._decay
        if s != self._levels_of:
            self._pairs = [(k, a * s) for k, a in zip(self._k, self._alpha, strict=True)]
            self._levels_of = s
        # The elements' loop stays inline: a method call per sample costs 5 % of it.
        i = 0
        for k, level in self._pairs:
            if slipping[i]:
                target = sign * level
                force[i] = target + (force[i] - target) * decay
            else:
                f = force[i] + k * dx
                # Break-away: held at the level, and slipping only in the direction of motion
                # (a position step against the velocity's sign, which consistent inputs never
                # give, must not start a slip towards the other level).
                if f >= level:
                    f = level
                    slipping[i] = sign > 0
                elif f <= -level:
                    f = -level
                    slipping[i] = sign < 0
                force[i] = f
            i += 1
        return math.fsum(force) + self._sigma2 * v

    def update_many(
        self, positions_m: list[float], velocities_m_s: list[float], periods_s: list[float]
    ) -> list[float]:
        """:meth:`update` of each sample in turn: the torques, N m (the same numbers).

        Compiled (``compiled=True``) when every argument is finite and every
        period > 0; else sample by sample, which raises at the first bad one.
        """
        block = self._block
        pos = np.array(positions_m, dtype=float)
        vel = np.array(velocities_m_s, dtype=float)
        per = np.array(periods_s, dtype=float)
        if (
            block is None
            or not (len(pos) == len(vel) == len(per))
            or not (np.isfinite(pos).all() and np.isfinite(vel).all() and np.isfinite(per).all())
            or not (per > 0.0).all()
        ):
            return [
                self.update(p, v, t)
                for p, v, t in zip(positions_m, velocities_m_s, periods_s, strict=True)
            ]
        force = np.array(self._force, dtype=float)
        slipping = np.array(self._slipping, dtype=bool)
        state = np.array(
            [
                0.0 if self._last is None else 1.0,
                0.0 if self._last is None else self._last,
                self._sign,
                self._fc,
                self._fs,
                self._vs,
                self._delta,
                self._c,
                self._sigma2,
                1.0 if self._stribeck else 0.0,
            ]
        )
        out = np.empty(len(pos))
        block(
            np.array(self._k, dtype=float),
            np.array(self._alpha, dtype=float),
            force,
            slipping,
            state,
            pos,
            vel,
            per,
            out,
            np.empty(len(force) + 1),
        )
        self._force[:] = force.tolist()
        self._slipping[:] = slipping.tolist()
        if state[0] != 0.0:
            self._last = float(state[1])
        self._sign = int(state[2])
        torques: list[float] = out.tolist()
        return torques

    @staticmethod
    def _refuse(position_m: float, velocity_m_s: float, period_s: float) -> NoReturn:
        """Raise the SignalError of :meth:`update` for the first argument at fault."""
        if not math.isfinite(position_m):
            raise SignalError(f"position_m: expected a finite number, got {position_m!r}")
        if not math.isfinite(velocity_m_s):
            raise SignalError(f"velocity_m_s: expected a finite number, got {velocity_m_s!r}")
        raise SignalError(f"period_s: expected a finite value > 0, got {period_s!r}")


def simulate_gms(
    params: GmsParams, position_m: ArrayLike, velocity_m_s: ArrayLike, *, period_s: float
) -> FloatArray:
    """GMS torque (N m) along a sampled path, from the virgin state.

    Parameters
    ----------
    params : GmsParams
        The model.
    position_m, velocity_m_s : array, shape (n,)
        Table position (m) and velocity (m/s) at each sample.
    period_s : float
        Sample period, s, > 0.
    """
    pos = np.asarray(position_m, dtype=float)
    vel = np.asarray(velocity_m_s, dtype=float)
    if pos.ndim != 1 or pos.shape != vel.shape:
        raise SignalError(
            f"position_m, velocity_m_s: expected 1-D arrays of one length, "
            f"got shapes {pos.shape} and {vel.shape}"
        )
    model = GmsModel(params)
    update = model.update
    return np.array(
        [update(p, v, period_s) for p, v in zip(pos.tolist(), vel.tolist(), strict=True)],
        dtype=float,
    )
