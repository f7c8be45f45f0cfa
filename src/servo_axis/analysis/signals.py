"""Recorded signals of a run, per control step, read from its bag without ROS.

The bag is read as raw CDR payloads (:func:`servo_axis.recording.reader.read_raw`)
and decoded with :mod:`servo_axis.wire.cdr`; a topic is known by its name in
the table of topics (:mod:`servo_axis.wire.topics`) under any namespace (so
``/x/state`` of a namespaced axis is ``state``, ``/x/clock`` is ``/clock``).

The recorder writes every message it gets, a stranger's included: a
message of a publisher that does not play the topic's role is on a channel
of its own (:data:`~servo_axis.recording.reader.STRANGER_KEY`), counted in
:attr:`BagStreams.strangers` and never part of a stream. Of the rest, only
validated samples become signals (:func:`read_streams`): each message is
checked as the nodes check it, by its topic's layout
(:mod:`servo_axis.wire.layouts`, the table the nodes' conversions come from:
joint names of the axis, one finite value per joint in each array the topic
uses, the stamp on the control grid; the labels, finite values and each
field's rule of a Float64MultiArray), and then one sample per step and stream
is kept by a :class:`~servo_axis.wire.streams.StreamGate` applied in recording
order: exactly the next step in lockstep, at most :data:`REALTIME_WINDOW`
samples ahead in realtime, never beyond the run. What fails is dropped and
counted (:attr:`Signals.dropped`): junk in a bag changes no figure. The rules
per topic beyond its layout (:class:`StreamRules`, :func:`stream_for`):

* ``state``, ``reference``, ``command``: steps 0, 1, ...
* ``deformation``: steps 0, 1, ... like ``state``; none in a run whose
  feedback has ``deformation.enabled`` false.
* ``learning/correction``: the reference instants from the second cycle on,
  one after the other; ``learning/input_correction``: the control samples
  from the second trial on; none in a run without learning.
* ``learning/cycle_stats``: cycles 1, 2, ... of the run, ``cycles_learned``
  never decreasing and at most the cycle; none in a run without learning.
* ``fault``: a step of the run, later than the previous fault's, a code of
  :class:`~servo_axis.core.feedback.loop.Fault`.
* ``plant/status``: the counters never decreasing; in lockstep the steps 0,
  ``status_every_steps``, ...; in realtime increasing (a last one at the end
  of the run).
* ``/clock``: the steps 0, ``clock_every_steps``, ...
* ``recorder/progress`` (if recorded): never decreasing, at most the run's
  steps.
* ``identifier/estimates`` (checked by
  :func:`~servo_axis.wire.layouts.check_estimate_values`): a step of the
  run on the identifier's schedule; none in a run without an ``identifier``
  section. Estimates carry no stamp and a restarted identifier may publish
  again one that was already recorded, so there is no gate: the first
  estimate of each step is kept, a later one with the same values is a
  repeat (counted in :attr:`BagStreams.repeated`, not junk) and one with
  other values is dropped like junk. :attr:`Signals.estimates` are in order
  of step.

The rules come from the run's parameters: the scenario if given, else the
run's ``params.yaml`` next to the bag (what the nodes ran with), else the
defaults of the schema. Every other topic is only counted.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml
from numpy.typing import NDArray

from servo_axis.analysis.serial import Serial
from servo_axis.core.deformation import DeformationTrace
from servo_axis.core.errors import ServoAxisError, SignalError
from servo_axis.core.feedback.loop import Fault
from servo_axis.core.feedback.output import controlled_output
from servo_axis.params.factories import (
    build_generator,
    checked_values,
    grid,
    identifier_schedule,
    learning_period_steps,
    run_steps,
)
from servo_axis.params.resolve import Resolved
from servo_axis.params.scenario import ROLES, SHARED_SECTION
from servo_axis.recording.reader import RawMessage, read_raw
from servo_axis.wire import cdr, layouts, topics
from servo_axis.wire.checks import step_of_stamp_ns
from servo_axis.wire.layouts import ArrayLayout, EstimateData
from servo_axis.wire.streams import (
    StampOrigin,
    StreamGate,
    decode_array_stream,
    decode_joint_stream,
    joint_codec,
)

#: The scenario's section of the parameter identifier (paper 003), present
#: only when one runs.
IDENTIFIER_SECTION = "identifier"

#: Name of each fault code of the ``fault`` topic (``following_error``, ...).
FAULT_NAMES: dict[int, str] = {int(f): f.name.lower() for f in Fault}


@dataclass(frozen=True)
class FaultRecord(Serial):
    """One message of the ``fault`` topic.

    Attributes
    ----------
    step : int
        Control sample at which the loop tripped.
    code : int
        :class:`~servo_axis.core.feedback.loop.Fault` code.
    name : str
        The code's name (``following_error``, ...), ``"?"`` for an unknown code.
    value : float
        The value that tripped (m, A or s, by code).
    """

    step: int
    code: int
    name: str
    value: float


#: How far past the last kept sample a sample of a realtime run may be, in
#: samples of its stream (there a lost message is a deadline miss, not an
#: error); a lockstep run takes exactly the next one.
REALTIME_WINDOW = 100


@dataclass(frozen=True, eq=False)
class Signals:
    """Signals of a run per recorded control step.

    Attributes
    ----------
    step : ndarray of int
        Control samples that have both a validated ``state`` and a validated
        ``reference`` message, ascending.
    encoder_rad, scale_m : ndarray of float
        Sensor readings at those steps (rad, m).
    reference_rad, feedforward_Nm : ndarray of float
        Feedback reference (rad) and feedforward torque ``K_T,n u_ff`` (N m).
    command_Nm : ndarray of float
        Motor torque reference ``K_T,n i`` (N m); NaN at a step without a
        validated ``command`` message.
    faults : list of FaultRecord
        The validated ``fault`` messages, in recording order.
    counts : dict
        Messages per topic as recorded, junk included (every topic of the
        bag, in order of first message).
    dropped : dict
        Recorded messages that failed validation or their stream's gate, per
        topic that has rules (:func:`read_streams`; 0 included), in order of
        first message.
    estimates : tuple of EstimateData
        The validated ``identifier/estimates`` (first of each step), in order
        of step; empty without an identifier.
    repeated : dict
        Per topic, recorded messages that repeat one already kept (the same
        step and values: a restarted identifier's), neither kept nor dropped.
    deformation : DeformationTrace or None
        The ``deformation`` topic (004 eqs. (6)-(7)) at each of :attr:`step`:
        ``d_r`` (m/rad), the scale's and the encoder's increments over ``p``
        samples (m, rad) and ``valid``, as the feedback published them. At a
        step without a validated message ``d_r`` is 0.0, the increments are
        NaN and ``valid`` is False. None when the bag has no ``deformation``
        topic.
    """

    step: NDArray[np.int_]
    encoder_rad: NDArray[np.float64]
    scale_m: NDArray[np.float64]
    reference_rad: NDArray[np.float64]
    feedforward_Nm: NDArray[np.float64]
    command_Nm: NDArray[np.float64]
    faults: list[FaultRecord] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    estimates: tuple[EstimateData, ...] = ()
    repeated: dict[str, int] = field(default_factory=dict)
    deformation: DeformationTrace | None = None


@dataclass(frozen=True)
class StreamRules:
    """What a valid recorded sample of a run is: the parameters the rules need.

    Attributes
    ----------
    period_ns : int
        Control period ``T_u``, ns: a stamp must be a whole number of them.
    axis : str
        The axis of the joint names (``<axis>_motor``, ``<axis>_table``).
    mode : str
        ``lockstep`` (exactly the next sample) or ``realtime`` (at most
        :data:`REALTIME_WINDOW` samples ahead).
    steps : int or None
        Control steps of the run (nothing at or beyond); None: unknown.
    ratio : int
        ``T_r / T_u``: the learning corrections are on the reference instants.
    cycle_steps : int or None
        Control steps per learning cycle; None: no learning in the run.
    status_every_steps, clock_every_steps : int
        The plant's ``plant/status`` and ``/clock`` strides.
    identifier : bool
        Whether the run has an identifier (an ``identifier`` section): else
        no ``identifier/estimates`` message is valid.
    estimate_period_steps, estimate_latency_steps : int
        The identifier's schedule (``rls_period_s``, ``latency_s`` in control
        samples): a valid estimate has ``step = (n + 1) R - 1`` and applies
        from ``step + 1 + latency``, the feedforward's own rule.
    deformation : bool
        Whether the feedback publishes the deformation ratio
        (``deformation.enabled``): else no ``deformation`` message is valid.
    state_stamps : str
        The plant's ``state_stamps`` (``plant_clock``: :attr:`plant_clock`).
    command_source : str
        The plant's ``command_source``: ``drive_setpoint`` commands are a
        drive's set-points of no step, recorded but not indexed.
    """

    period_ns: int
    axis: str = "x"
    mode: str = "lockstep"
    steps: int | None = None
    ratio: int = 2
    cycle_steps: int | None = None
    status_every_steps: int = 50
    clock_every_steps: int = 10
    identifier: bool = False
    estimate_period_steps: int = 1
    estimate_latency_steps: int = 0
    deformation: bool = False
    state_stamps: str = "grid"
    command_source: str = "stamped"

    @property
    def plant_clock(self) -> bool:
        """``state`` and ``command`` are stamped by the plant's own clock (realtime, issue 31)."""
        return self.state_stamps == "plant_clock" and self.mode != "lockstep"

    @property
    def window(self) -> int:
        """The gates' window: 1 in lockstep, :data:`REALTIME_WINDOW` in realtime."""
        return 1 if self.mode == "lockstep" else REALTIME_WINDOW

    @classmethod
    def defaults(cls, period_s: float) -> StreamRules:
        """The rules of a run of unknown parameters: the schema's defaults, no length, no learning."""
        plant = checked_values("plant", {})
        return cls(
            period_ns=_period_ns(period_s),
            axis=plant.axis,
            mode=plant.mode,
            ratio=grid(plant).ratio,
            status_every_steps=plant.status_every_steps,
            clock_every_steps=plant.clock_every_steps,
        )

    @classmethod
    def from_scenario(cls, scenario: Resolved | dict[str, Any], period_s: float) -> StreamRules:
        """The rules of a run of ``scenario`` (a single-axis scenario or a run's parameters,
        or either read once)."""
        resolved = Resolved.of(scenario)
        plant = resolved.plant
        cycle = None
        if resolved.has("feedforward"):
            cycle = learning_period_steps(resolved.feedforward)
        period, latency = 1, 0
        if resolved.has(IDENTIFIER_SECTION):
            period, latency = identifier_schedule(resolved.identifier)
        return cls(
            period_ns=_period_ns(period_s),
            axis=plant.axis,
            mode=plant.mode,
            steps=run_steps(plant),
            ratio=grid(plant).ratio,
            cycle_steps=cycle,
            status_every_steps=plant.status_every_steps,
            clock_every_steps=plant.clock_every_steps,
            identifier=resolved.has(IDENTIFIER_SECTION),
            estimate_period_steps=period,
            estimate_latency_steps=latency,
            deformation=bool(resolved.feedback.deformation.enabled),
            state_stamps=plant.state_stamps,
            command_source=plant.command_source,
        )

    @classmethod
    def for_bag(
        cls, bag_dir: Path, period_s: float, scenario: Resolved | dict[str, Any] | None = None
    ) -> StreamRules:
        """The rules of ``scenario``, else of the run's ``params.yaml`` beside the bag, else the defaults."""
        if scenario is not None:
            return cls.from_scenario(scenario, period_s)
        params = run_parameters(Path(bag_dir).parent / "params.yaml")
        if params is not None:
            try:
                return cls.from_scenario(params, period_s)
            except ServoAxisError:
                pass
        return cls.defaults(period_s)


