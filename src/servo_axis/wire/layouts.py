"""Every topic's layout, declared once: the table the conversions are derived from.

Only ``sensor_msgs/JointState``, ``std_msgs/Float64MultiArray`` and
``rosgraph_msgs/Clock`` cross the wire. This module says, for every
JointState and Float64MultiArray topic of :mod:`servo_axis.wire.topics`,
which value goes where, in SI units (REP 103), and what a valid value is:

* a :class:`JointLayout` names the joints of the axis (``<axis>_motor``,
  ``<axis>_table``) and, per array (``position``, ``velocity``, ``effort``),
  the field of its sample dataclass each joint's value is (the unit is in
  the field's name). The message is stamped with its control sample
  ``k * T_u``; the step is recovered from the stamp exactly.
* an :class:`ArrayLayout` lists the :class:`Field` s of a labelled
  Float64MultiArray: one ``MultiArrayDimension`` per field, ``label`` = the
  field with its unit, ``size`` = its number of values, ``stride`` = ``size``,
  in order; a vector that belongs to a step carries that step as its first
  field, ``step``. Each field has a rule (real, whole >= a minimum, flag 0/1,
  >= 0, > 0) that every decoder applies.

From this table :mod:`servo_axis.wire.messages` derives the rclpy
conversions (pure functions, one template per publisher),
:mod:`servo_axis.wire.streams` the decoding of recorded payloads
(:mod:`servo_axis.wire.cdr`) and :mod:`servo_axis.analysis.signals` the
reader of a bag: a JointState, an rclpy message or a decoded payload alike,
is checked and turned into the same sample by :meth:`JointLayout.decode`, a
Float64MultiArray by :meth:`ArrayLayout.values`. Every refusal is a
:class:`~servo_axis.core.errors.SignalError` naming what is wrong. Nothing
here imports rclpy.
"""

from __future__ import annotations

import dataclasses
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from servo_axis.core.errors import SignalError
from servo_axis.wire import topics
from servo_axis.wire.checks import check_finite, check_labelled_values, step_of_stamp_ns

S = TypeVar("S")

# -- the samples ---------------------------------------------------------------


@dataclass(frozen=True)
class StateSample:
    """Plant state at control sample ``step`` (topic ``state``).

    JointState names ``[<axis>_motor, <axis>_table]``: ``position`` = sensor
    readings (encoder rad, scale m); ``velocity`` = true velocities (rad/s,
    m/s); ``effort`` = [motor torque applied (N m), friction force at the
    table (N) = friction torque / R].
    """

    step: int
    encoder_rad: float
    scale_m: float
    velocity_rad_s: float
    velocity_m_s: float
    motor_torque_Nm: float
    friction_force_N: float


@dataclass(frozen=True)
class CommandSample:
    """Motor torque reference for control sample ``step`` (topic ``command``).

    JointState name ``[<axis>_motor]``, ``effort`` = [motor torque reference
    ``K_T,n i_ref`` (N m)]: the feedback's current reference times the
    nominal torque constant; the plant turns it back into its current
    reference with its own ``K_T`` (:mod:`servo_axis.core.drive`).
    """

    step: int
    torque_Nm: float


@dataclass(frozen=True)
class ReferenceSample:
    """Feedforward for control sample ``step`` (topic ``reference``).

    JointState name ``[<axis>_motor]``: ``position`` = motor-angle reference
    for the feedback (rad; with PTC the nominal output trajectory),
    ``velocity`` = its velocity (rad/s), ``effort`` = feedforward torque
    ``K_T,n u_ff`` (N m): the generator's feedforward current times the
    nominal torque constant, which the feedback turns back into a current
    (:mod:`servo_axis.core.drive`).
    """

    step: int
    position_rad: float
    velocity_rad_s: float
    torque_Nm: float


@dataclass(frozen=True)
class CorrectionSample:
    """Learning correction of the target at a reference instant (topic ``learning/correction``).

    JointState name ``[<axis>_motor]``, stamped with the instant it applies
    to: ``position`` = correction of the target angle (rad), ``velocity`` =
    its velocity (rad/s).
    """

    step: int
    position_rad: float
    velocity_rad_s: float


