"""Feedforward generator: reference trajectory, multirate PTC and friction table.

Per control sample ``k`` it gives the feedback reference ``r[k]`` (motor
angle, rad), its velocity and the feedforward current ``u_ff[k]`` (A):

* with PTC (paper 000 Sect. III-A, Fig. 5): the target state
  ``x_d[i] = [x(i T_r), v(i T_r)] / R`` at the reference instants, the
  multirate feedforward ``[u[2i], u[2i+1]] = B^-1 (x_d[i+1] - A x_d[i])`` and
  the nominal output trajectory at every ``T_u`` as ``r``;
* without PTC: ``r[k] = x(k T_u) / R`` and no model-based current;
* with a friction table (paper 000 Fig. 17): ``+ f(|y_d[k] - y_rev|) / K_T``
  with the sign of the reference's direction, added to ``u_ff``.

Samples must be asked for in order (the friction table tracks reversals);
they are computed in blocks of whole reference periods.
"""

from __future__ import annotations

import numpy as np

from .errors import ConfigError, require_positive
from .friction_table import FrictionFeedforward, FrictionTable
from .ptc import MultiratePtc
from .reference import Reference

#: Control samples computed at a time (a multiple of the PTC ratio 2).
BLOCK_STEPS = 256


class FeedforwardGenerator:
    """Streams ``(r, r', u_ff)`` per control sample.

    Parameters
    ----------
    reference : Reference
        Table-side trajectory (m, m/s, m/s^2).
    control_period_s : float
        ``T_u``, s, > 0; the reference period is ``T_r = 2 T_u``.
    lead_m_per_rad : float
        ``R``, m/rad, > 0.
    inertia_kgm2, damping_Nms_per_rad, torque_constant_Nm_per_A : float
        Nominal model ``P_n`` of eq. (1).
    ptc_enabled : bool
        Multirate PTC on (True) or reference only (False).
    friction_table : FrictionTable or None
        Data-based friction table, or None.
    """

    def __init__(
        self,
        *,
        reference: Reference,
        control_period_s: float,
        lead_m_per_rad: float,
        inertia_kgm2: float,
        damping_Nms_per_rad: float,
        torque_constant_Nm_per_A: float,
        ptc_enabled: bool = True,
        friction_table: FrictionTable | None = None,
    ) -> None:
        self._reference = reference
        self._tu = require_positive("control_period_s", control_period_s)
        self._lead = require_positive("lead_m_per_rad", lead_m_per_rad)
        self._ptc = (
            MultiratePtc(
                inertia_kgm2=inertia_kgm2,
                damping_Nms_per_rad=damping_Nms_per_rad,
                torque_constant_Nm_per_A=torque_constant_Nm_per_A,
                control_period_s=control_period_s,
                ratio=2,
            )
            if ptc_enabled
            else None
        )
        self._friction = (
            FrictionFeedforward(friction_table, torque_constant_Nm_per_A=torque_constant_Nm_per_A)
            if friction_table is not None
            else None
        )
        self._next = 0
        self._block_start = 0
        self._block: np.ndarray = np.zeros((0, 3))

    def _compute_block(self, k0: int) -> np.ndarray:
        k = np.arange(k0, k0 + BLOCK_STEPS)
        t = k * self._tu
        pos_m, vel_m, _ = self._reference.sample(t)
        out = np.empty((BLOCK_STEPS, 3))
        if self._ptc is not None:
            ti = np.arange(k0, k0 + BLOCK_STEPS + 1, 2) * self._tu
            p_r, v_r, _ = self._reference.sample(ti)
            x_d = np.column_stack((p_r, v_r)) / self._lead
            ptc = self._ptc.feedforward(x_d)
            out[:, 0] = ptc.position_rad
            out[:, 1] = ptc.velocity_rad_s
            out[:, 2] = ptc.current_A
        else:
            out[:, 0] = pos_m / self._lead
            out[:, 1] = vel_m / self._lead
            out[:, 2] = 0.0
        if self._friction is not None:
            out[:, 2] += [self._friction.current_A(float(p)) for p in pos_m]
        return out

    def samples(self, start: int, stop: int) -> list[tuple[float, float, float]]:
        """``(r_rad, r_rad_s, u_ff_A)`` for control samples ``start .. stop-1``.

        Raises
        ------
        ConfigError
            If ``start`` is not the next sample not yet given.
        """
        if start != self._next:
            raise ConfigError(f"start: expected the next sample {self._next}, got {start}")
        result: list[tuple[float, float, float]] = []
        k = start
        while k < stop:
            if not self._block_start <= k < self._block_start + len(self._block):
                self._block_start = k - (k % BLOCK_STEPS)
                self._block = self._compute_block(self._block_start)
            row = self._block[k - self._block_start]
            result.append((float(row[0]), float(row[1]), float(row[2])))
            k += 1
        self._next = stop
        return result
