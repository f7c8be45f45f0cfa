"""S-ILC relearns after a reference reversed against the one it learned (paper 001, Sect. IV-B).

The 001 scenario ``pilc_ref_change_silc`` with a Ref. 2 of the opposite
direction (-3 mm: the move goes out in -x and returns in +x), run by the
plain-call loop (:func:`servo_axis.simulate.simulate_learning`, which the
node graph reproduces exactly) for 20 trials, against the same Ref. 2
learned from trial 1. The mechanism (``servo_axis.core.learning.ilc``): a
trial starts from the rest its predecessor left, so the learned input at
rest must hold the friction of the last move, ``+-T_c / K_T``; Ref. 2
reversed flips it, and S-ILC must learn the flip once and then start every
trial where the last one ended.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import yaml
from numpy.testing import assert_allclose

from servo_axis.params.scenario import load_scenario
from servo_axis.simulate import simulate_learning

CONFIG = Path(__file__).resolve().parents[2] / "config"
N = 1000  # samples per trial (1 s at 1 ms)


def _variant(
    tmp_path: Path, name: str, reference: dict[str, list[float | int]], trials: int
) -> Path:
    data = load_scenario(CONFIG / "pilc_ref_change_silc.yaml")
    # One trial more than learned from: the last one is not (simulate_learning).
    data["/**"]["ros__parameters"]["duration_s"] = float(trials + 1)
    data["feedforward"]["ros__parameters"]["reference"].update(reference)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _run(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """RMS error (m), the error and the learned input (A) per trial, and T_c / K_T (A)."""
    data = load_scenario(path)
    plant = data["plant"]["ros__parameters"]
    kt = data["/**"]["ros__parameters"]["nominal"]["torque_constant_Nm_per_A"]
    run = simulate_learning(path)
    e = run.error_m
    f = run.trajectory.feedforward_Nm[: e.size].reshape(e.shape) / kt
    hold = plant["friction"]["rolling_coulomb_Nm"] / plant["torque_constant_Nm_per_A"]
    return np.sqrt(np.mean(e**2, axis=1)), e, f, hold


def test_silc_relearns_a_reversed_reference_like_one_learned_from_scratch(tmp_path: Path) -> None:
    reversed_ref = _variant(tmp_path, "reversed", {"amplitudes_m": [0.002, -0.003]}, 20)
    scratch = _variant(
        tmp_path,
        "scratch",
        {
            "amplitudes_m": [-0.003],
            "move_times_s": [0.5],
            "start_times_s": [0.2],
            "first_trials": [1],
        },
        15,
    )
    rms, e, f, hold = _run(reversed_ref)
    rms_new, _, f_new, _ = _run(scratch)
    assert rms.size == 20 and rms_new.size == 15
    # At rest after a move the friction sits at its Coulomb level against that
    # move; the learned input holds it: -T_c/K_T after Ref. 1 (its return is in
    # -x), +T_c/K_T once Ref. 2 reversed is learned (its return is in +x).
    assert_allclose(f[2:5, -1], -hold, rtol=0.01)
    assert_allclose(f[6:, -1], hold, rtol=0.01)
    assert_allclose(f_new[2:, -1], hold, rtol=0.01)
    # Every trial starts where the last one ended (the premise of eq. (4)-(6)).
    for prev, nxt in itertools.pairwise(f):
        assert abs(nxt[0] - prev[-1]) < 1e-3 * hold
    # So the axis stays at rest before the move (Ref. 2 starts at 0.2 s; L's
    # preview reaches back 50 ms): within two encoder counts (0.011 um each).
    count = 2.0 * np.pi / 2**20 * 1.91e-3
    assert np.max(np.abs(e[9:, :150])) <= 2.0 * count * (1.0 + 1e-9)
    # S-ILC starts over at the first trial of Ref. 2 (not better than no
    # learning at all) ...
    assert rms[5] > 0.8 * rms_new[0]
    # ... then falls trial after trial (eq. (6), (7): 0.25 on the plant's
    # rigid part) to the limit of eq. (6), which does not depend on where the
    # learning started: the same after 14 trials of Ref. 2 either way.
    assert all(b < a for a, b in itertools.pairwise(rms[5:17]))
    assert_allclose(rms[19], rms_new[14], rtol=0.03)
    assert rms[19] < 0.05 * rms[5]