@dataclass(frozen=True)
class InputCorrectionSample:
    """Learned feedforward torque at a control sample (topic ``learning/input_correction``).

    JointState name ``[<axis>_motor]``, stamped with the control sample it
    applies to: ``effort`` = torque ``K_T,n f`` (N m) of the current ``f_{j+1}``
    (A) of paper 001 eq. (3)/(11) that the law adds to the control input; the
    feedforward generator turns it back into a current
    (:mod:`servo_axis.core.drive`).
    """

    step: int
    torque_Nm: float


@dataclass(frozen=True)
class DeformationSample:
    """The deformation ratio at control sample ``step`` (topic ``deformation``, 004 eqs. (5)-(7)).

    ``d_r_m_per_rad`` (m/rad; 0 where not defined), ``scale_increment_m``
    (``x_t[k] - x_t[k-p]``, m), ``encoder_increment_rad`` (``th_m[k] -
    th_m[k-p]``, rad) and ``valid`` (``d_r`` is defined; 1/0 on the wire).
    """

    step: int
    d_r_m_per_rad: float
    scale_increment_m: float
    encoder_increment_rad: float
    valid: bool


@dataclass(frozen=True)
class EstimateData:
    """One online estimate of the identifier (topic ``identifier/estimates``).

    Attributes
    ----------
    step : int
        The last control sample the estimate was computed from (>= 0).
    applies_from_step : int
        The first control sample whose feedforward uses it (> ``step``).
    inertia_kgm2, damping_Nms_per_rad, unbalance_Nm, coulomb_Nm : float
        ``J`` (> 0), ``D``, ``U``, ``C`` (>= 0) of 003 eq. (2).
    kappa : float
        PE index of 003 eq. (7) (0 until its window is full).
    updated : tuple of 4 bool
        Whether ``J``, ``D``, ``U`` (eq. (16)) and ``C`` (eq. (8)) were updated.
    """

    step: int
    applies_from_step: int
    inertia_kgm2: float
    damping_Nms_per_rad: float
    unbalance_Nm: float
    coulomb_Nm: float
    kappa: float
    updated: tuple[bool, bool, bool, bool]

    def values(self) -> list[float]:
        """The message's data, in the order of :data:`ESTIMATES`' fields."""
        return [
            float(self.step),
            float(self.applies_from_step),
            self.inertia_kgm2,
            self.damping_Nms_per_rad,
            self.unbalance_Nm,
            self.coulomb_Nm,
            self.kappa,
            *(1.0 if u else 0.0 for u in self.updated),
        ]


# -- the two kinds of layout ---------------------------------------------------


