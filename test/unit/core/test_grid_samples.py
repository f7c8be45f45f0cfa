"""The adaptive feedforward's shortcuts give the numbers of the code they shortcut.

``GridSamples`` keeps a reference's samples on the control grid, computed a
chunk at a time: each must be the number ``reference.sample`` gives for the
same time in a short block, as the generator and the MNC formed them. The
PTC's ``_expm_upper`` runs the Pade core of ``scipy.linalg.expm`` for the
model's upper triangular matrix: it must be ``expm``'s result to the bit.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from servo_axis.core.feedforward.ptc import _expm_upper
from servo_axis.core.reference import (
    GridSamples,
    OneMinusCosReference,
    PointToPointReference,
    Reference,
    SegmentsReference,
    SineReference,
)

REFERENCES: dict[str, Reference] = {
    "sine_ramped": SineReference(amplitude_m=0.3, frequency_hz=1.3, phase_rad=0.2, ramp_s=0.7),
    "sine": SineReference(amplitude_m=0.01, frequency_hz=2.0, offset_m=0.1),
    "one_minus_cos": OneMinusCosReference(amplitude_m=0.025, frequency_hz=1.0),
    "point_to_point": PointToPointReference(distance_m=0.05, move_time_s=0.3, dwell_s=0.1),
    "segments": SegmentsReference(distances_m=(0.02, -0.01), durations_s=(0.2, 0.3), delay_s=0.05),
}


@pytest.mark.parametrize("name", sorted(REFERENCES))
def test_grid_samples_are_the_block_samples(name: str) -> None:
    reference = REFERENCES[name]
    tu = 4e-4
    grid = GridSamples(reference, tu, chunk=97)
    k0 = 0
    rng = np.random.default_rng(3)
    while k0 < 3000:
        k1 = k0 + int(rng.integers(1, 40))
        want = reference.sample(np.arange(k0, k1) * tu)
        got = grid.range(k0, k1)
        for a, b in zip(got, want, strict=True):
            assert a.tobytes() == np.asarray(b, dtype=float).tobytes()
        want2 = reference.sample(np.arange(k0, k1 + 1, 2) * tu)
        got2 = grid.range(k0, k1 + 1, 2)
        for a, b in zip(got2, want2, strict=True):
            assert a.tobytes() == np.asarray(b, dtype=float).tobytes()
        at = np.arange(k0, k1) + np.arange(k0, k1) % 2
        got3 = grid.steps(at)
        want3 = reference.sample(at * tu)
        for a, b in zip(got3, want3, strict=True):
            assert a.tobytes() == np.asarray(b, dtype=float).tobytes()
        k0 = k1


def test_grid_samples_go_back_and_keep_fresh_arrays() -> None:
    reference = REFERENCES["sine_ramped"]
    grid = GridSamples(reference, 1e-3, chunk=16)
    late = grid.range(100, 110)
    early = grid.range(3, 9)
    late[0][:] = 0.0  # a caller's array is its own
    for a, b in zip(
        grid.range(100, 110), reference.sample(np.arange(100, 110) * 1e-3), strict=True
    ):
        assert a.tolist() == b.tolist()
    for a, b in zip(early, reference.sample(np.arange(3, 9) * 1e-3), strict=True):
        assert a.tolist() == b.tolist()


def test_expm_upper_is_scipy_expm() -> None:
    rng = np.random.default_rng(0)
    for _ in range(5000):
        j = 10 ** rng.uniform(-6, 0)
        d = 10 ** rng.uniform(-6, 1) * float(rng.integers(0, 2))
        kt = 10 ** rng.uniform(-2, 1)
        tu = 10 ** rng.uniform(-5, -2)
        m = np.zeros((3, 3))
        m[0, 1] = 1.0
        m[1, 1] = -d / j
        m[1, 2] = kt / j
        got, want = _expm_upper(m * tu), scipy.linalg.expm(m * tu)
        assert got.tobytes() == want.tobytes()
