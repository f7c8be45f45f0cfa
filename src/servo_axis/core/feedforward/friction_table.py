"""Data-based friction table (paper 000 Sect. VI-B, Fig. 17; paper 001).

The table holds the motor torque (N m) that friction demands against the
displacement from the last reversal of the reference (m, table side, >= 0),
for motion in the positive direction after a reversal from negative motion:
it runs from about ``-T_c`` at the reversal to ``+T_c`` once the balls roll.
Motion in the negative direction uses the odd mirror, ``-table(d)``. The
feedforward supplies that torque: ``u_f = direction * table(|y_d - y_rev|) / K_T``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import TableError, require_positive

HEADER_LINE = "# servo_axis friction table v1"
COLUMNS_LINE = "displacement_m,torque_Nm"


@dataclass(frozen=True)
class FrictionTable:
    """Friction torque against displacement from the last reversal.

    Parameters
    ----------
    displacement_m : array, shape (n,)
        Strictly increasing, starting at 0, m; n >= 2.
    torque_Nm : array, shape (n,)
        Motor torque needed to overcome friction in the positive direction, N m.
    """

    displacement_m: NDArray[np.float64]
    torque_Nm: NDArray[np.float64]

    def __post_init__(self) -> None:
        d = np.array(self.displacement_m, dtype=float)
        t = np.array(self.torque_Nm, dtype=float)
        if d.ndim != 1 or t.ndim != 1 or d.shape != t.shape or d.size < 2:
            raise TableError(
                f"displacement_m, torque_Nm: expected two 1-D arrays of the same length >= 2, "
                f"got shapes {d.shape} and {t.shape}"
            )
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(t))):
            raise TableError("displacement_m, torque_Nm: expected finite values")
        if d[0] != 0.0 or np.any(np.diff(d) <= 0.0):
            raise TableError("displacement_m: expected strictly increasing values starting at 0")
        d.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(self, "displacement_m", d)
        object.__setattr__(self, "torque_Nm", t)

    def torque_Nm_at(self, displacement_m: ArrayLike, direction: int = 1) -> NDArray[np.float64]:
        """Friction torque (N m) at a displacement from reversal, in a direction (+1/-1).

        Linear interpolation; the last value is held beyond the table.
        """
        d = np.asarray(displacement_m, dtype=float)
        torque: NDArray[np.float64] = float(np.sign(direction)) * np.interp(
            d, self.displacement_m, self.torque_Nm
        )
        return torque

    def to_text(self) -> str:
        """The table as CSV text with a header naming the units."""
        lines = [HEADER_LINE, COLUMNS_LINE]
        lines += [
            f"{d!r},{t!r}"
            for d, t in zip(self.displacement_m.tolist(), self.torque_Nm.tolist(), strict=True)
        ]
        return "\n".join(lines) + "\n"

    @classmethod
    def from_text(cls, text: str, *, source: str = "table") -> FrictionTable:
        """Read the text :meth:`to_text` writes.

        Raises
        ------
        TableError
            Naming ``source`` and the line of a missing header, a non-numeric
            or non-finite value, a non-increasing displacement or too few rows.
        """
        lines = text.splitlines()
        if len(lines) < 2 or lines[0].strip() != HEADER_LINE:
            raise TableError(f"{source}: line 1: expected {HEADER_LINE!r}")
        if lines[1].strip() != COLUMNS_LINE:
            raise TableError(f"{source}: line 2: expected {COLUMNS_LINE!r}")
        disp: list[float] = []
        torque: list[float] = []
        for number, line in enumerate(lines[2:], start=3):
            if not line.strip():
                continue
            parts = line.split(",")
            try:
                if len(parts) != 2:
                    raise ValueError
                d, t = float(parts[0]), float(parts[1])
            except ValueError:
                raise TableError(
                    f"{source}: line {number}: expected two numbers, got {line!r}"
                ) from None
            if not (math.isfinite(d) and math.isfinite(t)):
                raise TableError(f"{source}: line {number}: expected finite numbers, got {line!r}")
            if disp and d <= disp[-1]:
                raise TableError(f"{source}: line {number}: displacement {d!r} does not increase")
            disp.append(d)
            torque.append(t)
        if len(disp) < 2:
            raise TableError(f"{source}: expected at least 2 rows, got {len(disp)}")
        try:
            return cls(np.array(disp), np.array(torque))
        except TableError as err:
            raise TableError(f"{source}: {err}") from err


class ReversalTracker:
    """Direction of a streamed position and the position of its last reversal.

    The direction flips as soon as the position moves against it by any
    amount; the reversal point is then the previous position (the extremum).
    Before any motion the direction is +1 and the reversal point is the first
    position. Plain float arithmetic: exact and deterministic.
    """

    def __init__(self) -> None:
        self.direction = 1
        self.reversals = 0
        self._last: float | None = None
        self._reversal = 0.0

    def update(self, position_m: float) -> tuple[int, float]:
        """Feed one position (m); return ``(direction, displacement from reversal in m)``."""
        if self._last is None:
            self._last = self._reversal = position_m
            return self.direction, 0.0
        step = position_m - self._last
        if step * self.direction < 0.0:
            self.direction = -self.direction
            self._reversal = self._last
            self.reversals += 1
        self._last = position_m
        return self.direction, abs(position_m - self._reversal)


class FrictionFeedforward:
    """Streaming friction feedforward current from a table (paper 000 Fig. 17).

    Parameters
    ----------
    table : FrictionTable
        The data-based friction model.
    torque_constant_Nm_per_A : float
        Nominal ``K_T``, N m/A, > 0.
    """

    def __init__(self, table: FrictionTable, *, torque_constant_Nm_per_A: float) -> None:
        self.table = table
        self._kt = require_positive("torque_constant_Nm_per_A", torque_constant_Nm_per_A)
        self._tracker = ReversalTracker()

    def current_A(self, position_m: float) -> float:
        """Feedforward current (A) for the next reference position ``y_d[k]`` (m)."""
        direction, displacement = self._tracker.update(position_m)
        return float(self.table.torque_Nm_at(displacement, direction)) / self._kt


def build_friction_table(
    *,
    position_m: ArrayLike,
    torque_Nm: ArrayLike,
    bin_width_m: float,
    max_displacement_m: float,
) -> FrictionTable:
    """Friction table from a slow reversing run.

    Samples before the first reversal are ignored. Each later sample gives a
    displacement from the last reversal and a torque, mirrored (``-torque``)
    in the negative direction. Samples are averaged in bins
    ``[i w, (i+1) w)`` up to ``max_displacement_m``; the table has a point at
    each bin centre and one at displacement 0 holding the first bin's value.

    Parameters
    ----------
    position_m : array
        Reference position at each sample, m.
    torque_Nm : array
        Friction torque estimate at each sample, N m.
    bin_width_m, max_displacement_m : float
        Bin width and the largest displacement tabulated, m, > 0.

    Raises
    ------
    TableError
        When a bin has no sample (lengthen the run or widen the bins).
    """
    pos = np.asarray(position_m, dtype=float)
    tq = np.asarray(torque_Nm, dtype=float)
    if pos.shape != tq.shape or pos.ndim != 1:
        raise TableError(
            f"position_m, torque_Nm: expected 1-D arrays of one length, got {pos.shape}, {tq.shape}"
        )
    w = require_positive("bin_width_m", bin_width_m)
    top = require_positive("max_displacement_m", max_displacement_m)
    tracker = ReversalTracker()
    disp = np.empty(pos.size)
    signed = np.empty(pos.size)
    keep = np.zeros(pos.size, dtype=bool)
    for k, (p, t) in enumerate(zip(pos.tolist(), tq.tolist(), strict=True)):
        direction, d = tracker.update(p)
        disp[k], signed[k], keep[k] = d, direction * t, tracker.reversals > 0
    n_bins = math.floor(top / w + 1e-9)
    idx = np.floor(disp[keep] / w).astype(int)
    vals = signed[keep]
    inside = idx < n_bins
    sums = np.bincount(idx[inside], weights=vals[inside], minlength=n_bins)
    counts = np.bincount(idx[inside], minlength=n_bins)
    if n_bins < 1 or np.any(counts == 0):
        empty = int(np.argmax(counts == 0)) if n_bins else 0
        raise TableError(
            f"bin {empty} ([{empty * w:.3g}, {(empty + 1) * w:.3g}) m) has no sample: "
            "lengthen the run or widen the bins"
        )
    means = sums / counts
    centres = (np.arange(n_bins) + 0.5) * w
    return FrictionTable(np.concatenate(([0.0], centres)), np.concatenate(([means[0]], means)))
