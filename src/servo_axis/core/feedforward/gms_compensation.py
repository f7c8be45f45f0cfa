"""GMS friction compensation: the conventional feedforward of paper 004 (Sect. II-A, Fig. 6).

Paper 004 compensates the rolling friction of its ball screw with the GMS
model (Al-Bender et al. 2005) fitted to a slow reversal (its Fig. 4(b))
before proposing its sigmoid law. As a feedforward term (:mod:`.terms`)
the model runs on the original reference, position and velocity at the
table, and its torque, the torque that overcomes friction (``+F_c`` in
steady sliding at ``v > 0``: it pushes in the direction of motion), is
divided by ``K_T``. The model keeps its element forces from one block to
the next: a term sees every control sample once, in order.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from servo_axis.core.errors import SignalError, require_positive
from servo_axis.core.feedforward.terms import ReferenceBlock
from servo_axis.core.friction.gms_model import GmsModel
from servo_axis.core.friction.gms_params import GmsParams

FloatArray = NDArray[np.float64]


class GmsTerm:
    """Friction compensation current from the GMS model on the reference.

    ``i_ff[k] = F_GMS(y_d[k], v_d[k]) / K_T``, with the model stepped by the
    time between consecutive control samples (``(k - k_prev) T_u``).

    Parameters
    ----------
    params : GmsParams
        The fitted model (torque at the motor per m of table travel).
    torque_constant_Nm_per_A : float
        Nominal ``K_T``, N m/A, > 0.
    control_period_s : float
        ``T_u``, s, > 0.

    Raises
    ------
    ConfigError
        For ``K_T`` or ``T_u`` not > 0.
    """

    def __init__(
        self, params: GmsParams, *, torque_constant_Nm_per_A: float, control_period_s: float
    ) -> None:
        self._kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
        self._period = require_positive("control_period_s", control_period_s)
        # The model stepped a block at a time, compiled (the same numbers).
        self._model = GmsModel(params, compiled=True)
        self._last_step: int | None = None

    @property
    def params(self) -> GmsParams:
        """The model's parameters."""
        return self._model.params

    def reset(self) -> None:
        """Start again from the virgin state; the next sample only sets the position."""
        self._model.reset()
        self._last_step = None

    def currents(self, block: ReferenceBlock) -> FloatArray:
        """Compensation current (A) at each sample of ``block``.

        Raises
        ------
        SignalError
            When the block's arrays differ in length or a step does not
            follow the previous one (``block.step`` named).
        """
        steps = np.asarray(block.step).tolist()
        pos = np.asarray(block.position_m, dtype=float).tolist()
        vel = np.asarray(block.velocity_m_s, dtype=float).tolist()
        if not len(steps) == len(pos) == len(vel):
            raise SignalError(
                f"block: expected step, position_m and velocity_m_s of one length, got "
                f"{len(steps)}, {len(pos)} and {len(vel)}"
            )
        kt, period = self._kt, self._period
        last = self._last_step
        periods: list[float] = []
        for k in steps:
            gap = 1 if last is None else k - last
            if gap <= 0:
                # The samples before it first, as one by one (the model moved through them).
                self._model.update_many(pos[: len(periods)], vel[: len(periods)], periods)
                raise SignalError(
                    f"block.step: expected steps after {last}, got {k} (each sample once, in order)"
                )
            periods.append(gap * period)
            last = int(k)
        torques = self._model.update_many(pos, vel, periods)
        self._last_step = last
        return np.array([t / kt for t in torques], dtype=float)
