"""A drive's set-point from a ``JointState`` command of ros2_control's topic-based hardware.

With ``command_source: drive_setpoint`` (realtime) the plant is the hardware
behind ``joint_state_topic_hardware_interface/JointStateTopicSystem``
(Jazzy release 1.1.0): the plugin publishes, at the controller manager's
rate, a ``sensor_msgs/JointState`` whose ``name`` is every joint of its
``<ros2_control>`` tag in tag order and whose ``effort`` holds one value per
joint *with an effort command interface*, in tag order (so ``effort[k]`` is
not ``name[k]`` when a state-only joint comes first). It stamps the message
with its own clock and fills a command a controller has not written yet
with NaN. :func:`setpoint_torque` reads the motor torque out of such a
message (or of one with one ``effort`` per name, the suite's own layout).

Nothing here imports rclpy.
"""

from __future__ import annotations

import math

from servo_axis.core.errors import SignalError
from servo_axis.wire.cdr import JointStateData


def setpoint_torque(msg: JointStateData, *, motor: str) -> float:
    """The motor torque set-point (N m) of a command message, NaN for "no command yet".

    Parameters
    ----------
    msg : JointStateData
        The decoded message (:func:`servo_axis.wire.cdr.decode_joint_state`);
        its stamp and ``frame_id`` are not read (a drive's set-point holds
        until the next one, whatever its stamp).
    motor : str
        The axis's driven joint, ``<axis>_motor``.

    Returns
    -------
    float
        ``effort`` of ``motor``: by name when ``effort`` has one value per
        name; the only value when it has one (the axis has one actuated
        joint: the one joint of the tag with an effort command interface).
        NaN: the plugin's "no command yet" (the caller holds its set-point).

    Raises
    ------
    SignalError
        ``motor`` missing from ``name``; ``effort`` empty (only the effort
        command interface is taken: a position or velocity command would
        need the drive's own inner loops) or of another length; a value
        that is +-inf.
    """
    if motor not in msg.name:
        raise SignalError(
            f"name: no joint {motor!r} (the axis's driven joint) in {list(msg.name)}; "
            f"name the motor joint {motor!r} in the <ros2_control> tag"
        )
    effort = msg.effort
    if not effort:
        given = [f for f in ("position", "velocity") if getattr(msg, f)]
        raise SignalError(
            f"effort: expected the motor torque (N m) of {motor!r}, got no effort value"
            + (
                f" (only {' and '.join(given)}: declare an effort command interface)"
                if given
                else ""
            )
        )
    if len(effort) == len(msg.name):
        value = effort[msg.name.index(motor)]
    elif len(effort) == 1:
        value = effort[0]
    else:
        raise SignalError(
            f"effort: expected one value per name ({len(msg.name)}) or one (the motor's), "
            f"got {len(effort)}: only {motor!r} may have an effort command interface"
        )
    if math.isinf(value):
        raise SignalError(f"effort of {motor!r}: expected a finite torque or NaN, got {value!r}")
    return float(value)
