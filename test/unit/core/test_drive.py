"""The drive's torque constant (core/drive.py): current to torque and back."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.core.drive import current_from_torque, torque_from_current


def test_torque_is_k_t_times_current() -> None:
    assert torque_from_current(2.0, torque_constant_Nm_per_A=0.715) == 2.0 * 0.715
    assert current_from_torque(1.43, torque_constant_Nm_per_A=0.715) == 1.43 / 0.715


def test_round_trip_within_rounding_for_floats_and_arrays() -> None:
    rng = np.random.default_rng(24)
    current = rng.uniform(-50.0, 50.0, 10_000)
    for kt in (0.715, 1.0, 0.3):
        torque = torque_from_current(current, torque_constant_Nm_per_A=kt)
        back = current_from_torque(torque, torque_constant_Nm_per_A=kt)
        assert_allclose(back, current, rtol=2.3e-16, atol=0.0)
        # The array form is the float form, element by element (the nodes
        # convert one sample at a time, the plain-call loops sometimes a block).
        one_by_one = [
            current_from_torque(
                torque_from_current(float(c), torque_constant_Nm_per_A=kt),
                torque_constant_Nm_per_A=kt,
            )
            for c in current[:500]
        ]
        assert_array_equal(back[:500], one_by_one)
    # K_T = 1 is exact.
    same = current_from_torque(
        torque_from_current(current, torque_constant_Nm_per_A=1.0), torque_constant_Nm_per_A=1.0
    )
    assert_array_equal(same, current)


def test_a_mismatched_drive_constant_changes_the_current_not_the_torque() -> None:
    # The controller's nominal K_T against the drive's own: the drive turns
    # the torque reference into its own current, so the motor gets the torque
    # asked for and the current differs by K_T,n / K_T,plant.
    tau_ref = torque_from_current(3.0, torque_constant_Nm_per_A=0.715)
    i_drive = current_from_torque(tau_ref, torque_constant_Nm_per_A=0.8)
    assert_allclose(i_drive, 3.0 * 0.715 / 0.8, rtol=1e-15)
    applied = torque_from_current(i_drive, torque_constant_Nm_per_A=0.8)
    assert_allclose(applied, 3.0 * 0.715, rtol=1e-15)