@dataclass(frozen=True, eq=False)
class JointLayout(Generic[S]):
    """A JointState topic: the joints, and the sample field of each value.

    Parameters
    ----------
    topic : str
        The topic's name in :data:`servo_axis.wire.topics.TOPICS`.
    sample : type
        The frozen dataclass of a sample: ``step`` then the fields below, in
        the order ``position``, ``velocity``, ``effort`` (checked).
    joints : tuple of str
        Joint name suffixes: the names are ``<axis>_<joint>``.
    position, velocity, effort : tuple of str
        Per array, the sample field of each joint's value (empty: the topic
        leaves the array empty). An array in use holds one finite value per
        joint.
    """

    topic: str
    sample: Callable[..., S]
    joints: tuple[str, ...]
    position: tuple[str, ...] = ()
    velocity: tuple[str, ...] = ()
    effort: tuple[str, ...] = ()
    #: The JointState arrays the topic uses, in message order.
    arrays: tuple[str, ...] = field(init=False)
    #: The sample's fields after ``step``: array by array, joint by joint.
    values: tuple[str, ...] = field(init=False)
    _names: dict[str, list[str]] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        arrays = tuple(a for a in ("position", "velocity", "effort") if getattr(self, a))
        object.__setattr__(self, "arrays", arrays)
        object.__setattr__(self, "values", (*self.position, *self.velocity, *self.effort))
        declared = ["step", *self.values]
        have = [f.name for f in dataclasses.fields(self.sample)]  # type: ignore[arg-type]
        if have != declared:
            raise TypeError(f"{self.topic}: sample fields {have} differ from the layout {declared}")
        for array in self.arrays:
            if len(getattr(self, array)) != len(self.joints):
                raise TypeError(f"{self.topic}: {array} needs one field per joint {self.joints}")

    def names(self, axis: str) -> list[str]:
        """The joint names on the axis ``axis`` (``[x_motor, x_table]``); do not modify."""
        names = self._names.get(axis)
        if names is None:
            names = self._names[axis] = [f"{axis}_{j}" for j in self.joints]
        return names

    def value_getter(self) -> Callable[[Any], tuple[float, ...]]:
        """A function that gives a sample's values (not the step) in message order."""
        names = self.values
        if len(names) == 1:
            (only,) = names
            return lambda sample: (getattr(sample, only),)
        getter: Callable[[Any], tuple[float, ...]] = operator.attrgetter(*names)
        return getter

    def decode(self, name: Sequence[str], msg: Any, stamp_ns: int, axis: str, period_ns: int) -> S:
        """The sample of a JointState, after the checks every subscriber makes.

        Parameters
        ----------
        name : sequence of str
            The message's joint names.
        msg : object
            The message (rclpy or :class:`servo_axis.wire.cdr.JointStateData`):
            its arrays are read by name.
        stamp_ns : int
            Its ``header.stamp`` in ns.
        axis : str
            The axis of the joint names.
        period_ns : int
            Control period ``T_u``, ns: the stamp must be a whole number of them.

        Raises
        ------
        SignalError
            Naming the first thing wrong: the joint names, an array's length,
            a value that is not finite, the stamp off the control grid.
        """
        return self.sample(step_of_stamp_ns(stamp_ns, period_ns), *self._values(name, msg, axis))

    def step(self, name: Sequence[str], msg: Any, stamp_ns: int, axis: str, period_ns: int) -> int:
        """The step of a JointState after the checks of :meth:`decode` (no sample is built)."""
        self._values(name, msg, axis)
        return step_of_stamp_ns(stamp_ns, period_ns)

    def _values(self, name: Sequence[str], msg: Any, axis: str) -> list[float]:
        """The values of the arrays in use, after checking the names, lengths and finiteness."""
        names = self._names.get(axis) or self.names(axis)
        if list(name) != names:
            raise SignalError(f"name: expected {names}, got {list(name)}")
        values: list[float] = []
        n = len(names)
        for array in self.arrays:
            got = getattr(msg, array)
            if len(got) != n:
                raise SignalError(f"{array}: expected {n} values, got {len(got)}")
            values += check_finite(array, got)
        return values


#: The rules a :class:`Field`'s value obeys.
RULES = ("real", "whole", "flag", "nonnegative", "positive")


@dataclass(frozen=True)
class Field:
    """One field of a labelled Float64MultiArray.

    Parameters
    ----------
    name : str
        The field's name with its unit (``rms_m``): its label, the sample's
        attribute, the name an error gives.
    rule : str
        What a value must be besides finite (:data:`RULES`): ``real``
        (anything), ``whole`` (a whole number >= ``minimum``), ``flag`` (0 or
        1), ``nonnegative`` (>= 0), ``positive`` (> 0).
    minimum : int
        The smallest whole number (rule ``whole``).
    size : int or None
        Number of values; None: a segment of any length (no rule applies).
    label : str
        The label on the wire when it says more than the name; "" for the name.
    """

    name: str
    rule: str = "real"
    minimum: int = 0
    size: int | None = 1
    label: str = ""

    def __post_init__(self) -> None:
        if self.rule not in RULES:
            raise ValueError(f"{self.name}: rule {self.rule!r} is not one of {RULES}")

    @property
    def wire_label(self) -> str:
        """``layout.dim[i].label`` of the field."""
        return self.label or self.name

    def check(self, value: float) -> None:
        """Raise :class:`SignalError` naming the field if ``value`` breaks its rule."""
        rule = self.rule
        if rule == "whole":
            if not float(value).is_integer() or value < self.minimum:
                raise SignalError(
                    f"{self.name}: expected a whole number >= {self.minimum}, got {value!r}"
                )
        elif rule == "flag":
            if value not in (0.0, 1.0):
                raise SignalError(f"{self.name}: expected 0 or 1, got {value!r}")
        elif rule == "nonnegative":
            if value < 0.0:
                raise SignalError(f"{self.name}: expected a value >= 0, got {value!r}")
        elif rule == "positive" and not value > 0.0:
            raise SignalError(f"{self.name}: expected a value > 0, got {value!r}")


