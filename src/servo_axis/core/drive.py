"""The drive's torque constant: current (A) to motor torque (N m) and back.

The wire carries torques (REP 103: a JointState ``effort`` is N m for a
revolute joint): the controllers compute a current reference ``i`` (A) and
publish the motor torque reference ``tau = K_T i`` with their nominal
``K_T`` (``nominal.torque_constant_Nm_per_A``); the drive (the plant)
turns it back into its current reference ``i = tau / K_T`` with its own
``K_T`` (the plant's ``torque_constant_Nm_per_A``) and saturates that on its
current limit. With equal constants the two conversions cancel up to float
rounding (every shipped scenario). A nominal constant that differs from the
plant's acts like a mis-set constant in the drive's set-point scaling: the
motor still gets the torque the controller asked for (the plant turns it
into its own current), but the current the drive draws is ``K_T,n /
K_T,plant`` times the one the controller computed, so the current limit
bites at the torque ``K_T,plant * limit``; before the wire carried torques
the same mismatch was a gain error of ``K_T,plant / K_T,n`` on the torque.

These two functions are the one place where the conversion is written, used
by the nodes and by the plain-call loops of :mod:`servo_axis.simulate`, so
that both compute the same floats bit for bit. Both take a float or an
array (elementwise, the same IEEE operation). The constants are checked
where they are read (> 0, :mod:`servo_axis.params.schemas`); nothing is
checked here, on the per-sample path.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

_T = TypeVar("_T", float, NDArray[np.float64])


def torque_from_current(current_A: _T, *, torque_constant_Nm_per_A: float) -> _T:
    """Motor torque ``K_T i`` of a current.

    Parameters
    ----------
    current_A : float or ndarray
        Current (reference), A.
    torque_constant_Nm_per_A : float
        ``K_T``, N m/A (> 0).

    Returns
    -------
    float or ndarray
        The torque, N m (same shape as ``current_A``).
    """
    return current_A * torque_constant_Nm_per_A


def current_from_torque(torque_Nm: _T, *, torque_constant_Nm_per_A: float) -> _T:
    """Current ``tau / K_T`` that gives a motor torque.

    Parameters
    ----------
    torque_Nm : float or ndarray
        Motor torque (reference), N m.
    torque_constant_Nm_per_A : float
        ``K_T``, N m/A (> 0).

    Returns
    -------
    float or ndarray
        The current, A (same shape as ``torque_Nm``).
    """
    return torque_Nm / torque_constant_Nm_per_A
