"""The lockstep stepping logic of the nodes, without rclpy (testable as plain objects).

* :func:`stream_gate`: the gate through which a node takes a per-sample
  stream (:class:`servo_axis.wire.streams.StreamGate`; :func:`stream_window`:
  how far it may jump);
* :class:`PeerWatch`: since when a lockstep node's producer is gone (the only
  case in which it stops waiting for it), and :func:`waited_too_long`: when a
  wait for a peer ends;
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

from servo_axis.wire.streams import StreamGate

S = TypeVar("S")


#: Window of a per-sample stream in realtime (:class:`~servo_axis.wire.streams.StreamGate`),
#: in samples of the stream. A realtime stream is reliable and in order, so
#: it skips a sample only if the transport lost it (the keep-last 2,000
#: history overflowed); a window of a few samples tolerates such a short gap,
#: and bounds what a junk stamp inside it can displace to that many samples
#: (the real stream is taken again right after it). A stamp further ahead is
#: refused as in lockstep.
REALTIME_WINDOW = 10


def stream_window(lockstep: bool) -> int:
    """The window of a per-sample stream gate: exactly the next in lockstep."""
    return 1 if lockstep else REALTIME_WINDOW


def stream_gate(
    lockstep: bool,
    *,
    first: int | None = 0,
    limit: int | None = None,
    stride: int = 1,
    period_ns: int | None = None,
) -> StreamGate:
    """The gate through which a node takes a per-sample stream (every node's, in one place).

    Exactly the next sample in lockstep; in realtime at most
    :data:`REALTIME_WINDOW` samples ahead of the last one taken (a stamp
    further ahead is refused unless the wall clock makes it plausible:
    ``period_ns``, realtime only, a node that fell behind takes the newest
    sample and goes on). ``first``, ``limit`` and ``stride`` are the
    :class:`~servo_axis.wire.streams.StreamGate`'s.
    """
    return StreamGate(
        window=stream_window(lockstep),
        first=first,
        limit=limit,
        stride=stride,
        period_ns=None if lockstep else period_ns,
    )


class PeerWatch:
    """Whether, and since when, a peer (a topic's publisher) is gone.

    A watchdog calls :meth:`look` with :meth:`~servo_axis.nodes.inputs.Inputs.peer_alive`'s answer;
    :meth:`gone_for` is how long the peer has been gone without interruption
    (0 while it lives; a peer never seen is gone from the first look), and
    :attr:`lost_at` when a peer seen alive went away (it may be back since:
    a respawned node, which missed what the old one owed), until
    :meth:`forget`.
    """

    def __init__(self) -> None:
        self.gone_since: float | None = None
        self.lost_at: float | None = None
        self.alive = False

    def look(self, alive: bool, now: float) -> None:
        """Record one look at the peer's liveliness at (monotonic) time ``now``."""
        if alive:
            self.gone_since = None
        else:
            if self.gone_since is None:
                self.gone_since = now
            if self.alive and self.lost_at is None:
                self.lost_at = now
        self.alive = alive

    def gone_for(self, now: float) -> float:
        """Seconds the peer has been gone without interruption (0 while it lives)."""
        return 0.0 if self.gone_since is None else now - self.gone_since

    def forget(self) -> None:
        """Clear :attr:`lost_at` (the wait it mattered for is over)."""
        self.lost_at = None


def waited_too_long(
    peer: PeerWatch,
    *,
    waiting_since: float,
    timeout_s: float,
    now: float,
    name: str,
    lockstep: bool,
) -> str | None:
    """Why a wait for ``peer`` (called ``name``) has lasted too long, or None to go on waiting.

    ``waiting_since`` is when the wait began, or when the plant last moved
    during it. Realtime: the plant stood still for ``timeout_s``. Lockstep:
    the peer has been gone for ``timeout_s``, or it went away during the
    wait (a respawned peer may not deliver what the dead one owed) and the
    plant has then stood still for ``timeout_s``; while it lives, never.
    """
    if not lockstep:
        still = now - waiting_since
        return f"the plant stood still for {still:.3g} s" if still > timeout_s else None
    if peer.gone_for(now) > timeout_s:
        return f"the {name} has been gone for {peer.gone_for(now):.3g} s"
    if peer.lost_at is not None:
        still = now - max(waiting_since, peer.lost_at)
        if still > timeout_s:
            return (
                f"the {name} went away during the wait and the plant stood still for {still:.3g} s"
            )
    return None


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