_CONVERT: dict[str, Callable[[float], Any]] = {"whole": int, "flag": lambda v: v == 1.0}


@dataclass(frozen=True, eq=False)
class ArrayLayout(Generic[S]):
    """A labelled Float64MultiArray topic: its fields, in order.

    Parameters
    ----------
    topic : str
        The topic's name in :data:`servo_axis.wire.topics.TOPICS`.
    fields : tuple of Field
        The fields, one dimension each.
    sample : type or None
        A frozen dataclass with one attribute per field (checked) that
        :meth:`sample_of` builds (``whole`` fields int, ``flag`` fields
        bool); None: the topic is read as its list of values.
    per_step : bool
        One message per control step, the step its first field (a stream
        the recorder may count).
    """

    topic: str
    fields: tuple[Field, ...]
    sample: Callable[..., S] | None = None
    per_step: bool = False
    #: The fields' names.
    names: tuple[str, ...] = field(init=False)
    #: The labels of the dimensions, in order.
    labels: tuple[str, ...] = field(init=False)
    #: The size of each field (None: a segment of any length).
    sizes: tuple[int | None, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "names", tuple(f.name for f in self.fields))
        object.__setattr__(self, "labels", tuple(f.wire_label for f in self.fields))
        object.__setattr__(self, "sizes", tuple(f.size for f in self.fields))
        if self.sample is not None:
            have = [f.name for f in dataclasses.fields(self.sample)]  # type: ignore[arg-type]
            if have != [f.name for f in self.fields]:
                raise TypeError(f"{self.topic}: sample fields {have} differ from {self.names}")
        if self.per_step and self.fields[0].name != "step":
            raise TypeError(f"{self.topic}: a per-step vector carries the step first")

    def values(
        self,
        dim_labels: Sequence[str],
        dim_sizes: Sequence[int],
        data: Sequence[float],
        dim_strides: Sequence[int] | None = None,
    ) -> list[float]:
        """The data of a message after checking its layout and every field's rule.

        Parameters
        ----------
        dim_labels, dim_sizes, dim_strides : sequence
            ``layout.dim[i].label``, ``.size`` and ``.stride`` (None: strides
            not checked).
        data : sequence of float
            ``data``.

        Raises
        ------
        SignalError
            Naming what is wrong (:func:`~servo_axis.wire.checks.check_labelled_values`,
            then the first field whose rule a value breaks).
        """
        values = check_labelled_values(
            dim_labels, dim_sizes, data, self.labels, dim_strides=dim_strides, sizes=self.sizes
        )
        offset = 0
        for f, n in zip(self.fields, dim_sizes, strict=True):
            if f.size == 1:
                f.check(values[offset])
            offset += n
        return values

    def checked(self, values: Sequence[float]) -> list[float]:
        """``values`` of a layout of scalars (no message) after the count, finiteness and rules."""
        if len(values) != len(self.fields):
            raise SignalError(f"data: expected {len(self.fields)} values, got {len(values)}")
        check_finite("data", values)
        out = [float(v) for v in values]
        for f, v in zip(self.fields, out, strict=True):
            f.check(v)
        return out

    def sample_of(self, values: Sequence[float]) -> S:
        """The :attr:`sample` of checked values (``whole`` fields int, ``flag`` fields bool)."""
        if self.sample is None:
            raise TypeError(f"{self.topic} has no sample class")
        return self.sample(
            *(_CONVERT.get(f.rule, float)(v) for f, v in zip(self.fields, values, strict=True))
        )

    def values_of(self, sample: Any) -> list[float]:
        """The data of a sample, in field order (a bool flag as 1.0/0.0)."""
        return [float(getattr(sample, name)) for name in self.names]


