"""The suite's ``state`` from the ``joint_states`` of ros2_control's ``joint_state_broadcaster``.

When ros2_control drives the axis (the suite's controllers against real or
simulated hardware), the axis's state is what
``joint_state_broadcaster/JointStateBroadcaster`` (ros2_controllers 4.42.1,
Jazzy) publishes on ``joint_states``: one ``sensor_msgs/JointState`` per
controller-manager cycle, stamped with the controller manager's ``now()``;
``name`` = the joints with a position, velocity or effort state interface,
sorted by name (or in the order of its ``joints`` parameter); ``position``,
``velocity`` and ``effort`` each one value per name, NaN where a joint lacks
that interface and before the hardware has a value. The suite's ``state``
has the names ``[<axis>_motor, <axis>_table]`` in that order and a finite
number in every field (:data:`servo_axis.wire.layouts.STATE`).

:func:`axis_state` maps one to the other by joint name; :class:`BridgeStream`
decides which messages become states (stamps strictly increasing, as
:class:`servo_axis.wire.streams.StampOrigin` requires). The node is
:mod:`servo_axis.nodes.joint_state_bridge`.

Which field is used by whom: the feedback, the learning unit and the
identifier read the positions (encoder angle, linear scale), the analysis
the positions and, for ``command_source: drive_setpoint`` only, the motor
effort; no node reads the velocities. So a NaN is replaced as follows (each
value the broadcaster gives finite is passed as it is):

* motor position NaN: not a state yet (the hardware has no value); skipped;
* table position NaN or no table joint (a motor-only axis, or a table joint
  with no position interface): ``lead_m_per_rad`` times the motor position,
  the rigid screw ``x = R theta``;
* motor velocity NaN: 0.0; table velocity NaN: ``lead_m_per_rad`` times the
  motor velocity;
* motor effort NaN: the torque the suite last commanded (what a forward
  effort controller holds), 0.0 before any; table effort (friction force)
  NaN: 0.0.

Nothing here imports rclpy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from servo_axis.core.errors import SignalError, require_positive

__all__ = ["AxisState", "BridgeStream", "JointStates", "axis_state"]


class JointStates(Protocol):
    """What :func:`axis_state` reads of a JointState (an rclpy message or a
    :class:`servo_axis.wire.cdr.JointStateData`)."""

    @property
    def name(self) -> Sequence[str]: ...
    @property
    def position(self) -> Sequence[float]: ...
    @property
    def velocity(self) -> Sequence[float]: ...
    @property
    def effort(self) -> Sequence[float]: ...


@dataclass(frozen=True)
class AxisState:
    """One state of the axis in the suite's layout (``state``), every value finite.

    ``position`` = [encoder angle (rad), scale (m)], ``velocity`` = [rad/s,
    m/s], ``effort`` = [motor torque (N m), friction force at the table (N)],
    in the order of the names ``[<axis>_motor, <axis>_table]``.
    """

    position: tuple[float, float]
    velocity: tuple[float, float]
    effort: tuple[float, float]


def _value(msg: JointStates, field: str, index: int | None) -> float:
    values = getattr(msg, field)
    if index is None or len(values) == 0:
        return math.nan
    value = float(values[index])
    if math.isinf(value):
        raise SignalError(
            f"{field}[{index}] ({msg.name[index]!r}): expected a finite number or NaN, got {value!r}"
        )
    return value


def axis_state(
    msg: JointStates, *, axis: str, lead_m_per_rad: float, held_torque_Nm: float = 0.0
) -> AxisState | None:
    """The suite's state of a broadcaster's message, by joint name; None: no state yet.

    Parameters
    ----------
    msg : JointStates
        The broadcaster's message: any joint order, other joints ignored,
        each of ``position``, ``velocity``, ``effort`` empty or one value per
        name, NaN for "no such interface" or "no value yet".
    axis : str
        The axis name: the joints ``<axis>_motor`` (required) and
        ``<axis>_table`` (optional).
    lead_m_per_rad : float
        Ball-screw lead R (m/rad), > 0: the table's position and velocity
        when the message has none (``x = R theta``).
    held_torque_Nm : float
        The motor effort when the message has none (N m, finite): the torque
        last commanded.

    Returns
    -------
    AxisState or None
        None while the motor's position is NaN (the hardware has no value).

    Raises
    ------
    SignalError
        No ``<axis>_motor`` in ``name``; an array neither empty nor one value
        per name; a value that is +-inf.
    """
    require_positive("lead_m_per_rad", lead_m_per_rad)
    names = list(msg.name)
    motor, table = f"{axis}_motor", f"{axis}_table"
    if motor not in names:
        raise SignalError(
            f"name: no joint {motor!r} (the axis's motor) in {names}; the broadcaster must "
            f"publish it (a joint of the <ros2_control> tag with a position state interface)"
        )
    for field in ("position", "velocity", "effort"):
        n = len(getattr(msg, field))
        if n not in (0, len(names)):
            raise SignalError(f"{field}: expected 0 or {len(names)} values (one per name), got {n}")
    m = names.index(motor)
    t = names.index(table) if table in names else None
    angle = _value(msg, "position", m)
    if math.isnan(angle):
        return None
    scale = _value(msg, "position", t)
    speed = _value(msg, "velocity", m)
    speed = 0.0 if math.isnan(speed) else speed
    table_speed = _value(msg, "velocity", t)
    torque = _value(msg, "effort", m)
    force = _value(msg, "effort", t)
    return AxisState(
        position=(angle, lead_m_per_rad * angle if math.isnan(scale) else scale),
        velocity=(speed, lead_m_per_rad * speed if math.isnan(table_speed) else table_speed),
        effort=(
            float(held_torque_Nm) if math.isnan(torque) else torque,
            0.0 if math.isnan(force) else force,
        ),
    )


class BridgeStream:
    """Which broadcaster messages become states: stamps strictly increasing.

    The suite numbers the states of a plant that owns its clock in arrival
    order and refuses a stamp not after the previous one
    (:class:`servo_axis.wire.streams.StampOrigin`); the broadcaster stamps
    with the controller manager's ``now()``, which a system clock stepped
    back (or a reader that got a message twice) could repeat. Such a
    message is dropped here and counted, not sent to be refused.
    """

    def __init__(self) -> None:
        self.last_ns: int | None = None
        #: Messages taken, and dropped: stamp not after the last, no value yet.
        self.taken = 0
        self.out_of_order = 0
        self.no_value = 0

    def take(self, stamp_ns: int, state: AxisState | None) -> bool:
        """Whether a message stamped ``stamp_ns`` (ns) with ``state`` becomes a state."""
        if state is None:
            self.no_value += 1
            return False
        if self.last_ns is not None and stamp_ns <= self.last_ns:
            self.out_of_order += 1
            return False
        self.last_ns = stamp_ns
        self.taken += 1
        return True
