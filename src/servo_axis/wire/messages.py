"""Conversions between wire messages and plain samples: pure functions.

Only ``sensor_msgs/JointState``, ``std_msgs/Float64MultiArray`` and
``rosgraph_msgs/Clock`` cross the wire (docs/design.md section 3). Every per-sample signal
is a JointState whose ``header.stamp`` is the sample's simulation time
``k * T_u``; the step ``k`` is recovered from the stamp exactly (integer
nanoseconds). A JointState carries only what it defines, in SI units (REP
103): ``position`` (rad, m), ``velocity`` (rad/s, m/s), ``effort`` (N m for
the motor joint, N for the table); the current references of the
controllers travel as motor torque references ``K_T i``
(:mod:`servo_axis.core.drive`). What is not a joint state travels as a
Float64MultiArray with one ``MultiArrayDimension`` per field (``label`` =
the field with its unit, ``size`` = its number of values, ``stride`` =
``size``: :func:`labelled_array`); a vector that belongs to a step carries
that step as its first field, ``step``.

Decoders validate: names, lengths, finiteness and the stamp grid. They raise
:class:`servo_axis.core.errors.SignalError` naming what is wrong. The checks
themselves are pure functions of :mod:`servo_axis.wire.cdr` (no rclpy), which
the analysis applies to the payloads of a bag: one rule for both.
"""

from __future__ import annotations

import array
import struct
from collections.abc import Sequence
from dataclasses import dataclass

from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from servo_axis.core.errors import SignalError

# The labels and joint names are defined beside the pure checks (wire.cdr) and
# re-exported here, where the nodes take them from.
from servo_axis.wire.cdr import DEFORMATION_LABELS as DEFORMATION_LABELS
from servo_axis.wire.cdr import ESTIMATE_LABELS as ESTIMATE_LABELS
from servo_axis.wire.cdr import FAULT_LABELS as FAULT_LABELS
from servo_axis.wire.cdr import PROGRESS_LABELS as PROGRESS_LABELS
from servo_axis.wire.cdr import STATS_LABELS as STATS_LABELS
from servo_axis.wire.cdr import STATUS_LABELS as STATUS_LABELS
from servo_axis.wire.cdr import EstimateData as EstimateData
from servo_axis.wire.cdr import (
    check_deformation_values,
    check_estimate_values,
    check_finite,
    check_joint_arrays,
    check_labelled_values,
    step_of_stamp_ns,
)
from servo_axis.wire.cdr import motor_names as motor_names
from servo_axis.wire.cdr import state_names as state_names

NS_PER_S = 1_000_000_000


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


def clock_message(step: int, period_ns_: int) -> Clock:
    """``/clock`` message for control sample ``step``."""
    return Clock(clock=stamp_from_step(step, period_ns_))


_finite = check_finite


def _check_joint_state(
    msg: JointState, names: Sequence[str], fields: Sequence[str], period_ns_: int
) -> int:
    check_joint_arrays(msg.name, names, ((f, getattr(msg, f)) for f in fields))
    return step_from_stamp(msg.header.stamp, period_ns_)


def joint_state_template(names: Sequence[str], fields: Sequence[str]) -> JointState:
    """A JointState with ``names`` and zeroed ``fields`` of matching length, to be filled."""
    msg = JointState()
    msg.name = list(names)
    for field in fields:
        setattr(msg, field, array.array("d", [0.0] * len(names)))
    return msg


def _fill(msg: JointState, step: int, period_ns_: int, **fields: Sequence[float]) -> JointState:
    """Write stamp and values into a template in place (no message construction)."""
    ns = step * period_ns_
    stamp = msg.header.stamp
    stamp.sec = ns // NS_PER_S
    stamp.nanosec = ns % NS_PER_S
    for field, values in fields.items():
        getattr(msg, field)[:] = array.array("d", _finite(field, values))
    return msg


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


def state_to_msg(sample: StateSample, *, axis: str, period_ns_: int) -> JointState:
    """Encode a :class:`StateSample`."""
    template = joint_state_template(state_names(axis), ("position", "velocity", "effort"))
    return write_state(template, sample, period_ns_=period_ns_)