def _period_ns(period_s: float) -> int:
    ns = round(period_s * 1e9)
    if ns <= 0:
        raise SignalError(f"period_s: expected a positive period, got {period_s!r}")
    return ns


def run_parameters(path: Path) -> dict[str, Any] | None:
    """A run's ``params.yaml`` as a single-axis scenario (``/**/<node>`` -> ``<node>``); None if unreadable."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError):
        return None
    if not isinstance(data, dict):
        return None
    out: dict[str, Any] = {}
    for key, section in data.items():
        name = key[len("/**/") :] if isinstance(key, str) and key.startswith("/**/") else key
        if name == SHARED_SECTION or name in ROLES or name == IDENTIFIER_SECTION:
            out[name] = section
    return out


class Kept(NamedTuple):
    """A recorded message that passed its topic's rules."""

    step: int  #: control step (cycle number of cycle_stats, value of recorder/progress)
    data: bytes  #: the CDR payload as recorded
    #: the layout's sample (StateSample, DeformationSample, EstimateData, ...),
    #: the checked values of an array topic without one, the ClockData of /clock
    msg: Any


@dataclass(frozen=True, eq=False)
class BagStreams:
    """The validated streams of a bag (:func:`read_streams`).

    Attributes
    ----------
    kept : dict
        Per recorded topic with rules (its name as recorded), the messages
        kept, in recording order: one per step.
    dropped : dict
        Per topic with rules, how many recorded messages were dropped.
    first_reason : dict
        Per topic with a dropped message, why the first one was dropped.
    counts : dict
        Messages per topic as recorded (every topic, in order of first message).
    repeated : dict
        Per topic with a message that repeats one already kept
        (:class:`Repeated`), how many: neither kept nor dropped.
    strangers : dict
        Per topic with a stranger's channel, how many messages strangers
        published (recorded, in ``counts``; neither kept nor dropped).
    """

    kept: dict[str, list[Kept]]
    dropped: dict[str, int]
    first_reason: dict[str, str]
    counts: dict[str, int]
    repeated: dict[str, int] = field(default_factory=dict)
    strangers: dict[str, int] = field(default_factory=dict)

    def by_table_name(self, name: str) -> list[Kept]:
        """The kept messages of table topic ``name`` (``state``, ``/clock``, ...), every namespace."""
        out: list[Kept] = []
        for topic, kept in self.kept.items():
            if table_name(topic) == name:
                out.extend(kept)
        return out