# -- the table ---------------------------------------------------------------

STATE = JointLayout(
    "state",
    StateSample,
    joints=("motor", "table"),
    position=("encoder_rad", "scale_m"),
    velocity=("velocity_rad_s", "velocity_m_s"),
    effort=("motor_torque_Nm", "friction_force_N"),
)
COMMAND = JointLayout("command", CommandSample, joints=("motor",), effort=("torque_Nm",))
REFERENCE = JointLayout(
    "reference",
    ReferenceSample,
    joints=("motor",),
    position=("position_rad",),
    velocity=("velocity_rad_s",),
    effort=("torque_Nm",),
)
CORRECTION = JointLayout(
    "learning/correction",
    CorrectionSample,
    joints=("motor",),
    position=("position_rad",),
    velocity=("velocity_rad_s",),
)
INPUT_CORRECTION = JointLayout(
    "learning/input_correction", InputCorrectionSample, joints=("motor",), effort=("torque_Nm",)
)

_STEP = Field("step", "whole")

STATUS: ArrayLayout[Any] = ArrayLayout(
    "plant/status",
    (
        _STEP,
        Field("deadline_misses", "whole"),
        Field("rejected_commands", "whole"),
        Field("command_timeouts", "whole"),
    ),
)
PROGRESS: ArrayLayout[Any] = ArrayLayout("recorder/progress", (Field("steps_recorded", "whole"),))
FAULT: ArrayLayout[Any] = ArrayLayout(
    "fault",
    (
        _STEP,
        Field("code", "whole", label="code(1=following_error;2=travel;3=current;4=input_timeout)"),
        Field("value", label="value(m_or_A_or_s)"),
    ),
)
CYCLE_STATS: ArrayLayout[Any] = ArrayLayout(
    "learning/cycle_stats",
    (
        Field("cycle", "whole", minimum=1),
        Field("rms_m", "nonnegative"),
        Field("max_m", "nonnegative"),
        Field("cycles_learned", "whole"),
    ),
)
#: 004 eqs. (5)-(7): the control step, ``d_r`` (0 where not defined), the
#: scale's increment ``x_t[k] - x_t[k-p]``, the encoder's ``th_m[k] - th_m[k-p]``
#: and whether ``d_r`` is defined (1/0).
DEFORMATION = ArrayLayout(
    "deformation",
    (
        _STEP,
        Field("d_r_m_per_rad"),
        Field("scale_increment_m"),
        Field("encoder_increment_rad"),
        Field("valid", "flag"),
    ),
    sample=DeformationSample,
    per_step=True,
)
#: The last control sample the estimate was computed from, the first it
#: applies to (after ``step``: :func:`check_estimate_values`), ``J, D, U, C``
#: (003 eq. (2)), the PE index of eq. (7) (an eigenvalue: a rounding below 0
#: passes) and whether each parameter was updated at this RLS step (1/0).
ESTIMATES: ArrayLayout[Any] = ArrayLayout(
    "identifier/estimates",
    (
        _STEP,
        Field("applies_from_step"),
        Field("inertia_kgm2", "positive"),
        Field("damping_Nms_per_rad", "nonnegative"),
        Field("unbalance_Nm", "nonnegative"),
        Field("coulomb_Nm", "nonnegative"),
        Field("kappa"),
        Field("updated_inertia", "flag"),
        Field("updated_damping", "flag"),
        Field("updated_unbalance", "flag"),
        Field("updated_coulomb", "flag"),
    ),
)
#: The trial whose data gave them, then what a projection-based law
#: identified (001 eq. (14b) in SI units).
PARAMETERS: ArrayLayout[Any] = ArrayLayout(
    "learning/parameters",
    (
        Field("trial", "whole", minimum=1),
        Field("inertia_kgm2"),
        Field("damping_Nms_per_rad"),
        Field("coulomb_Nm"),
    ),
)
#: A friction table (001 Fig. 8): the trial, then two segments of one value
#: per displacement (:func:`check_friction_table`).
FRICTION_TABLE: ArrayLayout[Any] = ArrayLayout(
    "learning/friction_table",
    (Field("trial", "whole", minimum=1), Field("x_r_m", size=None), Field("torque_Nm", size=None)),
)