def write_state(msg: JointState, sample: StateSample, *, period_ns_: int) -> JointState:
    """Fill a template from :func:`state_to_msg` with ``sample`` (publisher reuse)."""
    return _fill(
        msg,
        sample.step,
        period_ns_,
        position=(sample.encoder_rad, sample.scale_m),
        velocity=(sample.velocity_rad_s, sample.velocity_m_s),
        effort=(sample.motor_torque_Nm, sample.friction_force_N),
    )


def state_from_msg(msg: JointState, *, axis: str, period_ns_: int) -> StateSample:
    """Decode and validate a ``state`` message."""
    step = _check_joint_state(
        msg, state_names(axis), ("position", "velocity", "effort"), period_ns_
    )
    return StateSample(
        step=step,
        encoder_rad=msg.position[0],
        scale_m=msg.position[1],
        velocity_rad_s=msg.velocity[0],
        velocity_m_s=msg.velocity[1],
        motor_torque_Nm=msg.effort[0],
        friction_force_N=msg.effort[1],
    )


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


def command_to_msg(sample: CommandSample, *, axis: str, period_ns_: int) -> JointState:
    """Encode a :class:`CommandSample`."""
    template = joint_state_template(motor_names(axis), ("effort",))
    return write_command(template, sample, period_ns_=period_ns_)


def write_command(msg: JointState, sample: CommandSample, *, period_ns_: int) -> JointState:
    """Fill a template from :func:`command_to_msg` with ``sample`` (publisher reuse)."""
    return _fill(msg, sample.step, period_ns_, effort=(sample.torque_Nm,))


def command_from_msg(msg: JointState, *, axis: str, period_ns_: int) -> CommandSample:
    """Decode and validate a ``command`` message."""
    step = _check_joint_state(msg, motor_names(axis), ("effort",), period_ns_)
    return CommandSample(step=step, torque_Nm=msg.effort[0])


@dataclass(frozen=True)
class DeformationSample:
    """The deformation ratio at control sample ``step`` (topic ``deformation``, 004 eqs. (5)-(7)).

    A Float64MultiArray of the fields :data:`DEFORMATION_LABELS`: ``step``,
    ``d_r_m_per_rad`` (m/rad; 0 where not defined), ``scale_increment_m``
    (``x_t[k] - x_t[k-p]``, m), ``encoder_increment_rad`` (``th_m[k] -
    th_m[k-p]``, rad) and ``valid`` (1 where ``d_r`` is defined, else 0).
    """

    step: int
    d_r_m_per_rad: float
    scale_increment_m: float
    encoder_increment_rad: float
    valid: bool


def deformation_to_msg(sample: DeformationSample) -> Float64MultiArray:
    """Encode a :class:`DeformationSample`."""
    template = labelled_array(DEFORMATION_LABELS, [0.0] * len(DEFORMATION_LABELS))
    return write_deformation(template, sample)


def write_deformation(msg: Float64MultiArray, sample: DeformationSample) -> Float64MultiArray:
    """Fill a template from :func:`deformation_to_msg` with ``sample`` (publisher reuse)."""
    values = (
        float(sample.step),
        sample.d_r_m_per_rad,
        sample.scale_increment_m,
        sample.encoder_increment_rad,
        1.0 if sample.valid else 0.0,
    )
    msg.data[:] = array.array("d", _finite("data", values))
    return msg


def deformation_from_msg(msg: Float64MultiArray) -> DeformationSample:
    """Decode and validate a ``deformation`` message (layout, finiteness, step, valid 0/1)."""
    values = labelled_array_values(msg, DEFORMATION_LABELS)
    step = check_deformation_values(values)
    return DeformationSample(
        step=step,
        d_r_m_per_rad=values[1],
        scale_increment_m=values[2],
        encoder_increment_rad=values[3],
        valid=values[4] == 1.0,
    )


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


def reference_to_msg(sample: ReferenceSample, *, axis: str, period_ns_: int) -> JointState:
    """Encode a :class:`ReferenceSample`."""
    template = joint_state_template(motor_names(axis), ("position", "velocity", "effort"))
    return write_reference(template, sample, period_ns_=period_ns_)


def write_reference(msg: JointState, sample: ReferenceSample, *, period_ns_: int) -> JointState:
    """Fill a template from :func:`reference_to_msg` with ``sample`` (publisher reuse)."""
    return _fill(
        msg,
        sample.step,
        period_ns_,
        position=(sample.position_rad,),
        velocity=(sample.velocity_rad_s,),
        effort=(sample.torque_Nm,),
    )


