"""Conversions between wire messages and plain samples: pure functions.

Only ``sensor_msgs/JointState``, ``std_msgs/Float64MultiArray`` and
``rosgraph_msgs/Clock`` cross the wire (docs/design.md section 3). Which value
of which topic goes where, in which unit, and what a valid value is, is
declared once in :mod:`servo_axis.wire.layouts`; the conversions here are
derived from it. A per-sample signal is a JointState stamped with the
sample's simulation time ``k * T_u``; the step ``k`` is recovered from the
stamp exactly (integer nanoseconds). What is not a joint state travels as a
labelled Float64MultiArray (:func:`labelled_array`).

Per topic ``<t>`` of a JointState layout: ``<t>_to_msg(sample, axis=,
period_ns_=)`` builds a message, ``write_<t>(msg, sample, period_ns_=)`` fills
the template of a publisher in place (no message construction per sample)
and ``<t>_from_msg(msg, axis=, period_ns_=)`` decodes and validates one
(:meth:`~servo_axis.wire.layouts.JointLayout.decode`: names, lengths,
finiteness and the stamp grid, with the code the analysis applies to the
payloads of a bag). Decoders raise :class:`servo_axis.core.errors.SignalError`
naming what is wrong.
"""

from __future__ import annotations

import array
import struct
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from servo_axis.core.errors import SignalError
from servo_axis.wire import layouts
from servo_axis.wire.checks import check_finite, check_labelled_values, step_of_stamp_ns

# The samples and the joint names are declared with the layouts (no rclpy) and
# re-exported here, where the nodes take them from.
from servo_axis.wire.layouts import CommandSample as CommandSample
from servo_axis.wire.layouts import CorrectionSample as CorrectionSample
from servo_axis.wire.layouts import DeformationSample as DeformationSample
from servo_axis.wire.layouts import EstimateData as EstimateData
from servo_axis.wire.layouts import InputCorrectionSample as InputCorrectionSample
from servo_axis.wire.layouts import ReferenceSample as ReferenceSample
from servo_axis.wire.layouts import StateSample as StateSample
from servo_axis.wire.layouts import check_estimate_values as check_estimate_values
from servo_axis.wire.layouts import motor_names as motor_names
from servo_axis.wire.layouts import state_names as state_names
from servo_axis.wire.sample_cdr import ArrayCodec, JointCodec

#: The labels of each labelled Float64MultiArray topic (its layout's).
STATUS_LABELS = layouts.STATUS.labels
PROGRESS_LABELS = layouts.PROGRESS.labels
FAULT_LABELS = layouts.FAULT.labels
STATS_LABELS = layouts.CYCLE_STATS.labels
DEFORMATION_LABELS = layouts.DEFORMATION.labels
ESTIMATE_LABELS = layouts.ESTIMATES.labels
PARAMETER_LABELS = layouts.PARAMETERS.labels
FRICTION_TABLE_LABELS = layouts.FRICTION_TABLE.labels

NS_PER_S = 1_000_000_000

S = TypeVar("S")


def period_ns(period_s: float) -> int:
    """Control period in whole nanoseconds (raises if it is not whole)."""
    ns = round(period_s * NS_PER_S)
    if ns <= 0 or abs(ns - period_s * NS_PER_S) > 1e-3:
        raise SignalError(f"period_s: expected a whole number of nanoseconds > 0, got {period_s!r}")
    return ns