def table_name(topic: str) -> str | None:
    """The table name (:data:`servo_axis.wire.topics.TOPICS`) of a recorded topic, None if none.

    ``/x/state``, ``/state`` and ``state`` are ``state``; ``/x/clock`` is ``/clock``.
    """
    best: str | None = None
    for entry in topics.TOPICS:
        rel = entry.name.lstrip("/")
        if topic in (rel, "/" + rel) or topic.endswith("/" + rel):
            if best is None or len(rel) > len(best.lstrip("/")):
                best = entry.name
    return best


_Check = Callable[[bytes], tuple[int, Any, Callable[[], None] | None]]


class Repeated(Exception):  # noqa: N818 - an outcome, not an error
    """A message that repeats one already kept, value for value: skipped, not junk."""


class AfterTheEnd(Exception):  # noqa: N818 - an outcome, not an error
    """A sample of a plant that owns its clock stamped after the run's last step."""


class _Stream:
    """One recorded topic's rules: payload checks, then its gate (if any)."""

    def __init__(self, check: _Check, gate: StreamGate | None) -> None:
        self._check = check
        self._gate = gate

    def take(self, data: bytes) -> tuple[int, Any]:
        step, msg, commit = self._check(data)
        if self._gate is not None:
            self._gate.accept(step)
        if commit is not None:
            commit()
        return step, msg


