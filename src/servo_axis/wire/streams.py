"""Which stamps of a per-sample stream are taken, for the nodes and for the bag's readers.

A per-sample stream (``state``, ``command``, ``reference``) carries one
message per control step, in order. :class:`StreamGate` takes exactly the
next step in lockstep (``window=1``), or a step at most ``window`` ahead of
the last one in realtime (where a lost sample is a deadline miss, not an
error). A message ahead of that (a stranger's ``step + 1000`` or ``1e9 s``)
or behind it (a replay) is refused and leaves the gate as it was, so it
never displaces the real stream. The nodes apply it after a message's
payload is validated (:mod:`servo_axis.wire.messages`), and the analysis
applies the same gate to the bag in arrival order, so that junk a recorder
wrote changes no figure. The streams and their checks are those of the
topic layouts (:mod:`servo_axis.wire.layouts`).

Nothing here imports rclpy.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, TypeVar

from servo_axis.core import deadlines
from servo_axis.core.errors import SignalError
from servo_axis.wire import cdr, layouts
from servo_axis.wire.layouts import ArrayLayout, JointLayout
from servo_axis.wire.sample_cdr import ArrayCodec, JointCodec

T = TypeVar("T")


class StreamGate:
    """Accepts the next step of a stream (or one within ``window`` of it).

    Parameters
    ----------
    window : int
        How far past the last accepted step a step may be, >= 1: 1 = exactly
        the next (lockstep); larger = that many steps may be skipped
        (realtime).
    first : int or None
        The step the stream starts at (its first accepted step must be
        within ``window`` of ``first - 1``); None: a node that joins a
        running stream takes the first step it gets.
    limit : int or None
        The first step beyond the stream (the run's length).
    stride : int
        Steps between two samples of the stream (a stream of reference
        instants has stride ``T_r / T_u``), >= 1.
    period_ns : int or None
        Realtime, a node's gate: the control period, ns. A step further
        ahead than ``window`` is then taken too when it is plausible by the
        wall clock: not beyond where the stream's clock is now, as the
        arrivals of the steps taken show its start
        (:func:`~servo_axis.core.deadlines.start_estimate_ns`: never before
        it), plus ``window`` samples. A node that fell behind (a stall, a
        reader's history that overflowed) takes the newest sample and goes
        on, while a stranger's ``step + 1000`` or ``1e9 s`` stamp is still
        refused. None: no wall clock (lockstep, a bag's analysis).
    plausible : callable or None
        ``plausible(step)``: whether a step further ahead than ``window`` is
        taken, in place of the wall clock of ``period_ns`` (a stream that
        runs ahead of the clock, as the references do, is bounded by the
        clock of another stream); None: as ``period_ns`` says.
    """

    def __init__(
        self,
        *,
        window: int = 1,
        first: int | None = 0,
        limit: int | None = None,
        stride: int = 1,
        period_ns: int | None = None,
        plausible: Callable[[int], bool] | None = None,
    ) -> None:
        if window < 1:
            raise ValueError(f"window: expected >= 1, got {window!r}")
        if stride < 1:
            raise ValueError(f"stride: expected >= 1, got {stride!r}")
        self.window = window
        self.stride = stride
        self.limit = limit
        self.last: int | None = None if first is None else first - stride
        self.period_ns = period_ns
        self.plausible = plausible
        self._start_ns: int | None = None  # the stream clock's d_0, from the arrivals
        #: Samples of the stream passed over (gaps within the window, and jumps).
        self.skipped = 0
        #: Jumps further than the window taken because the wall clock allowed them.
        self.jumps = 0

    def now_step(self) -> int | None:
        """Realtime: the step the stream's clock is at now, as the arrivals show it (None: not known)."""
        if self.period_ns is None or self._start_ns is None:
            return None
        return (time.monotonic_ns() - self._start_ns) // self.period_ns

    def _plausible(self, step: int) -> bool:
        """Realtime: ``step`` is not ahead of where the stream's clock is now (plus the window),
        or ``plausible`` says it may be taken."""
        if self.plausible is not None:
            return self.plausible(step)
        now = self.now_step()
        return now is not None and step <= now + self.window * self.stride

    def check(self, step: int) -> None:
        """Raise :class:`SignalError` unless ``step`` is one the gate takes now (nothing changes)."""
        if self.limit is not None and step >= self.limit:
            raise SignalError(f"stamp beyond the run's last step {self.limit - 1} (step {step})")
        if step < 0:
            raise SignalError(f"negative step {step}")
        if step % self.stride:
            raise SignalError(f"step {step} is not on the stream's grid of {self.stride} steps")
        if self.last is None:
            return
        if step <= self.last:
            raise SignalError(f"stale stamp (step {step}, last taken {self.last})")
        if step > self.last + self.window * self.stride and not self._plausible(step):
            expected = (
                f"{self.last + self.stride}"
                if self.window == 1
                else f"at most {self.last + self.window * self.stride}"
            )
            raise SignalError(f"stamp ahead of the stream (step {step}, expected {expected})")

    def accept(self, step: int) -> None:
        """:meth:`check`, then take ``step`` as the last one."""
        self.check(step)
        if self.last is not None:
            gap = (step - self.last) // self.stride - 1
            if gap > 0:
                self.skipped += gap
                self.jumps += gap >= self.window
        if self.period_ns is not None:
            self._start_ns = deadlines.start_estimate_ns(
                self._start_ns, time.monotonic_ns(), step, self.period_ns
            )
        self.last = step

    @property
    def expected(self) -> int | None:
        """The next step in lockstep (None before the first of a joining node)."""
        return None if self.last is None else self.last + self.stride


def gated(items: Iterable[tuple[int, T]], gate: StreamGate) -> Iterator[tuple[int, T]]:
    """The ``(step, item)`` pairs of ``items`` (in arrival order) that ``gate`` takes."""
    for step, item in items:
        try:
            gate.accept(step)
        except SignalError:
            continue
        yield step, item


#: The JointState streams of the table, by topic (:mod:`servo_axis.wire.layouts`).
JOINT_STREAMS: dict[str, JointLayout[Any]] = layouts.JOINT_LAYOUTS

#: The per-sample Float64MultiArray streams of the table (a vector per control
#: step that carries the step as its first field), by topic.
ARRAY_STREAMS: dict[str, ArrayLayout[Any]] = {
    name: layout
    for name, layout in layouts.LAYOUTS.items()
    if isinstance(layout, ArrayLayout) and layout.per_step
}

#: The codecs of the per-sample vectors of scalars (:class:`~servo_axis.wire.sample_cdr.ArrayCodec`).
ARRAY_CODECS: dict[str, ArrayCodec[Any]] = {
    name: ArrayCodec(layout)
    for name, layout in ARRAY_STREAMS.items()
    if layout.sample is not None and set(layout.sizes) == {1}
}

#: Every stream with one message per control step (what a recorder may count).
STEP_STREAMS: frozenset[str] = frozenset(JOINT_STREAMS) | frozenset(ARRAY_STREAMS)


def decode_joint_stream(name: str, data: bytes, *, axis: str, period_ns: int) -> tuple[int, Any]:
    """Step and sample of a recorded JointState of stream ``name`` that passes the subscribers' checks.

    The sample is the layout's (:class:`~servo_axis.wire.layouts.StateSample`, ...).

    Raises
    ------
    SignalError
        For a payload that does not decode, the wrong joints, a missing or
        non-finite value, a stamp off the control grid.
    """
    sample = joint_codec(name, axis, period_ns).decode(data)
    return sample.step, sample


def decode_array_stream(name: str, data: bytes) -> tuple[int, Any]:
    """Step and sample of a recorded per-sample Float64MultiArray of stream ``name``.

    Raises
    ------
    SignalError
        For a payload that does not decode, a layout other than the topic's
        fields, a non-finite value or a value its field's rule refuses.
    """
    codec = ARRAY_CODECS.get(name)
    if codec is not None:
        sample = codec.decode(data)
    else:
        layout = ARRAY_STREAMS[name]
        msg = cdr.decode_float64_multi_array(data)
        sample = layout.sample_of(layout.values(msg.labels, msg.sizes, msg.data, msg.strides))
    return sample.step, sample


def decode_step_stream(name: str, data: bytes, *, axis: str, period_ns: int) -> tuple[int, Any]:
    """Step and sample of a recorded sample of any :data:`STEP_STREAMS` stream.

    The checks of :func:`decode_joint_stream` and :func:`decode_array_stream`
    (the recorder counts with it, every step).
    """
    if name in ARRAY_STREAMS:
        return decode_array_stream(name, data)
    return decode_joint_stream(name, data, axis=axis, period_ns=period_ns)


@functools.lru_cache(maxsize=64)
def joint_codec(name: str, axis: str, period_ns: int) -> JointCodec[Any]:
    """The codec of JointState stream ``name`` on ``axis`` (one per stream, made once)."""
    return JointCodec(JOINT_STREAMS[name], axis=axis, period_ns=period_ns)