#: Every JointState and Float64MultiArray topic's layout, by topic name.
LAYOUTS: dict[str, JointLayout[Any] | ArrayLayout[Any]] = {
    layout.topic: layout
    for layout in (
        STATE,
        COMMAND,
        REFERENCE,
        CORRECTION,
        INPUT_CORRECTION,
        STATUS,
        PROGRESS,
        FAULT,
        CYCLE_STATS,
        DEFORMATION,
        ESTIMATES,
        PARAMETERS,
        FRICTION_TABLE,
    )
}


def _check_table() -> None:
    """Each layout's topic is in the topic table with the layout's type, and each topic has one."""
    for entry in topics.TOPICS:
        layout = LAYOUTS.get(entry.name)
        want = {topics.JOINT_STATE: JointLayout, topics.FLOAT64_MULTI_ARRAY: ArrayLayout}
        kind = want.get(entry.type_name)
        if (kind is None) != (layout is None) or (kind and not isinstance(layout, kind)):
            raise TypeError(f"topic {entry.name!r} ({entry.type_name}): layout {layout!r}")
    missing = set(LAYOUTS) - set(topics.BY_NAME)
    if missing:
        raise TypeError(f"layouts of topics not in the topic table: {sorted(missing)}")


_check_table()

#: The JointState layouts of per-sample streams, by topic.
JOINT_LAYOUTS: dict[str, JointLayout[Any]] = {
    name: layout for name, layout in LAYOUTS.items() if isinstance(layout, JointLayout)
}


# -- the rules across fields -------------------------------------------------


def check_estimate_values(values: Sequence[float]) -> EstimateData:
    """An :class:`EstimateData` of the values of an ``identifier/estimates`` message.

    The values are in :data:`ESTIMATES`' order (its :meth:`ArrayLayout.values`
    checks a message's layout); each field's rule, then ``applies_from_step``
    a whole number after ``step``.

    Raises
    ------
    SignalError
        A wrong count, a value that is not finite, a step that is not whole
        and >= 0, ``J <= 0``, a negative ``D``, ``U`` or ``C``, a flag not 0
        or 1, or an application step not after the step.
    """
    v = ESTIMATES.checked(values)
    step, applies = int(v[0]), v[1]
    if applies != int(applies) or applies <= step:
        raise SignalError(
            f"applies_from_step: expected a whole number after step {step}, got {applies!r}"
        )
    return EstimateData(
        step=step,
        applies_from_step=int(applies),
        inertia_kgm2=v[2],
        damping_Nms_per_rad=v[3],
        unbalance_Nm=v[4],
        coulomb_Nm=v[5],
        kappa=v[6],
        updated=(v[7] == 1.0, v[8] == 1.0, v[9] == 1.0, v[10] == 1.0),
    )


def check_friction_table(
    dim_labels: Sequence[str],
    dim_sizes: Sequence[int],
    data: Sequence[float],
    dim_strides: Sequence[int] | None = None,
) -> tuple[int, list[float], list[float]]:
    """``(trial, x_r_m, torque_Nm)`` of a ``learning/friction_table`` message, checked.

    Raises
    ------
    SignalError
        As :meth:`ArrayLayout.values` of :data:`FRICTION_TABLE`, or for
        columns of different lengths.
    """
    values = FRICTION_TABLE.values(dim_labels, dim_sizes, data, dim_strides)
    n, n_torque = dim_sizes[1], dim_sizes[2]
    if n != n_torque:
        raise SignalError(
            f"layout.dim 'torque_Nm': expected size {n} (one per x_r_m), got {n_torque}"
        )
    return int(values[0]), values[1 : 1 + n], values[1 + n :]


def state_names(axis: str) -> list[str]:
    """Joint names of the ``state`` topic: ``[<axis>_motor, <axis>_table]``."""
    return list(STATE.names(axis))


def motor_names(axis: str) -> list[str]:
    """Joint names of the ``command``, ``reference`` and ``learning/*correction`` topics."""
    return list(COMMAND.names(axis))