def _values(layout: ArrayLayout[Any], data: bytes) -> list[float]:
    """The values of a recorded Float64MultiArray of ``layout``, checked by its layout."""
    msg = cdr.decode_float64_multi_array(data)
    return layout.values(msg.labels, msg.sizes, msg.data, msg.strides)


def _plant_clock_stream(rules: StreamRules, name: str, origin: StampOrigin) -> _Check:
    """``state``/``command`` stamped by the plant's clock: the step each state got in
    arrival order (:class:`StampOrigin`, one step per state), a command its state's."""
    steps = origin.steps_by_stamp

    def check(data: bytes) -> tuple[int, Any, None]:
        sample = joint_codec(name, rules.axis, 1).decode(data)  # its step is its stamp, ns
        step = steps.get(sample.step)
        if step is None:
            raise SignalError(f"stamp {sample.step} ns is not that of a state taken")
        if rules.steps is not None and step >= rules.steps:
            raise AfterTheEnd  # such a plant (a driver) goes on after the run
        return step, dataclasses.replace(sample, step=step), None

    return check


def plant_clock_steps(messages: list[Any], rules: StreamRules) -> StampOrigin:
    """The steps of the recorded states of a plant that owns its clock, in arrival order."""
    origin = StampOrigin(rules.period_ns, remember=2**62)
    for m in messages:
        try:
            origin.state_step(joint_codec("state", rules.axis, 1).decode(m.data).step)
        except SignalError:
            continue
    return origin


