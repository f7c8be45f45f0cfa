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


class StampOrigin:
    """The steps of a stream stamped by a plant's own clock (``state_stamps: plant_clock``).

    Such a plant (a driver stamping with its ROS time) is not on the ``k T_u``
    grid and does not start at 0. Each state is a step of its own: the first
    is step 0 (its stamp is ``t_0``), each later one the step nearest
    ``(t - t_0) / T_u`` but at least one after the previous state's
    (:meth:`state_step`): a timer that jitters by up to a period keeps one
    step per state, and one that skipped ticks leaves steps out. The
    commands echo their state's stamp: :meth:`command_step` is the step of
    the state of that stamp. A stamp not after the previous state's is
    refused; with arrival times, so is one further ahead than the time since
    the first arrival allows (plus ``slack`` samples): junk stamped ``+1000``
    steps never displaces the real stream.

    Parameters
    ----------
    period_ns : int
        The nominal period ``T_u``, ns, > 0.
    slack : int
        Samples a stamp may lead the arrival clock by, >= 0 (200: a reader's
        latency spikes of tens of ms under load are not junk).
    remember : int
        States whose stamps are kept for their commands, >= 1.
    """

    def __init__(self, period_ns: int, *, slack: int = 200, remember: int = 4096) -> None:
        if period_ns <= 0:
            raise ValueError(f"period_ns: expected > 0, got {period_ns!r}")
        self.period_ns = period_ns
        self.slack = slack
        self.remember = remember
        self.origin_ns: int | None = None
        self._first_arrival_ns: int | None = None
        self._last: tuple[int, int] | None = None  # (stamp ns, step) of the last state
        self._steps: dict[int, int] = {}  # stamp ns -> step, the last `remember` states

    def state_step(self, stamp_ns: int, arrival_ns: int | None = None) -> int:
        """The step of the next state, stamped ``stamp_ns`` (the first one sets ``t_0``).

        Raises
        ------
        SignalError
            For a stamp not after the previous state's, or ahead of what the
            arrival clock allows.
        """
        if self.origin_ns is None or self._last is None:
            self.origin_ns, self._first_arrival_ns = stamp_ns, arrival_ns
            return self._take(stamp_ns, 0)
        last_ns, last_step = self._last
        if stamp_ns <= last_ns:
            raise SignalError(f"stamp {stamp_ns} ns not after the last state's {last_ns} ns")
        nearest = (stamp_ns - self.origin_ns + self.period_ns // 2) // self.period_ns
        step = max(last_step + 1, nearest)
        if arrival_ns is not None and self._first_arrival_ns is not None:
            bound = (arrival_ns - self._first_arrival_ns) // self.period_ns + self.slack
            if step > bound:
                raise SignalError(
                    f"stamp ahead of the plant's clock (step {step}, at most {bound} by now)"
                )
        return self._take(stamp_ns, step)

    def _take(self, stamp_ns: int, step: int) -> int:
        self._last = (stamp_ns, step)
        self._steps[stamp_ns] = step
        if len(self._steps) > self.remember:
            del self._steps[next(iter(self._steps))]
        return step

    @property
    def steps_by_stamp(self) -> dict[int, int]:
        """The step of each remembered state, by its stamp (ns)."""
        return self._steps

    @property
    def last_stamp_ns(self) -> int | None:
        """The stamp of the last state taken (None before the first)."""
        return None if self._last is None else self._last[0]

    def command_step(self, stamp_ns: int) -> int:
        """The step of the state stamped ``stamp_ns`` (a command echoes it).

        Raises
        ------
        SignalError
            For a stamp that is not one of the last states' taken.
        """
        step = self._steps.get(stamp_ns)
        if step is None:
            raise SignalError(f"stamp {stamp_ns} ns is not that of a state taken")
        return step


class EarlyCommands:
    """Commands of a plant that owns its clock that came before the state they echo.

    A reader of both streams (the recorder) takes ``state`` and ``command``
    from two subscriptions, in whatever order its executor runs their
    callbacks: a reader that fell behind has both queues full and may take
    ``command[k]`` before ``state[k]``. Such a command is kept (at most
    ``limit``, the oldest refused past that) until the state of its stamp is
    taken (:meth:`state_taken`); one whose stamp is not after the last state
    taken never will be, and is refused at once; and once a state later than
    a kept command's stamp is taken, that command's state never came and it
    is refused then. The steps a command gets so do not depend on the order
    of the two callbacks.

    Parameters
    ----------
    origin : StampOrigin
        The steps of the states taken.
    limit : int
        Commands kept at most, >= 1.
    """

    def __init__(self, origin: StampOrigin, *, limit: int = 4096) -> None:
        if limit < 1:
            raise ValueError(f"limit: expected >= 1, got {limit!r}")
        self.origin = origin
        self.limit = limit
        self._waiting: dict[int, int] = {}  # stamp ns -> commands of that stamp kept
        #: Commands refused because they were kept too long or too many.
        self.expired = 0

    @property
    def waiting(self) -> int:
        """Commands kept, waiting for their state."""
        return sum(self._waiting.values())

    def step(self, stamp_ns: int) -> int | None:
        """The step of the command stamped ``stamp_ns``, or None: kept until its state comes.

        Raises
        ------
        SignalError
            For a stamp whose state cannot come any more (not after the last
            state taken, not one of them), or when ``limit`` commands are kept.
        """
        steps = self.origin.steps_by_stamp
        step = steps.get(stamp_ns)
        if step is not None:
            return step
        last = self.origin.last_stamp_ns
        if last is not None and stamp_ns <= last:
            raise SignalError(f"stamp {stamp_ns} ns is not that of a state taken")
        if self.waiting >= self.limit:
            raise SignalError(
                f"stamp {stamp_ns} ns: {self.limit} commands already wait for their states"
            )
        self._waiting[stamp_ns] = self._waiting.get(stamp_ns, 0) + 1
        return None

    def state_taken(self, stamp_ns: int, step: int) -> tuple[list[int], int]:
        """A state stamped ``stamp_ns`` was taken as ``step``: the steps of the kept commands
        that echo it (one per command), and how many kept ones are refused now (stamps before
        it: their states never came)."""
        matched = [step] * self._waiting.pop(stamp_ns, 0)
        stale = [s for s in self._waiting if s < stamp_ns]
        refused = sum(self._waiting.pop(s) for s in stale)
        self.expired += refused
        return matched, refused


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
