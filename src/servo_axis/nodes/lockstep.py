"""The lockstep stepping logic of the nodes, without rclpy (testable as plain objects).

* :class:`StampGate`: a per-sample stream accepts only stamps after the last
  one (and not beyond a limit);
* :class:`FlowControl`: the plant never runs more than a lag ahead of what
  the recorder has acknowledged, and ends only when it has everything;
* :class:`SampleBuffer`: samples that came ahead (the feedforward's preview)
  waiting for the step that uses them;
* :class:`PeriodCollector`: the learning unit's error of one period at the
  instants it learns from, and whether the period was seen whole.
"""

from __future__ import annotations

import math
from typing import Generic, TypeVar

import numpy as np

from servo_axis.core.errors import SignalError

S = TypeVar("S")


class StampGate:
    """Accepts steps strictly after the last accepted one and below ``limit``.

    Parameters
    ----------
    limit : int or None
        First step that is beyond the stream (e.g. the run's length).
    """

    def __init__(self, limit: int | None = None) -> None:
        self.last = -1
        self.limit = limit

    def check(self, step: int) -> None:
        """Raise :class:`SignalError` for a stale or out-of-run step (nothing changes)."""
        if step <= self.last:
            raise SignalError(f"stale stamp (step {step} after {self.last})")
        if self.limit is not None and step >= self.limit:
            raise SignalError(f"stamp beyond the run's last step {self.limit - 1} (step {step})")

    def accept(self, step: int) -> None:
        """:meth:`check`, then take ``step`` as the last one."""
        self.check(step)
        self.last = step


class FlowControl:
    """The plant's wait for the recorder in lockstep.

    Parameters
    ----------
    enabled : bool
        Off: never wait.
    max_lag_steps : int
        Largest lead of the plant over the recorder's acknowledgement, >= 1.
    steps : int
        Steps of the run (the end waits until all are recorded).
    """

    def __init__(self, *, enabled: bool, max_lag_steps: int, steps: int) -> None:
        self.enabled = enabled
        self.max_lag_steps = max_lag_steps
        self.steps = steps
        self.recorded = -1

    def acknowledge(self, recorded: int) -> None:
        """The recorder has every sample before step ``recorded``."""
        self.recorded = max(self.recorded, recorded)

    @property
    def ready(self) -> bool:
        """The recorder has announced itself (or flow control is off)."""
        return not self.enabled or self.recorded >= 0

    def may_step_to(self, next_step: int) -> bool:
        """Whether the plant may publish ``next_step`` now."""
        if not self.enabled or next_step >= self.steps:
            return True
        return self.recorded >= next_step - self.max_lag_steps

    @property
    def complete(self) -> bool:
        """Everything of the run is recorded (or flow control is off)."""
        return not self.enabled or self.recorded >= self.steps


class SampleBuffer(Generic[S]):
    """Samples by step that came before the step that uses them."""

    def __init__(self) -> None:
        self._samples: dict[int, S] = {}

    def put(self, step: int, sample: S) -> None:
        """Keep ``sample`` for ``step``."""
        self._samples[step] = sample

    def take(self, step: int) -> S | None:
        """The sample of ``step`` (removed), or None if it has not come."""
        return self._samples.pop(step, None)

    def drop_before(self, step: int) -> None:
        """Forget samples of steps before ``step`` (samples whose step never came)."""
        for old in [s for s in self._samples if s < step]:
            del self._samples[old]

    def __len__(self) -> int:
        return len(self._samples)


class PeriodCollector:
    """The error of one learning period, one value per index, NaN where none came.

    Parameters
    ----------
    size : int
        Values per period.
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self.error = np.full(size, math.nan)

    def put(self, index: int, value: float) -> None:
        """The error at ``index`` of the period."""
        self.error[index] = value

    @property
    def received(self) -> int:
        """How many values of the period came."""
        return int(np.count_nonzero(np.isfinite(self.error)))

    @property
    def complete(self) -> bool:
        """Every value of the period came (a partial period must not be learned)."""
        return self.received == self.size

    def restart(self) -> np.ndarray:
        """The period's error; the collector starts a new period."""
        error, self.error = self.error, np.full(self.size, math.nan)
        return error