def _joint_stream(rules: StreamRules, name: str) -> _Check:
    def check(data: bytes) -> tuple[int, Any, None]:
        step, sample = decode_joint_stream(name, data, axis=rules.axis, period_ns=rules.period_ns)
        return step, sample, None

    return check


def _deformation_stream(rules: StreamRules) -> _Check:
    def check(data: bytes) -> tuple[int, Any, None]:
        # The subscribers' own checks (the layout's: fields, finite values,
        # a whole step, valid 0 or 1).
        step, sample = decode_array_stream("deformation", data)
        return step, sample, None

    return check


def _never(reason: str) -> _Check:
    def check(data: bytes) -> tuple[int, Any, None]:
        raise SignalError(reason)

    return check


def _stats_stream(rules: StreamRules) -> _Check:
    learned = [0]

    def check(data: bytes) -> tuple[int, Any, Callable[[], None]]:
        values = _values(layouts.CYCLE_STATS, data)
        step, n = int(values[0]), int(values[3])
        if n < learned[0] or n > step:
            raise SignalError(f"cycles_learned: {n} after {learned[0]}, in cycle {step}")

        def commit() -> None:
            learned[0] = n

        return step, values, commit

    return check


def _fault_stream(rules: StreamRules) -> _Check:
    def check(data: bytes) -> tuple[int, Any, None]:
        values = _values(layouts.FAULT, data)
        if int(values[1]) not in FAULT_NAMES:
            raise SignalError(f"code: expected one of {sorted(FAULT_NAMES)}, got {values[1]!r}")
        return int(values[0]), values, None

    return check


def _status_stream(rules: StreamRules) -> _Check:
    last = [0, 0, 0]

    def check(data: bytes) -> tuple[int, Any, Callable[[], None]]:
        values = _values(layouts.STATUS, data)
        counters = [int(v) for v in values[1:]]
        if any(c < p for c, p in zip(counters, last, strict=True)):
            raise SignalError(f"counters decrease: {counters} after {last}")

        def commit() -> None:
            last[:] = counters

        return int(values[0]), values, commit

    return check


def _clock_stream(rules: StreamRules) -> _Check:
    def check(data: bytes) -> tuple[int, Any, None]:
        msg = cdr.decode_clock(data)
        return step_of_stamp_ns(msg.stamp_ns, rules.period_ns), msg, None

    return check


def _progress_stream(rules: StreamRules) -> _Check:
    last = [0]

    def check(data: bytes) -> tuple[int, Any, Callable[[], None]]:
        values = _values(layouts.PROGRESS, data)
        done = int(values[0])
        if done < last[0] or (rules.steps is not None and done > rules.steps):
            raise SignalError(f"steps_recorded: {done} after {last[0]} (run of {rules.steps})")

        def commit() -> None:
            last[0] = done

        return done, values, commit

    return check


