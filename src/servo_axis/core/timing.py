"""The sample grid: control period ``T_u``, reference period ``T_r = ratio T_u``, cycles.

Paper 000 Sect. III-A: the feedback runs at ``T_u``; the multirate PTC
updates its target at the reference instants ``i T_r`` with ``T_r = 2 T_u``
for the order-2 plant (as many inputs per reference period as states).
Control sample ``k`` is at ``k T_u``; reference instant ``i`` is control
sample ``ratio * i``. A learning cycle (000) or trial (001) is a whole
number of reference periods. Every node and every report takes this
arithmetic from here, so that the ratio is written once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ConfigError, require_positive


@dataclass(frozen=True, kw_only=True)
class SampleGrid:
    """Control and reference periods of an axis.

    Parameters
    ----------
    control_period_s : float
        ``T_u``, s, > 0.
    ratio : int
        ``T_r / T_u``, >= 1 (2 for the multirate PTC of an order-2 plant).
    """

    control_period_s: float
    ratio: int = 2

    def __post_init__(self) -> None:
        require_positive("control_period_s", self.control_period_s)
        if isinstance(self.ratio, bool) or not isinstance(self.ratio, int) or self.ratio < 1:
            raise ConfigError(f"ratio: expected an integer >= 1, got {self.ratio!r}")

    @property
    def reference_period_s(self) -> float:
        """``T_r = ratio T_u``, s."""
        return self.ratio * self.control_period_s

    def steps(self, duration_s: float, *, name: str = "duration_s") -> int:
        """Control samples in ``duration_s`` (rounded), at least 1.

        Raises
        ------
        ConfigError
            Naming ``name`` if the duration is not finite or holds no sample.
        """
        if not math.isfinite(duration_s):
            raise ConfigError(f"{name}: expected a finite duration, got {duration_s!r}")
        steps = round(duration_s / self.control_period_s)
        if steps < 1:
            raise ConfigError(f"{name}: expected at least one control period, got {duration_s!r}")
        return int(steps)

    def instants_per(self, period_s: float, *, name: str, minimum: int = 1) -> int:
        """Reference instants in ``period_s`` (a cycle, a trial), which must be whole.

        Raises
        ------
        ConfigError
            Naming ``name`` if ``period_s`` is not a whole number (>= ``minimum``)
            of reference periods.
        """
        tr = self.reference_period_s
        count = round(period_s / tr) if math.isfinite(period_s) else 0
        if count < minimum or not math.isclose(count * tr, period_s, rel_tol=1e-9):
            raise ConfigError(
                f"{name}: expected a whole number (>= {minimum}) of reference periods {tr!r} s, "
                f"got {period_s!r}"
            )
        return int(count)

    def steps_per(self, period_s: float, *, name: str) -> int:
        """Control samples in ``period_s``, which must be a whole number of them."""
        count = round(period_s / self.control_period_s) if math.isfinite(period_s) else 0
        if count < 1 or abs(count * self.control_period_s - period_s) > 1e-9:
            raise ConfigError(
                f"{name}: expected a whole number of control periods, got {period_s!r}"
            )
        return int(count)

    def is_reference_instant(self, step: int) -> bool:
        """True when control sample ``step`` is a reference instant."""
        return step % self.ratio == 0

    def reference_instants(self, steps: ArrayLike) -> NDArray[np.bool_]:
        """Mask of the reference instants among control samples ``steps``."""
        mask: NDArray[np.bool_] = np.asarray(steps) % self.ratio == 0
        return mask

    def instant_of(self, step: int) -> int:
        """Reference instant of control sample ``step`` (the one at or before it)."""
        return step // self.ratio

    def step_of(self, instant: int) -> int:
        """Control sample of reference instant ``instant``."""
        return instant * self.ratio