def reference_from_msg(msg: JointState, *, axis: str, period_ns_: int) -> ReferenceSample:
    """Decode and validate a ``reference`` message."""
    step = _check_joint_state(
        msg, motor_names(axis), ("position", "velocity", "effort"), period_ns_
    )
    return ReferenceSample(
        step=step,
        position_rad=msg.position[0],
        velocity_rad_s=msg.velocity[0],
        torque_Nm=msg.effort[0],
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
    msg.data = [float(v) for v in _finite("data", values)]
    return msg


def labelled_array_values(
    msg: Float64MultiArray, labels: Sequence[str], *, sizes: Sequence[int | None] | None = None
) -> list[float]:
    """Values of a :func:`labelled_array` message after checking its layout.

    ``sizes`` as in :func:`servo_axis.wire.cdr.check_labelled_values` (None:
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


def write_correction(msg: JointState, sample: CorrectionSample, *, period_ns_: int) -> JointState:
    """Fill a template from :func:`correction_to_msg` with ``sample`` (publisher reuse)."""
    return _fill(
        msg,
        sample.step,
        period_ns_,
        position=(sample.position_rad,),
        velocity=(sample.velocity_rad_s,),
    )


def correction_to_msg(sample: CorrectionSample, *, axis: str, period_ns_: int) -> JointState:
    """Encode a :class:`CorrectionSample`."""
    template = joint_state_template(motor_names(axis), ("position", "velocity"))
    return write_correction(template, sample, period_ns_=period_ns_)


def correction_from_msg(msg: JointState, *, axis: str, period_ns_: int) -> CorrectionSample:
    """Decode and validate a ``learning/correction`` message."""
    step = _check_joint_state(msg, motor_names(axis), ("position", "velocity"), period_ns_)
    return CorrectionSample(step=step, position_rad=msg.position[0], velocity_rad_s=msg.velocity[0])


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


def write_input_correction(
    msg: JointState, sample: InputCorrectionSample, *, period_ns_: int
) -> JointState:
    """Fill a template from :func:`input_correction_to_msg` with ``sample`` (publisher reuse)."""
    return _fill(msg, sample.step, period_ns_, effort=(sample.torque_Nm,))


def input_correction_to_msg(
    sample: InputCorrectionSample, *, axis: str, period_ns_: int
) -> JointState:
    """Encode an :class:`InputCorrectionSample`."""
    template = joint_state_template(motor_names(axis), ("effort",))
    return write_input_correction(template, sample, period_ns_=period_ns_)


def input_correction_from_msg(
    msg: JointState, *, axis: str, period_ns_: int
) -> InputCorrectionSample:
    """Decode and validate a ``learning/input_correction`` message."""
    step = _check_joint_state(msg, motor_names(axis), ("effort",), period_ns_)
    return InputCorrectionSample(step=step, torque_Nm=msg.effort[0])


def estimate_to_msg(estimate: EstimateData) -> Float64MultiArray:
    """Encode an online estimate (topic ``identifier/estimates``, :data:`ESTIMATE_LABELS`)."""
    return labelled_array(ESTIMATE_LABELS, estimate.values())


def estimate_from_msg(msg: Float64MultiArray) -> EstimateData:
    """Decode and validate an ``identifier/estimates`` message (:func:`check_estimate_values`)."""
    return check_estimate_values(labelled_array_values(msg, ESTIMATE_LABELS))


#: ``learning/parameters``: the trial whose data gave them, then what a
#: projection-based law identified (001 eq. (14b) in SI units).
PARAMETER_LABELS = ("trial", "inertia_kgm2", "damping_Nms_per_rad", "coulomb_Nm")

#: ``learning/friction_table``: three labelled segments, one after the other.
FRICTION_TABLE_LABELS = ("trial", "x_r_m", "torque_Nm")


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
    data = labelled_array_values(msg, FRICTION_TABLE_LABELS, sizes=(1, None, None))
    n, n_torque = msg.layout.dim[1].size, msg.layout.dim[2].size
    if n != n_torque:
        raise SignalError(
            f"layout.dim 'torque_Nm': expected size {n} (one per x_r_m), got {n_torque}"
        )
    trial = data[0]
    if trial != int(trial) or trial < 1:
        raise SignalError(f"trial: expected a whole number >= 1, got {trial!r}")
    return int(trial), data[1 : 1 + n], data[1 + n :]