def _estimate_stream(rules: StreamRules) -> _Check:
    seen: dict[int, list[float]] = {}

    def check(data: bytes) -> tuple[int, Any, Callable[[], None]]:
        values = _values(layouts.ESTIMATES, data)
        estimate = layouts.check_estimate_values(values)
        step = estimate.step
        if rules.steps is not None and step >= rules.steps:
            raise SignalError(f"step {step} beyond the run's last step {rules.steps - 1}")
        period, latency = rules.estimate_period_steps, rules.estimate_latency_steps
        if (step + 1) % period or estimate.applies_from_step != step + 1 + latency:
            raise SignalError(
                f"step {step}, applies_from_step {estimate.applies_from_step}: not on the "
                f"identifier's schedule (every {period} steps, applying {latency + 1} later)"
            )
        if step in seen:
            if seen[step] == values:
                raise Repeated(f"estimate of step {step} again")
            raise SignalError(f"step {step}: an estimate with other values was recorded first")

        def commit() -> None:
            seen[step] = values

        return step, estimate, commit

    return check


def stream_for(name: str, rules: StreamRules, origin: StampOrigin | None = None) -> _Stream | None:
    """The rules of table topic ``name`` (a fresh gate), None for a topic without rules.

    ``origin``: the steps of the states of a plant that owns its clock
    (:func:`plant_clock_steps`), for its ``state`` and ``command``.
    """
    w, limit = rules.window, rules.steps
    if name == "command" and rules.command_source == "drive_setpoint":
        # A drive's set-points are of no step: recorded, not indexed (the
        # torque each step applied is the state's motor effort).
        return None
    if name in ("state", "command") and rules.plant_clock and origin is not None:
        # The plant's timer may skip samples: any step ahead within the run.
        window = 2**62 if limit is None else max(limit, 1)
        return _Stream(
            _plant_clock_stream(rules, name, origin),
            StreamGate(window=window, first=0, limit=limit),
        )
    if name in ("state", "command", "reference"):
        return _Stream(_joint_stream(rules, name), StreamGate(window=w, first=0, limit=limit))
    if name == "deformation":
        if not rules.deformation:
            return _Stream(_never("no deformation ratio in this run"), None)
        # One per step from step 0, like state: the feedback publishes it with
        # each state it answers.
        return _Stream(_deformation_stream(rules), StreamGate(window=w, first=0, limit=limit))
    if name == "learning/correction":
        if rules.cycle_steps is None:
            return _Stream(_never("no learning in this run"), None)
        check = _joint_stream(rules, name)
        gate = StreamGate(window=w, first=rules.cycle_steps, limit=limit, stride=rules.ratio)
        return _Stream(check, gate)
    if name == "learning/input_correction":
        if rules.cycle_steps is None:
            return _Stream(_never("no learning in this run"), None)
        check = _joint_stream(rules, name)
        return _Stream(check, StreamGate(window=w, first=rules.cycle_steps, limit=limit))
    if name == "learning/cycle_stats":
        if rules.cycle_steps is None:
            return _Stream(_never("no learning in this run"), None)
        cycles = None if limit is None else (limit - 1) // rules.cycle_steps + 1
        return _Stream(_stats_stream(rules), StreamGate(window=min(w, 2), first=1, limit=cycles))
    if name == "fault":
        # Strictly later than the previous one, anywhere in the run.
        return _Stream(_fault_stream(rules), StreamGate(window=2**62, first=0, limit=limit))
    if name == "plant/status":
        if rules.mode == "lockstep":
            gate = StreamGate(window=1, first=0, limit=limit, stride=rules.status_every_steps)
        else:  # every status_every_steps and a last one at the end
            end = None if limit is None else limit + 1
            gate = StreamGate(window=2 * rules.status_every_steps, first=0, limit=end)
        return _Stream(_status_stream(rules), gate)
    if name == "/clock":
        gate = StreamGate(window=w, first=0, limit=limit, stride=rules.clock_every_steps)
        return _Stream(_clock_stream(rules), gate)
    if name == "recorder/progress":
        return _Stream(_progress_stream(rules), None)
    if name == "identifier/estimates":
        if not rules.identifier:
            return _Stream(_never("no identifier in this run"), None)
        return _Stream(_estimate_stream(rules), None)
    return None


