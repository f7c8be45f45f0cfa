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

from .errors import ConfigError, SignalError, require_positive
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
        learning_cycle_steps: int | None = None,
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
        if learning_cycle_steps is not None:
            if self._ptc is None:
                raise ConfigError(
                    "learning_cycle_steps: repetitive learning needs PTC (ptc_enabled)"
                )
            if learning_cycle_steps < 8 or learning_cycle_steps % 2:
                raise ConfigError(
                    f"learning_cycle_steps: expected an even number >= 8, got {learning_cycle_steps!r}"
                )
        self._cycle_steps = learning_cycle_steps
        self._corrections: dict[int, np.ndarray] = {}
        self._next = 0
        self._block_start = 0
        self._block: np.ndarray = np.zeros((0, 3))

    def set_correction(
        self, cycle: int, position_rad: np.ndarray, velocity_rad_s: np.ndarray
    ) -> None:
        """Correction of the target for learning cycle ``cycle`` (>= 1), per reference instant.

        Added to ``x_d`` before PTC, so it shifts both the feedforward and the
        feedback reference (000 Fig. 5, 9). Cycle ``j`` starts at control
        sample ``j * learning_cycle_steps``.
        """
        if self._cycle_steps is None:
            raise ConfigError("cycle: this generator was built without learning_cycle_steps")
        nd = self._cycle_steps // 2
        pos = np.asarray(position_rad, dtype=float)
        vel = np.asarray(velocity_rad_s, dtype=float)
        if cycle < 1 or pos.shape != (nd,) or vel.shape != (nd,):
            raise SignalError(
                f"correction: expected cycle >= 1 and {nd} samples, got {cycle}, {pos.shape}, {vel.shape}"
            )
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            raise SignalError("correction: expected finite values")
        self._corrections[cycle] = np.column_stack((pos, vel))
        for old in [c for c in self._corrections if c < cycle - 2]:
            del self._corrections[old]

    def repeat_correction(self, cycle: int) -> None:
        """Use the correction of cycle ``cycle - 1`` (zero for cycle 1) for ``cycle`` as well."""
        if self._cycle_steps is None:
            raise ConfigError("cycle: this generator was built without learning_cycle_steps")
        nd = self._cycle_steps // 2
        previous = self._corrections.get(cycle - 1, np.zeros((nd, 2)))
        self.set_correction(cycle, previous[:, 0], previous[:, 1])

    def ready_until(self) -> int | None:
        """First control sample that waits for a learning correction not yet set (None: none waits).

        The two samples of the last reference interval of cycle ``j-1`` need
        ``x_d`` at the first instant of cycle ``j``, so they wait for ``c_j``.
        """
        if self._cycle_steps is None:
            return None
        cycle = max(1, self._next // self._cycle_steps)
        while cycle in self._corrections:
            cycle += 1
        return cycle * self._cycle_steps - 2

    def _block_end(self, k0: int) -> int:
        end = k0 - (k0 % BLOCK_STEPS) + BLOCK_STEPS
        if self._cycle_steps is not None:
            # Blocks are cut where a new correction is first needed, the same
            # way every run (the numbers must not depend on request sizes).
            cs = self._cycle_steps
            for cut in ((k0 // cs + 1) * cs - 2, (k0 // cs + 1) * cs):
                if k0 < cut < end:
                    end = cut
        return end

    def _targets(self, ti: np.ndarray, first_instant: int) -> np.ndarray:
        p_r, v_r, _ = self._reference.sample(ti)
        x_d = np.column_stack((p_r, v_r)) / self._lead
        if self._cycle_steps is not None:
            nd = self._cycle_steps // 2
            for row in range(len(x_d)):
                cycle, idx = divmod(first_instant + row, nd)
                if cycle >= 1:
                    x_d[row] += self._corrections[cycle][idx]
        return x_d

    def _compute_block(self, k0: int, k1: int) -> np.ndarray:
        n = k1 - k0
        k = np.arange(k0, k1)
        t = k * self._tu
        pos_m, vel_m, _ = self._reference.sample(t)
        out = np.empty((n, 3))
        if self._ptc is not None:
            ti = np.arange(k0, k1 + 1, 2) * self._tu
            x_d = self._targets(ti, k0 // 2)
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
        limit = self.ready_until()
        if limit is not None and stop > limit:
            raise ConfigError(
                f"stop: samples from {limit} on wait for a learning correction, asked up to {stop}"
            )
        k = start
        while k < stop:
            if not self._block_start <= k < self._block_start + len(self._block):
                self._block_start = k if self._cycle_steps is not None else k - (k % BLOCK_STEPS)
                self._block = self._compute_block(
                    self._block_start, self._block_end(self._block_start)
                )
            row = self._block[k - self._block_start]
            result.append((float(row[0]), float(row[1]), float(row[2])))
            k += 1
        self._next = stop
        return result