def stamp_from_step(step: int, period_ns_: int) -> Time:
    """``builtin_interfaces/Time`` of control sample ``step``."""
    ns = step * period_ns_
    return Time(sec=ns // NS_PER_S, nanosec=ns % NS_PER_S)


def step_from_stamp(stamp: Time, period_ns_: int) -> int:
    """Control sample index of ``stamp``; raises if it is off the grid."""
    return step_of_stamp_ns(stamp.sec * NS_PER_S + stamp.nanosec, period_ns_)


def stamp_ns_from_cdr(data: bytes) -> int:
    """``header.stamp`` (ns) of a CDR-serialised message that starts with a ``std_msgs/Header``.

    Reads the two stamp fields right after the 4-byte encapsulation header
    (CDR, either byte order) without deserialising the message: a node that
    needs only some samples of a stream can skip the others cheaply.
    """
    if len(data) < 12 or data[0] != 0 or data[1] not in (0, 1):
        raise SignalError("data: expected a CDR-encapsulated message with a header")
    sec, nanosec = struct.unpack_from("<iI" if data[1] == 1 else ">iI", data, 4)
    if not 0 <= nanosec < NS_PER_S:
        raise SignalError(f"header.stamp.nanosec: expected 0..999999999, got {nanosec}")
    return sec * NS_PER_S + nanosec


def joint_codec(topic: str, *, axis: str, period_ns_: int) -> JointCodec[Any]:
    """The CDR codec of JointState topic ``topic`` on ``axis`` (:class:`~servo_axis.wire.sample_cdr.JointCodec`).

    What the per-sample path publishes (``publish(codec.encode(sample))``,
    the same bytes as the message of ``<topic>_to_msg``) and decodes from a
    ``raw=True`` subscription (``codec.decode(data)``, the checks of
    ``<topic>_from_msg``).
    """
    return JointCodec(layouts.JOINT_LAYOUTS[topic], axis=axis, period_ns=period_ns_)


def array_codec(topic: str) -> ArrayCodec[Any]:
    """The CDR codec of per-sample vector topic ``topic`` (:class:`~servo_axis.wire.sample_cdr.ArrayCodec`).

    ``publish(codec.encode(sample))`` sends the message of ``<topic>_to_msg``.
    """
    layout = layouts.LAYOUTS[topic]
    if not isinstance(layout, layouts.ArrayLayout):
        raise SignalError(f"topic: {topic!r} is not a Float64MultiArray topic")
    return ArrayCodec(layout)


def clock_message(step: int, period_ns_: int) -> Clock:
    """``/clock`` message for control sample ``step``."""
    return Clock(clock=stamp_from_step(step, period_ns_))


def joint_state_template(names: Sequence[str], fields: Sequence[str]) -> JointState:
    """A JointState with ``names`` and zeroed ``fields`` of matching length, to be filled."""
    msg = JointState()
    msg.name = list(names)
    for field in fields:
        setattr(msg, field, array.array("d", [0.0] * len(names)))
    return msg


def _joint_conversions(
    layout: layouts.JointLayout[S],
) -> tuple[Callable[..., JointState], Callable[..., JointState], Callable[..., S]]:
    """``(to_msg, write, from_msg)`` of a JointState layout."""
    arrays = layout.arrays
    n = len(layout.joints)
    spans = tuple((a, i * n, (i + 1) * n) for i, a in enumerate(arrays))
    values_of = layout.value_getter()
    decode = layout.decode
    double = array.array

    def write(msg: JointState, sample: Any, *, period_ns_: int) -> JointState:
        ns = sample.step * period_ns_
        stamp = msg.header.stamp
        stamp.sec = ns // NS_PER_S
        stamp.nanosec = ns % NS_PER_S
        values = values_of(sample)
        for name, lo, hi in spans:
            getattr(msg, name)[:] = double("d", check_finite(name, values[lo:hi]))
        return msg

    def to_msg(sample: Any, *, axis: str, period_ns_: int) -> JointState:
        return write(
            joint_state_template(layout.names(axis), arrays), sample, period_ns_=period_ns_
        )

    def from_msg(msg: JointState, *, axis: str, period_ns_: int) -> S:
        stamp = msg.header.stamp
        return decode(msg.name, msg, stamp.sec * NS_PER_S + stamp.nanosec, axis, period_ns_)

    topic, sample_name = layout.topic, layout.sample.__name__  # type: ignore[attr-defined]
    to_msg.__doc__ = f"Encode a :class:`{sample_name}` (topic ``{topic}``)."
    write.__doc__ = (
        f"Fill a template of ``{topic}`` with a :class:`{sample_name}` (publisher reuse)."
    )
    from_msg.__doc__ = f"Decode and validate a ``{topic}`` message into a :class:`{sample_name}`."
    return to_msg, write, from_msg


state_to_msg, write_state, state_from_msg = _joint_conversions(layouts.STATE)
command_to_msg, write_command, command_from_msg = _joint_conversions(layouts.COMMAND)
reference_to_msg, write_reference, reference_from_msg = _joint_conversions(layouts.REFERENCE)
correction_to_msg, write_correction, correction_from_msg = _joint_conversions(layouts.CORRECTION)
input_correction_to_msg, write_input_correction, input_correction_from_msg = _joint_conversions(
    layouts.INPUT_CORRECTION
)


def deformation_to_msg(sample: DeformationSample) -> Float64MultiArray:
    """Encode a :class:`DeformationSample` (topic ``deformation``)."""
    return labelled_array(DEFORMATION_LABELS, layouts.DEFORMATION.values_of(sample))


def write_deformation(msg: Float64MultiArray, sample: DeformationSample) -> Float64MultiArray:
    """Fill a template from :func:`deformation_to_msg` with ``sample`` (publisher reuse)."""
    msg.data[:] = array.array("d", check_finite("data", layouts.DEFORMATION.values_of(sample)))
    return msg


def deformation_from_msg(msg: Float64MultiArray) -> DeformationSample:
    """Decode and validate a ``deformation`` message (layout, finiteness, each field's rule)."""
    sample: DeformationSample = layouts.DEFORMATION.sample_of(_values(msg, layouts.DEFORMATION))
    return sample


def _values(msg: Float64MultiArray, layout: layouts.ArrayLayout[Any]) -> list[float]:
    """The checked data of a message of ``layout`` (:meth:`~servo_axis.wire.layouts.ArrayLayout.values`)."""
    dims = list(msg.layout.dim)
    return layout.values(
        [d.label for d in dims], [d.size for d in dims], msg.data, [d.stride for d in dims]
    )


def labelled_array(
    labels: Sequence[str], values: Sequence[float], *, sizes: Sequence[int] | None = None
) -> Float64MultiArray:
    """Float64MultiArray with one dimension per field: ``label``, ``size``, ``stride`` = ``size``.

    Parameters
    ----------
    labels : sequence of str
        The fields, in order, each named with its unit (``step``, ``rms_m``).
    values : sequence of float
        The data: the fields' values one after the other.
    sizes : sequence of int or None
        The number of values of each field (a segment has several); None:
        one each.

    Raises
    ------
    SignalError
        For an empty, repeated or comma-separated label, sizes that do not
        match the labels or add up to ``len(values)``, or a value that is
        not finite.
    """
    counts = [1] * len(labels) if sizes is None else [int(n) for n in sizes]
    if len(counts) != len(labels):
        raise SignalError(f"sizes: expected one size per label {list(labels)}, got {counts}")
    for label in labels:
        if not label or "," in label:
            raise SignalError(f"labels: expected non-empty labels without commas, got {label!r}")
    if len(set(labels)) != len(labels):
        raise SignalError(f"labels: expected distinct labels, got {list(labels)}")
    if any(n < 0 for n in counts) or sum(counts) != len(values):
        raise SignalError(
            f"values: expected {sum(counts)} values (sizes {counts} of {list(labels)}), "
            f"got {len(values)}"
        )
    msg = Float64MultiArray()
    msg.layout.dim = [
        MultiArrayDimension(label=label, size=n, stride=n)
        for label, n in zip(labels, counts, strict=True)
    ]
    msg.data = [float(v) for v in check_finite("data", values)]
    return msg


def labelled_array_values(
    msg: Float64MultiArray, labels: Sequence[str], *, sizes: Sequence[int | None] | None = None
) -> list[float]:
    """Values of a :func:`labelled_array` message after checking its layout.

    ``sizes`` as in :func:`servo_axis.wire.checks.check_labelled_values` (None:
    every field a scalar; an entry None: a segment of any length).
    """
    dims = list(msg.layout.dim)
    return check_labelled_values(
        [d.label for d in dims],
        [d.size for d in dims],
        msg.data,
        labels,
        dim_strides=[d.stride for d in dims],
        sizes=sizes,
    )


def estimate_to_msg(estimate: EstimateData) -> Float64MultiArray:
    """Encode an online estimate (topic ``identifier/estimates``, :data:`ESTIMATE_LABELS`)."""
    return labelled_array(ESTIMATE_LABELS, estimate.values())


def estimate_from_msg(msg: Float64MultiArray) -> EstimateData:
    """Decode and validate an ``identifier/estimates`` message (:func:`check_estimate_values`)."""
    return check_estimate_values(_values(msg, layouts.ESTIMATES))


def friction_table_to_msg(
    trial: int, x_r_m: Sequence[float], torque_Nm: Sequence[float]
) -> Float64MultiArray:
    """A friction table (001 Fig. 8) as ``[trial, x_r_m..., torque_Nm...]`` with one dimension per segment.

    Raises
    ------
    SignalError
        If the two columns differ in length or hold NaN/inf.
    """
    x = [float(v) for v in x_r_m]
    t = [float(v) for v in torque_Nm]
    if len(x) != len(t):
        raise SignalError(f"torque_Nm: expected {len(x)} values (one per x_r_m), got {len(t)}")
    check_finite("x_r_m", x)
    check_finite("torque_Nm", t)
    return labelled_array(FRICTION_TABLE_LABELS, [float(trial), *x, *t], sizes=(1, len(x), len(t)))


def friction_table_from_msg(msg: Float64MultiArray) -> tuple[int, list[float], list[float]]:
    """``(trial, x_r_m, torque_Nm)`` of a :func:`friction_table_to_msg` message, checked."""
    dims = list(msg.layout.dim)
    return layouts.check_friction_table(
        [d.label for d in dims], [d.size for d in dims], msg.data, [d.stride for d in dims]
    )