class _Recorded(NamedTuple):
    type_name: str
    data: bytes
    stranger: str = ""  #: who published it, if a stranger (its channel's)


def recorded_by_topic(bag_dir: Path) -> dict[str, list[_Recorded]]:
    """Every message of a bag per topic, in the order the recorder wrote them.

    Topics in order of first message (log time). Within a topic the order is
    the channel's sequence number: the recorder's arrival order, which is
    what a gate must see. The log times are no such order: the recorder logs
    a message at its stamp (simulation time), so a junk message stamped in
    the past would sort before the real one it follows.
    """
    by_topic: dict[str, list[RawMessage]] = {}
    for m in read_raw(Path(bag_dir)):  # log-time order: topics in order of first message
        by_topic.setdefault(m.topic, []).append(m)
    return {
        topic: [
            _Recorded(m.type_name, m.data, m.stranger) for m in sorted(ms, key=lambda m: m.sequence)
        ]
        for topic, ms in by_topic.items()
    }


def read_streams(bag_dir: Path, rules: StreamRules) -> BagStreams:
    """The validated messages of every topic of a bag, in recording order.

    Each message of a topic with rules (:func:`stream_for`) is decoded,
    checked and offered to its topic's gate in the order the recorder got
    them (:func:`recorded_by_topic`); what fails is dropped and counted.
    Topics without rules are only counted; a message that repeats one
    already kept (:class:`Repeated`) is counted in ``repeated``; a
    stranger's message (on a stranger's channel) in ``strangers``.
    """
    kept: dict[str, list[Kept]] = {}
    dropped: dict[str, int] = {}
    repeated: dict[str, int] = {}
    reasons: dict[str, str] = {}
    counts: dict[str, int] = {}
    strangers: dict[str, int] = {}
    recorded = recorded_by_topic(Path(bag_dir))
    origin = None
    if rules.plant_clock:
        states = [
            m
            for t, ms in recorded.items()
            if table_name(t) == "state"
            for m in ms
            if not m.stranger
        ]
        origin = plant_clock_steps(states, rules)
    for topic, messages in recorded.items():
        counts[topic] = len(messages)
        others = sum(1 for m in messages if m.stranger)
        if others:
            strangers[topic] = others
        name = table_name(topic)
        stream = stream_for(name, rules, origin) if name is not None else None
        if stream is None or name is None:
            continue
        kept[topic], dropped[topic] = [], 0
        expected = topics.topic(name).type_name
        for m in messages:
            if m.stranger:
                continue
            try:
                if m.type_name and m.type_name != expected:
                    raise SignalError(f"type: expected {expected}, got {m.type_name}")
                step, msg = stream.take(m.data)
            except AfterTheEnd:
                continue
            except Repeated:
                repeated[topic] = repeated.get(topic, 0) + 1
                continue
            except SignalError as err:
                dropped[topic] += 1
                reasons.setdefault(topic, str(err))
                continue
            kept[topic].append(Kept(step, m.data, msg))
    return BagStreams(
        kept=kept,
        dropped=dropped,
        first_reason=reasons,
        counts=counts,
        repeated=repeated,
        strangers=strangers,
    )


