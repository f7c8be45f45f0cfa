"""Feedforward generator: reference trajectory + multirate PTC + a sum of terms.

Per control sample ``k`` it gives the feedback reference ``r[k]`` (motor
angle, rad), its velocity and the feedforward current ``u_ff[k]`` (A):

* with PTC (paper 000 Sect. III-A, Fig. 5): the target state
  ``x_d[i] = [x(i T_r), v(i T_r)] / R`` at the reference instants (plus a
  learned target-side correction), the multirate feedforward
  ``[u[2i], u[2i+1]] = B^-1 (x_d[i+1] - A x_d[i])`` and the nominal output
  trajectory at every ``T_u`` as ``r``;
* without PTC: ``r[k] = x(k T_u) / R`` and no model-based current;
* then every feedforward term (:mod:`.terms`: the friction table of paper
  000 Fig. 17, later compensators) adds its current, in order, and a learned
  input-side correction (ILC, paper 001 eq. (3)) adds its own.

Samples must be asked for in order (terms may track reversals); they are
computed in blocks, cut the same way every run, so the numbers never depend
on how many samples a caller asks for at once.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from servo_axis.core.errors import ConfigError, SignalError, require_positive
from servo_axis.core.feedforward.ptc import MultiratePtc
from servo_axis.core.feedforward.terms import FeedforwardTerm, ReferenceBlock
from servo_axis.core.models.base import NominalModel
from servo_axis.core.reference import GridSamples, Reference
from servo_axis.core.timing import SampleGrid

#: Control samples computed at a time (a multiple of the PTC ratio).
BLOCK_STEPS = 256


SIDES = ("target", "input")


class FeedforwardGenerator:
    """Streams ``(r, r', u_ff)`` per control sample.

    Parameters
    ----------
    reference : Reference
        Table-side trajectory (m, m/s, m/s^2).
    grid : SampleGrid
        ``T_u`` and ``T_r = ratio T_u``.
    lead_m_per_rad : float
        ``R``, m/rad, > 0.
    nominal : NominalModel
        ``P_n`` of eq. (1) for the PTC (replaceable later through :attr:`ptc`).
    ptc_enabled : bool
        Multirate PTC on (True) or reference only (False).
    terms : sequence of FeedforwardTerm
        Currents added to ``u_ff``, in this order.
    learning_period_steps : int or None
        Control samples per learning period (cycle or trial), or None when
        nothing is learned; corrections of period ``j >= 1`` apply from
        sample ``j * learning_period_steps``.
    learning_side : str
        ``"target"`` (added to ``x_d`` before PTC, per reference instant) or
        ``"input"`` (added to ``u_ff``, per control sample).
    estimate_period_steps : int or None
        Control samples per online estimate (``T_RLS / T_u``, paper 003), a
        whole number of reference periods; None: no online estimates.
    estimate_latency_steps : int
        Samples between the last sample an estimate is computed from and the
        first it applies to, minus one: estimate ``n`` applies from
        ``(n + 1) R + latency``; at least one estimate period, so that the
        preview never runs ahead of the estimates it depends on.
    """

    def __init__(
        self,
        *,
        reference: Reference,
        grid: SampleGrid,
        lead_m_per_rad: float,
        nominal: NominalModel,
        ptc_enabled: bool = True,
        terms: Sequence[FeedforwardTerm] = (),
        learning_period_steps: int | None = None,
        learning_side: str = "target",
        estimate_period_steps: int | None = None,
        estimate_latency_steps: int = 0,
    ) -> None:
        self._reference = reference
        self._grid = grid
        self._tu = grid.control_period_s
        self._lead = require_positive("lead_m_per_rad", lead_m_per_rad)
        self._kt = nominal.torque_constant_Nm_per_A
        self.ptc = (
            MultiratePtc(
                **nominal.as_kwargs(),
                control_period_s=self._tu,
                ratio=grid.ratio,
                # A short block per online estimate: the compiled PTC (the same numbers).
                compiled=estimate_period_steps is not None,
            )
            if ptc_enabled
            else None
        )
        self._terms = list(terms)
        if learning_side not in SIDES:
            raise ConfigError(f"learning_side: expected one of {SIDES}, got {learning_side!r}")
        ratio = grid.ratio
        if learning_period_steps is not None:
            if learning_side == "target" and self.ptc is None:
                raise ConfigError(
                    "learning_period_steps: target-side learning needs PTC (ptc_enabled)"
                )
            if learning_period_steps < 4 * ratio or learning_period_steps % ratio:
                raise ConfigError(
                    f"learning_period_steps: expected a multiple of {ratio} >= {4 * ratio}, "
                    f"got {learning_period_steps!r}"
                )
        self._cycle_steps = learning_period_steps
        self._side = learning_side
        # Online estimates (paper 003): the n-th (n = 0, 1, ...) is computed
        # from the samples up to (n + 1) R - 1 and applies from
        # (n + 1) R + latency; nothing from there on is given before it is set.
        self._estimate_period = estimate_period_steps
        self._next_estimate: int | None = None
        if estimate_period_steps is not None:
            for name, value in (
                ("estimate_period_steps", estimate_period_steps),
                ("estimate_latency_steps", estimate_latency_steps),
            ):
                if isinstance(value, bool) or not isinstance(value, int) or value % ratio:
                    raise ConfigError(
                        f"{name}: expected a whole number of reference periods ({ratio} "
                        f"control samples), got {value!r}"
                    )
            if estimate_period_steps < ratio or estimate_latency_steps < estimate_period_steps:
                raise ConfigError(
                    "estimate_latency_steps: expected at least one estimate period "
                    f"({estimate_period_steps} samples), got {estimate_latency_steps!r}"
                )
            self._next_estimate = estimate_period_steps + estimate_latency_steps
        self._estimates_wait = True
        self._last_estimate_from = -1  # first sample of the last estimate set
        # With online estimates a block ends at the next estimate (a few
        # samples): the reference is then taken from samples computed a
        # chunk at a time (the same numbers, GridSamples).
        self._grid_samples = (
            GridSamples(reference, self._tu) if estimate_period_steps is not None else None
        )
        self._corrections: dict[int, np.ndarray] = {}
        self._next = 0
        self._block_start = 0
        self._block: np.ndarray = np.zeros((0, 3))
        self._rows: list[tuple[float, float, float]] = []  # the block as floats

    @property
    def learning_side(self) -> str:
        """``"target"`` or ``"input"``."""
        return self._side

    def _correction_shape(self) -> tuple[int, int]:
        if self._cycle_steps is None:
            raise ConfigError("cycle: this generator was built without learning_period_steps")
        if self._side == "target":
            return self._cycle_steps // self._grid.ratio, 2
        return self._cycle_steps, 1

    def set_correction(self, cycle: int, *values: np.ndarray) -> None:
        """The learned correction for learning period ``cycle`` (>= 1).

        Target side: ``(position_rad, velocity_rad_s)`` per reference instant
        of the period, added to ``x_d`` before PTC, so it shifts both the
        feedforward and the feedback reference (000 Fig. 5, 9). Input side:
        ``(current_A,)`` per control sample, added to ``u_ff``.
        """
        n, columns = self._correction_shape()
        arrays = [np.asarray(v, dtype=float) for v in values]
        shapes = [a.shape for a in arrays]
        if cycle < 1 or len(arrays) != columns or any(shape != (n,) for shape in shapes):
            raise SignalError(
                f"correction: expected cycle >= 1 and {columns} x {n} samples, got {cycle}, {shapes}"
            )
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise SignalError("correction: expected finite values")
        self._corrections[cycle] = np.column_stack(arrays)
        for old in [c for c in self._corrections if c < cycle - 2]:
            del self._corrections[old]

    def replace_correction(self, cycle: int, *values: np.ndarray) -> int:
        """Realtime: the correction of period ``cycle``, which may be under way already.

        It applies from the next sample not yet given (the ones given used
        what was set before, :meth:`repeat_correction` at the boundary): a
        realtime learning unit's correction cannot be in before the boundary
        it is learned at, so it takes effect a little into its period. The
        law's fixed point is unchanged (there ``c_{j+1} = c_j``).

        Returns
        -------
        int
            The first control sample that uses it.
        """
        self.set_correction(cycle, *values)
        self._block_start, self._block = 0, np.zeros((0, 3))  # recompute from here
        self._rows = []
        return self._next

    def boundary_lead(self) -> int:
        """Control samples before a period's start that first need its correction.

        A target-side correction is needed one reference interval early (``x_d``
        one instant ahead), an input-side one at the period's first sample.
        """
        return self._grid.ratio if self._side == "target" and self._cycle_steps else 0

    def repeat_correction(self, cycle: int) -> None:
        """Use the correction of period ``cycle - 1`` (zero for period 1) for ``cycle`` as well."""
        n, columns = self._correction_shape()
        previous = self._corrections.get(cycle - 1, np.zeros((n, columns)))
        self.set_correction(cycle, *(previous[:, c] for c in range(columns)))

    @property
    def next_estimate_step(self) -> int | None:
        """The sample from which the next online estimate applies (None: no estimates)."""
        return self._next_estimate

    def set_estimate(
        self,
        from_step: int,
        *,
        inertia_kgm2: float,
        damping_Nms_per_rad: float,
        unbalance_Nm: float,
        coulomb_Nm: float,
    ) -> int:
        """The online estimate that applies from ``from_step`` (003 Fig. 3, eq. (11)-(15)).

        The PTC's model is rebuilt from ``J``, ``D`` (eq. (11)) and every
        adaptive term (one with ``set_parameters``: the MNC) gets ``U``, ``C``,
        from ``from_step`` on. Estimates come in order, one per estimate
        period: ``from_step`` must be :attr:`next_estimate_step`.

        After :meth:`stop_waiting_for_estimates`, an estimate that comes
        once samples from ``from_step`` on were given (late) applies from
        the first reference instant whose samples were not given, and at
        least one reference interval after the last estimate's start.

        Returns
        -------
        int
            The first control sample that uses it: ``from_step``, or later
            for a late estimate.

        Raises
        ------
        ConfigError
            Without estimates, or ``from_step`` not the next one expected,
            or a value the model refuses.
        """
        if self._next_estimate is None or self._estimate_period is None:
            raise ConfigError("from_step: this generator takes no online estimates")
        if from_step != self._next_estimate:
            raise ConfigError(
                f"from_step: expected the next estimate's step {self._next_estimate}, "
                f"got {from_step!r}"
            )
        ratio = self._grid.ratio
        first = from_step
        if not self._estimates_wait:
            not_given = -(-self._next // ratio) * ratio
            first = max(from_step, not_given, self._last_estimate_from + ratio)
            # The samples in hand from ``first`` on used the model in force
            # (a block ends on a reference instant, and so does ``first``).
            keep = max(0, first - self._block_start)
            self._block, self._rows = self._block[:keep], self._rows[:keep]
        if self.ptc is not None:
            self.ptc.replace_model(
                from_instant=first // ratio,
                inertia_kgm2=inertia_kgm2,
                damping_Nms_per_rad=damping_Nms_per_rad,
                torque_constant_Nm_per_A=self._kt,
            )
            self.ptc.forget_before(self._next // ratio)
        for term in self._terms:
            setter = getattr(term, "set_parameters", None)
            if setter is not None:
                setter(from_step=first, unbalance_Nm=unbalance_Nm, coulomb_Nm=coulomb_Nm)
                forget = getattr(term, "forget_before", None)
                if forget is not None:
                    forget(self._next)
        self._next_estimate = from_step + self._estimate_period
        self._last_estimate_from = first
        return first

    def stop_waiting_for_estimates(self) -> None:
        """No sample waits for an online estimate any more; a late one applies late.

        What a realtime feedforward does: the plant's clock does not wait
        for the identifier, so the model in force goes on past an
        estimate's ``from_step`` until the estimate is in, and applies
        from the first reference instant not yet given then
        (:meth:`set_estimate`). Estimates are still taken in order.
        """
        self._estimates_wait = False

    def stop_estimates(self) -> None:
        """Keep the model and the terms' ``U``, ``C`` in force for the rest of the run.

        No sample waits for an online estimate any more and none is taken
        (:meth:`set_estimate` raises): what a feedforward does once its
        identifier is gone (a fallback, not the deterministic protocol).
        """
        self._next_estimate = None

    def ready_until(self) -> int | None:
        """First control sample that waits for a learning correction not yet set (None: none waits).

        Target side: the samples of the last reference interval of period
        ``j-1`` need ``x_d`` at the first instant of period ``j``, so they
        wait for ``c_j``. Input side: period ``j`` starts with its own.
        """
        limits = (
            [] if self._next_estimate is None or not self._estimates_wait else [self._next_estimate]
        )
        if self._cycle_steps is not None:
            cycle = max(1, self._next // self._cycle_steps)
            while cycle in self._corrections:
                cycle += 1
            lead = self._grid.ratio if self._side == "target" else 0
            limits.append(cycle * self._cycle_steps - lead)
        return min(limits) if limits else None

    def repeat_past_run(self, steps: int) -> None:
        """Set the correction of the period after a run of ``steps`` samples (the last one again).

        A target-side law's last reference interval of the run looks one
        instant into the period after it, whose correction no learning unit
        will make (nothing after the run would use it): the last correction
        is repeated at once, what a learning timeout would do without the
        wait. Nothing happens unless the next sample that waits is one of
        those last ones.
        """
        ready = self.ready_until()
        lead = self.boundary_lead()
        if ready is not None and self._cycle_steps and ready < steps <= ready + lead:
            self.repeat_correction((ready + lead) // self._cycle_steps)

    def _block_end(self, k0: int) -> int:
        end = k0 - (k0 % BLOCK_STEPS) + BLOCK_STEPS
        if self._cycle_steps is not None:
            # Blocks are cut where a new correction is first needed, the same
            # way every run (the numbers must not depend on request sizes).
            cs = self._cycle_steps
            boundary = (k0 // cs + 1) * cs
            for cut in (boundary - self._grid.ratio, boundary):
                if k0 < cut < end:
                    end = cut
        if self._next_estimate is not None and k0 < self._next_estimate < end:
            end = self._next_estimate  # the next model starts there
        return end

    def _targets(self, k0: int, k1: int, first_instant: int) -> np.ndarray:
        """``x_d`` at the reference instants of control samples ``k0 .. k1`` (both included)."""
        ratio = self._grid.ratio
        if self._grid_samples is not None:
            p_r, v_r, _ = self._grid_samples.range(k0, k1 + 1, ratio)
            # np.column_stack((p_r, v_r)) / R for two 1-d arrays of one length
            # (what range gives), without its generality: the same division.
            x_d = np.empty((len(p_r), 2))
            x_d[:, 0] = p_r
            x_d[:, 1] = v_r
            x_d /= self._lead
        else:
            p_r, v_r, _ = self._reference.sample(np.arange(k0, k1 + 1, ratio) * self._tu)
            x_d = np.column_stack((p_r, v_r)) / self._lead
        if self._cycle_steps is not None and self._side == "target":
            nd = self._cycle_steps // self._grid.ratio
            for row in range(len(x_d)):
                cycle, idx = divmod(first_instant + row, nd)
                if cycle >= 1:
                    x_d[row] += self._corrections[cycle][idx]
        return x_d

    def _compute_block(self, k0: int, k1: int) -> np.ndarray:
        n = k1 - k0
        k = np.arange(k0, k1)
        if self._grid_samples is not None:
            pos_m, vel_m, acc_m = self._grid_samples.range(k0, k1)
        else:
            pos_m, vel_m, acc_m = self._reference.sample(k * self._tu)
        out = np.empty((n, 3))
        if self.ptc is not None:
            first = self._grid.instant_of(k0)
            x_d = self._targets(k0, k1, first)
            ptc = self.ptc.feedforward(x_d, first)
            out[:, 0] = ptc.position_rad
            out[:, 1] = ptc.velocity_rad_s
            out[:, 2] = ptc.current_A
        else:
            out[:, 0] = pos_m / self._lead
            out[:, 1] = vel_m / self._lead
            out[:, 2] = 0.0
        block = ReferenceBlock(
            step=k, position_m=pos_m, velocity_m_s=vel_m, acceleration_m_s2=acc_m
        )
        for term in self._terms:
            out[:, 2] += term.currents(block)
        if self._cycle_steps is not None and self._side == "input":
            cs = self._cycle_steps
            for row, step in enumerate(range(k0, k1)):
                cycle, idx = divmod(step, cs)
                if cycle >= 1:
                    out[row, 2] += self._corrections[cycle][idx, 0]
        return out

    def samples(self, start: int, stop: int) -> list[tuple[float, float, float]]:
        """``(r_rad, r_rad_s, u_ff_A)`` for control samples ``start .. stop-1``.

        Raises
        ------
        ConfigError
            If ``start`` is not the next sample not yet given, or a sample
            from ``stop`` on waits for a learning correction not yet set.
        """
        if start != self._next:
            raise ConfigError(f"start: expected the next sample {self._next}, got {start}")
        # One sample of the block in hand, nothing learned (the per-sample
        # path of a loop with online estimates): what the loop below gives.
        index = start - self._block_start
        if (
            stop == start + 1
            and self._cycle_steps is None
            and 0 <= index < len(self._rows)
            and (
                self._next_estimate is None
                or not self._estimates_wait
                or stop <= self._next_estimate
            )
        ):
            self._next = stop
            return [self._rows[index]]
        result: list[tuple[float, float, float]] = []
        limit = self.ready_until()
        if limit is not None and stop > limit:
            raise ConfigError(
                f"stop: samples from {limit} on wait for a learning correction, asked up to {stop}"
            )
        k = start
        while k < stop:
            if not self._block_start <= k < self._block_start + len(self._block):
                # With learning or online estimates a block starts at the next
                # sample: the terms forget what no sample from it on uses
                # (set_estimate), also after the estimates stopped (a fallback).
                cut = self._cycle_steps is not None or self._estimate_period is not None
                self._block_start = k if cut else k - (k % BLOCK_STEPS)
                self._block = self._compute_block(
                    self._block_start, self._block_end(self._block_start)
                )
                self._rows = [(r0, r1, r2) for r0, r1, r2 in self._block.tolist()]
            # The rows of this block up to stop, as one slice.
            first = self._block_start
            end = min(stop, first + len(self._block))
            result += self._rows[k - first : end - first]
            k = end
        self._next = stop
        return result
