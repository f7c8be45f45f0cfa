"""The plain-call loop with a target-side law (RPTC, paper 000): eq. (27) without ROS.

The node graph reproduces :func:`servo_axis.simulate.simulate_learning` bit
for bit (``test/integration/test_learning.py``); here its numbers are held
against the paper's properties on their own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose

from servo_axis.params.scenario import find_scenario
from servo_axis.simulate import simulate, simulate_learning


def cycle_rms(name: str) -> np.ndarray:
    """RMS error (m) of each cycle learned from, and the run's steps."""
    run = simulate_learning(find_scenario(name))
    return np.sqrt(np.mean(run.error_m**2, axis=1))


def test_n_times_filter_equals_n_cycles_of_the_plain_filter_eq27() -> None:
    q3 = cycle_rms("rptc_ideal")  # Q~3
    q1 = cycle_rms("rptc_ideal_q")  # Q
    # Cycle 1 is not learned from (start_cycle 3: the error of cycle 2 is
    # the first learned), so cycles 1-2 are the same loop without learning.
    assert_allclose(q3[:2], q1[:2], rtol=1e-12)
    # Eq. (27): one learning cycle with Q~3 = three with Q (cycle 3 vs 5).
    assert_allclose(q3[2], q1[4], rtol=0.05)
    assert q3[2] < 1e-3 * q3[1]


def test_before_learning_the_loop_is_the_loop_without_learning(tmp_path: Path) -> None:
    import yaml

    from servo_axis.params.resolve import node_values
    from servo_axis.params.scenario import load_scenario

    path = find_scenario("rptc_detailed")
    run = simulate_learning(path)
    data = load_scenario(path)
    start = node_values(data, "learning")["start_cycle"]
    ff = data["feedforward"]["ros__parameters"]
    ff["learning"]["enabled"] = False
    data.pop("learning")
    plain = tmp_path / "plain.yaml"
    plain.write_text(yaml.safe_dump(data, sort_keys=False))
    without = simulate(plain)
    # Until the first correction is used (learned from cycle start_cycle - 1,
    # for cycle start_cycle, needed from that cycle's start minus one
    # reference interval: the boundary protocol), the two loops are the same.
    cycle = len(run.trajectory.encoder_rad) // (len(run.error_m) + 1)
    first_used = (start - 1) * cycle - 2
    np.testing.assert_array_equal(
        run.trajectory.command_Nm[:first_used], without.command_Nm[:first_used]
    )
    # ... and from there they differ.
    assert not np.array_equal(
        run.trajectory.command_Nm[: first_used + 4], without.command_Nm[: first_used + 4]
    )