def load_signals(
    bag_dir: Path, period_s: float, *, scenario: Resolved | dict[str, Any] | None = None
) -> Signals:
    """Arrays per step from a bag's validated samples (state, reference, command, deformation), faults, counts.

    Parameters
    ----------
    bag_dir : Path
        The bag directory.
    period_s : float
        Control period ``T_u``, s: a message stamped ``t`` is step ``t / T_u``
        (a stamp off that grid is dropped).
    scenario : Resolved, dict or None
        The run's (single-axis) scenario (or it read once), for the rules
        (:class:`StreamRules`); None: the run's ``params.yaml`` beside the
        bag, else the defaults.

    Returns
    -------
    Signals
        The steps common to ``state`` and ``reference``, sorted, with the
        signals at those steps (the deformation ratio too, when the bag has
        its topic); the identifier's estimates in order of step; what was
        dropped (and repeated) per topic.
    """
    rules = StreamRules.for_bag(Path(bag_dir), period_s, scenario)
    streams = read_streams(Path(bag_dir), rules)
    state = {k.step: (k.msg.encoder_rad, k.msg.scale_m) for k in streams.by_table_name("state")}
    ref = {
        k.step: (k.msg.position_rad, k.msg.torque_Nm) for k in streams.by_table_name("reference")
    }
    cmd = {k.step: k.msg.torque_Nm for k in streams.by_table_name("command")}
    faults = []
    for k in streams.by_table_name("fault"):
        step, code, value = k.msg
        faults.append(
            FaultRecord(step=int(step), code=int(code), name=FAULT_NAMES[int(code)], value=value)
        )
    steps = sorted(set(state) & set(ref))
    estimates = sorted((k.msg for k in streams.by_table_name("identifier/estimates")), key=_step)
    deformation = None
    if any(table_name(topic) == "deformation" for topic in streams.counts):
        deformation = _deformation_trace(streams.by_table_name("deformation"), steps)
    return Signals(
        step=np.array(steps, dtype=int),
        encoder_rad=np.array([state[s][0] for s in steps]),
        scale_m=np.array([state[s][1] for s in steps]),
        reference_rad=np.array([ref[s][0] for s in steps]),
        feedforward_Nm=np.array([ref[s][1] for s in steps]),
        command_Nm=np.array([cmd.get(s, math.nan) for s in steps]),
        faults=faults,
        counts=streams.counts,
        dropped=streams.dropped,
        estimates=tuple(estimates),
        repeated=streams.repeated,
        deformation=deformation,
    )


def _deformation_trace(kept: list[Kept], steps: list[int]) -> DeformationTrace:
    """The kept ``deformation`` samples at ``steps`` (missing ones: 0.0, NaN, NaN, invalid)."""
    by_step = {
        k.step: (
            k.msg.d_r_m_per_rad,
            k.msg.scale_increment_m,
            k.msg.encoder_increment_rad,
            1.0 if k.msg.valid else 0.0,
        )
        for k in kept
    }
    missing = (0.0, math.nan, math.nan, 0.0)
    rows = np.array([by_step.get(s, missing) for s in steps], dtype=float).reshape(-1, 4)
    return DeformationTrace(
        d_r_m_per_rad=rows[:, 0].copy(),
        scale_increment_m=rows[:, 1].copy(),
        encoder_increment_rad=rows[:, 2].copy(),
        valid=rows[:, 3] == 1.0,
    )


def _step(estimate: EstimateData) -> int:
    return estimate.step


def learning_enabled(scenario: Resolved | dict[str, Any]) -> bool:
    """True when the scenario's feedforward generator applies learning corrections."""
    resolved = Resolved.of(scenario)
    return resolved.has("feedforward") and bool(resolved.feedforward.learning.enabled)


def tracking(
    scenario: Resolved | dict[str, Any], scenario_path: Path, sig: Signals
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Target (rad) and controlled output ``y`` (rad) per recorded step.

    ``y`` is the feedback's sensor reading in rad of motor angle
    (:func:`~servo_axis.core.feedback.output.controlled_output`). The target
    is the reference the feedback got, except with learning: then it is the
    original target without the learned correction (the ``r`` of 000 eq. (9)),
    recomputed with the same generator (its term files relative to
    ``scenario_path``).
    """
    resolved = Resolved.of(scenario, scenario_path)
    fb = resolved.feedback
    y = controlled_output(
        fb.sensor,
        encoder_rad=sig.encoder_rad,
        scale_m=sig.scale_m,
        lead_m_per_rad=fb.lead_m_per_rad,
    )
    target = sig.reference_rad
    if learning_enabled(resolved) and sig.step.size:
        values = resolved.feedforward.with_keys({"learning.enabled": False})
        rows = build_generator(values).samples(0, int(sig.step.max()) + 1)
        target = np.array([rows[k][0] for k in sig.step])
    return target, y
