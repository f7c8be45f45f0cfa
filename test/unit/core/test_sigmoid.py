"""The sigmoid friction compensation of paper 004 eqs. (8)-(9) and its feedforward term."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from servo_axis.core.errors import ConfigError, SignalError
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.core.feedforward.sigmoid import (
    PAPER_PRESLIDING_M,
    PAPER_SIGMA_M2_PER_RAD,
    SCAN_CHUNK_STEPS,
    SigmoidParams,
    SigmoidTerm,
    estimated_deformation_ratio,
    gamma_for_width,
    sigmoid_torque,
)
from servo_axis.core.feedforward.terms import FeedforwardTerm, ReferenceBlock
from servo_axis.core.models.base import NominalModel
from servo_axis.core.reference import OneMinusCosReference, PointToPointReference, Reference
from servo_axis.core.timing import SampleGrid

TU = 0.5e-3  # s, 004 Sect. II-B
KT = 0.715  # N m/A, 004 Table I
F0 = 0.3  # N m
HALF_WIDTH = PAPER_PRESLIDING_M / 2  # 7.5 um
GAMMA = gamma_for_width(sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, half_width_m=HALF_WIDTH)
PARAMS = SigmoidParams(
    sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, gamma_m_per_rad=GAMMA, coulomb_Nm=F0
)
# 004 Sect. V: 25 (1 - cos 2 pi t) mm, reversals at 0.5 s (top, 50 mm), 1 s (bottom, 0), ...
PAPER_REF = OneMinusCosReference(amplitude_m=0.025, frequency_hz=1.0)


def block_of(reference: Reference, steps: np.ndarray) -> ReferenceBlock:
    pos, vel, acc = reference.sample(steps * TU)
    return ReferenceBlock(
        step=steps.astype(np.int64), position_m=pos, velocity_m_s=vel, acceleration_m_s2=acc
    )


def term_on(reference: Reference, **kwargs: float) -> SigmoidTerm:
    return SigmoidTerm(
        PARAMS, reference=reference, control_period_s=TU, torque_constant_Nm_per_A=KT, **kwargs
    )


def currents_in_blocks(term: FeedforwardTerm, reference: Reference, sizes: list[int]) -> np.ndarray:
    out, start = [], 0
    for size in sizes:
        out.append(term.currents(block_of(reference, np.arange(start, start + size))))
        start += size
    return np.concatenate(out)


# -- the law, eqs. (8)-(9) ------------------------------------------------------


def test_limits_and_symmetry() -> None:
    z = np.array([0.0, 1e-9, 1e-6, 7.5e-6, 1e-4, 1e-2, 1.0, math.inf])
    up = sigmoid_torque(z, 1, PARAMS)
    down = sigmoid_torque(z, -1, PARAMS)
    assert up[0] == 0.0 and down[0] == 0.0  # exactly 0 at the reversal point
    # +F_0 far from the reversal: 1 - 1 / (2 r^2) with r = gamma z / sigma = 2753 at 1 cm.
    assert_allclose(up[-3], F0, rtol=1e-7)
    assert_allclose(up[-2:], F0, rtol=1e-10)
    assert up[-1] == F0
    assert_array_equal(down, -up)  # odd in the direction
    # Through a reversal, against the signed displacement s from it (direction sgn s):
    # odd in s, 0 at s = 0, -F_0 .. +F_0.
    pos = np.linspace(0.0, 50e-6, 1001)[1:]
    s = np.concatenate((-pos[::-1], [0.0], pos))
    f = sigmoid_torque(np.abs(s), np.sign(s), PARAMS)
    assert_array_equal(f, -f[::-1])
    assert f[1000] == 0.0
    # Only the sign of the direction counts (the velocity itself may be passed).
    assert_array_equal(sigmoid_torque(z, 0.37, PARAMS), up)
    assert_array_equal(sigmoid_torque(z, 0.0, PARAMS), 0.0)


def test_eq9_literal_form_with_eq8() -> None:
    z = np.geomspace(1e-9, 1e-1, 200)
    d_r = estimated_deformation_ratio(z, PAPER_SIGMA_M2_PER_RAD)
    assert_allclose(d_r, PAPER_SIGMA_M2_PER_RAD / z, rtol=0.0, atol=0.0)
    q = (GAMMA / d_r) ** 2
    literal = np.sqrt(q / (1.0 + q)) * F0
    assert_allclose(sigmoid_torque(z, 1, PARAMS), literal, rtol=1e-13, atol=0.0)
    with pytest.raises(SignalError, match="z_m"):
        estimated_deformation_ratio(0.0, PAPER_SIGMA_M2_PER_RAD)
    with pytest.raises(SignalError, match="z_m"):
        estimated_deformation_ratio([1e-6, -1e-6], PAPER_SIGMA_M2_PER_RAD)
    with pytest.raises(ConfigError, match="sigma_m2_per_rad"):
        estimated_deformation_ratio(1e-6, 0.0)


def test_switching_width() -> None:
    at_half_width = sigmoid_torque(HALF_WIDTH, 1, PARAMS)
    assert_allclose(at_half_width, 0.9 * F0, rtol=1e-13)
    # Well inside the pre-sliding region the compensation is small.
    inside = sigmoid_torque(np.linspace(0.0, PAPER_PRESLIDING_M / 10, 100), 1, PARAMS)
    assert np.all(inside < 0.5 * F0)
    # Other fractions too.
    for fraction in (0.5, 0.99):
        g = gamma_for_width(
            sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, half_width_m=HALF_WIDTH, fraction=fraction
        )
        p = SigmoidParams(sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, gamma_m_per_rad=g, coulomb_Nm=F0)
        assert_allclose(sigmoid_torque(HALF_WIDTH, -1, p), -fraction * F0, rtol=1e-13)


def test_gamma_for_the_papers_sigma() -> None:
    # In the paper's units: sigma = 0.04 mm^2/rad, w = 7.5e-3 mm, gamma in mm/rad.
    gamma_mm = 0.04 / 7.5e-3 * 0.9 / math.sqrt(1.0 - 0.81)
    print(
        f"gamma = {GAMMA:.6e} m/rad = {GAMMA * 1e3:.4f} mm/rad "
        f"({GAMMA / 1.910e-3:.2f} R) for sigma = 0.04 mm^2/rad, x_s/2 = 7.5 um"
    )
    assert_allclose(GAMMA * 1e3, gamma_mm, rtol=1e-12)
    assert_allclose(GAMMA, 0.0110120, rtol=1e-5)

    # The closed form against a numerical solution of |F_c(w)| = 0.9 F_0.
    def excess(gamma: float) -> float:
        p = SigmoidParams(
            sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, gamma_m_per_rad=gamma, coulomb_Nm=1.0
        )
        return float(sigmoid_torque(HALF_WIDTH, 1, p)) - 0.9

    assert_allclose(brentq(excess, 1e-4, 1.0, xtol=1e-16), GAMMA, rtol=1e-10)


def test_monotonic_in_z() -> None:
    f = sigmoid_torque(np.linspace(0.0, 200e-6, 20_001), 1, PARAMS)
    assert np.all(np.diff(f) > 0.0)
    assert np.all(f < F0)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("sigma_m2_per_rad", 0.0),
        ("sigma_m2_per_rad", -1e-8),
        ("gamma_m_per_rad", 0.0),
        ("gamma_m_per_rad", -0.01),
        ("gamma_m_per_rad", math.nan),
        ("coulomb_Nm", 0.0),
        ("coulomb_Nm", -0.3),
        ("coulomb_Nm", math.inf),
    ],
)
def test_bad_parameters_are_refused_by_name(field: str, value: float) -> None:
    kwargs = {"sigma_m2_per_rad": 4e-8, "gamma_m_per_rad": 0.011, "coulomb_Nm": 0.3}
    kwargs[field] = value
    with pytest.raises(ConfigError, match=field):
        SigmoidParams(**kwargs)


def test_bad_arguments_are_refused_by_name() -> None:
    for kwargs, name in [
        ({"half_width_m": 0.0}, "half_width_m"),
        ({"sigma_m2_per_rad": -1.0}, "sigma_m2_per_rad"),
        ({"fraction": 0.0}, "fraction"),
        ({"fraction": 1.0}, "fraction"),
        ({"fraction": math.nan}, "fraction"),
    ]:
        args = {"sigma_m2_per_rad": 4e-8, "half_width_m": 7.5e-6, "fraction": 0.9}
        args.update(kwargs)
        with pytest.raises(ConfigError, match=name):
            gamma_for_width(**args)
    for kwargs, name in [
        ({"control_period_s": 0.0}, "control_period_s"),
        ({"torque_constant_Nm_per_A": -1.0}, "torque_constant_Nm_per_A"),
        ({"search_horizon_s": 0.0}, "search_horizon_s"),
    ]:
        args = {"control_period_s": TU, "torque_constant_Nm_per_A": KT, "search_horizon_s": 1.0}
        args.update(kwargs)
        with pytest.raises(ConfigError, match=name):
            SigmoidTerm(PARAMS, reference=PAPER_REF, **args)
    with pytest.raises(SignalError, match="z_m"):
        sigmoid_torque([1e-6, -1e-9], 1, PARAMS)
    with pytest.raises(SignalError, match="z_m"):
        sigmoid_torque(math.nan, 1, PARAMS)
    with pytest.raises(SignalError, match="direction"):
        sigmoid_torque(1e-6, math.nan, PARAMS)


# -- the term on the paper's reference -------------------------------------------


def expected_on_paper_ref(steps: np.ndarray) -> np.ndarray:
    """z from the analytic reversals (t = n / 2 s, at 50 mm or 0), direction sgn(v)."""
    t = steps * TU
    x, v, _ = PAPER_REF.sample(t)
    n_prev = np.floor(t / 0.5 + 1e-9)  # reversals at 0.5, 1.0, ...: none before 0.5 s
    x_at = np.where(np.mod(np.arange(0, 100), 2) == 1, 0.05, 0.0)  # x at t = n / 2
    z_next = np.abs(x - x_at[(n_prev + 1).astype(int)])
    z_prev = np.where(n_prev >= 1, np.abs(x - x_at[n_prev.astype(int)]), np.inf)
    z = np.minimum(z_prev, z_next)
    return sigmoid_torque(z, np.sign(v), PARAMS) / KT


def test_term_on_the_papers_reference() -> None:
    n = 4401  # 2.2 s
    steps = np.arange(n)
    term = term_on(PAPER_REF)
    current = term.currents(block_of(PAPER_REF, steps))
    assert current.shape == (n,)

    revs = term.reversals
    assert_allclose([r.time_s for r in revs[:4]], [0.5, 1.0, 1.5, 2.0], rtol=0.0, atol=1e-9)
    assert_allclose([r.position_m for r in revs[:4]], [0.05, 0.0, 0.05, 0.0], rtol=0.0, atol=1e-12)

    # Against z and the direction computed from the analytic reversals.
    assert_allclose(current[1:], expected_on_paper_ref(steps[1:]), rtol=1e-9, atol=1e-9)
    # At rest before the reference first moves (t = 0, v = 0 exactly): no current.
    assert current[0] == 0.0
    # Away from the reversals: the Coulomb level in the direction of motion.
    assert_allclose(current[500], F0 / KT, rtol=1e-7)  # t = 0.25 s, v > 0
    assert_allclose(current[1500], -F0 / KT, rtol=1e-7)  # t = 0.75 s, v < 0

    x = PAPER_REF.sample(steps * TU)[0]
    for rev in revs[:4]:
        k = round(rev.time_s / TU)
        # 0 at the reversal instant, to within the displacement of one sample.
        one_sample = max(abs(x[k] - x[k - 1]), abs(x[k + 1] - x[k]))
        limit = float(sigmoid_torque(one_sample, 1, PARAMS)) / KT
        assert abs(current[k]) <= limit
        # Braking before it: |F_c| below F_0 and falling, in the old direction;
        # rising after it in the new one.
        before = current[k - 40 : k]
        after = current[k + 1 : k + 41]
        old = 1.0 if rev.position_m > 0.025 else -1.0
        assert np.all(np.sign(before) == old) and np.all(np.sign(after) == -old)
        assert np.all(np.diff(np.abs(before)) < 0.0)
        assert np.all(np.diff(np.abs(after)) > 0.0)
        one_ms = abs(current[k - 2])  # 1 ms before
        assert one_ms < 0.5 * F0 / KT
        z_1ms = abs(x[k - 2] - rev.position_m)
        assert_allclose(one_ms, float(sigmoid_torque(z_1ms, 1, PARAMS)) / KT, rtol=1e-9)
        print(
            f"reversal at {rev.time_s:.6f} s: |i| 1 ms before = {one_ms:.4f} A, at it = {abs(current[k]):.2e} A"
        )


def test_same_currents_whatever_the_blocks() -> None:
    n = 5000
    whole = term_on(PAPER_REF).currents(block_of(PAPER_REF, np.arange(n)))
    rng = np.random.default_rng(7)
    sizes: list[int] = []
    while sum(sizes) < n:
        sizes.append(int(min(rng.integers(1, 700), n - sum(sizes))))
    for split in (sizes, [1] * n, [256] * (n // 256) + [n % 256]):
        again = currents_in_blocks(term_on(PAPER_REF), PAPER_REF, split)
        assert_array_equal(again.view(np.int64), whole.view(np.int64))


def test_through_the_generator() -> None:
    """The term is a FeedforwardTerm: the generator adds exactly its currents."""
    n = 2600
    term_alone = term_on(PAPER_REF).currents(block_of(PAPER_REF, np.arange(n)))
    gen = FeedforwardGenerator(
        reference=PAPER_REF,
        grid=SampleGrid(control_period_s=TU),
        lead_m_per_rad=1.910e-3,
        nominal=NominalModel(
            inertia_kgm2=2.6e-3, damping_Nms_per_rad=0.07, torque_constant_Nm_per_A=KT
        ),
        ptc_enabled=False,
        terms=[term_on(PAPER_REF)],
    )
    u_ff = np.array([row[2] for row in gen.samples(0, 1000) + gen.samples(1000, n)])
    assert_array_equal(u_ff.view(np.int64), term_alone.view(np.int64))


def test_search_horizon() -> None:
    # A 2 ms horizon (4 samples): the top reversal (first sample after it: 1001)
    # counts from sample 997 on; before that only the previous one, and there is none.
    term = term_on(PAPER_REF, search_horizon_s=2e-3)
    assert term.horizon_steps == 4
    current = term.currents(block_of(PAPER_REF, np.arange(1100)))
    assert_array_equal(current[990:997], F0 / KT)
    assert np.all(np.abs(current[997:1001]) < F0 / KT)
    full = term_on(PAPER_REF).currents(block_of(PAPER_REF, np.arange(1100)))
    assert_array_equal(current[997:], full[997:])


def test_scan_is_incremental() -> None:
    """Each grid sample is evaluated once whatever the block size (plus brentq's few)."""

    @dataclass
    class Counting:
        inner: Reference
        points: int = 0

        @property
        def period_s(self) -> float | None:
            return self.inner.period_s

        def sample(self, t_s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            self.points += np.asarray(t_s).size
            return self.inner.sample(t_s)

    n = 20_000
    counting = Counting(PAPER_REF)
    term = term_on(counting)
    current = currents_in_blocks(term, PAPER_REF, [7] * (n // 7) + [n % 7])
    scanned = (math.ceil((n + term.horizon_steps) / SCAN_CHUNK_STEPS) + 1) * SCAN_CHUNK_STEPS
    assert counting.points <= scanned + 150 * len(term.reversals)
    # t = 0.5 .. 10.5 s at least: the scan has looked 1 s (and part of a chunk) ahead.
    times = [r.time_s for r in term.reversals]
    assert 21 <= len(times) <= 23
    assert_allclose(times, 0.5 * np.arange(1, len(times) + 1), rtol=0.0, atol=1e-9)
    assert_allclose(current[1:], expected_on_paper_ref(np.arange(1, n)), rtol=1e-9, atol=1e-9)


# -- other references --------------------------------------------------------------


@dataclass(frozen=True)
class AbsSineVelocity:
    """x = A (2 m + 1 - cos(w t - m pi)) for m pi <= w t < (m + 1) pi: v = A w |sin w t| >= 0."""

    amplitude_m: float = 0.01
    omega_rad_s: float = 2.0 * math.pi

    @property
    def period_s(self) -> float | None:
        return None

    def sample(self, t_s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t_s, dtype=float)
        a, w = self.amplitude_m, self.omega_rad_s
        m = np.floor(w * t / math.pi)
        x = a * (2.0 * m + 1.0 - np.cos(w * t - m * math.pi))
        return x, a * w * np.abs(np.sin(w * t)), a * w * w * np.cos(w * t - m * math.pi)


def test_non_reversal_motion_is_not_a_reversal() -> None:
    ref = AbsSineVelocity()
    term = term_on(ref)
    current = term.currents(block_of(ref, np.arange(6000)))
    assert term.reversals == ()
    assert current[0] == 0.0  # at rest before it moves
    assert_array_equal(current[1:], F0 / KT)  # no reversal: the Coulomb level


def test_stop_and_go_in_one_direction() -> None:
    # Moves of 10 mm in 0.2 s with a 0.1 s dwell (v = 0 exactly), always forwards.
    ref = PointToPointReference(distance_m=0.01, move_time_s=0.2, dwell_s=0.1, back_and_forth=False)

    @dataclass(frozen=True)
    class Staircase:
        @property
        def period_s(self) -> float | None:
            return None

        def sample(self, t_s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            t = np.asarray(t_s, dtype=float)
            m = np.floor(t / 0.3)
            x, v, a = ref.sample(t - 0.3 * m)
            return x + 0.01 * m, v, a

    stairs = Staircase()
    steps = np.arange(3000)
    _, v, _ = stairs.sample(steps * TU)
    term = term_on(stairs)
    current = term.currents(block_of(stairs, steps))
    assert term.reversals == ()
    assert current[0] == 0.0
    # Moving, or stopped with the next move (forwards) ahead: +F_0.
    assert_array_equal(current[1:], F0 / KT)
    assert np.sum(v[1:] == 0.0) > 500  # the dwells were there
    # With a horizon shorter than a dwell, a standstill with no motion ahead gets nothing.
    short = term_on(stairs, search_horizon_s=0.02)
    cur = short.currents(block_of(stairs, steps))
    dwell = steps[(steps * TU % 0.3 > 0.2) & (steps * TU % 0.3 < 0.3 - 0.03)]
    assert_array_equal(cur[dwell], 0.0)
    assert_array_equal(cur[v != 0.0], F0 / KT)


def test_reversal_after_a_dwell() -> None:
    # Out 10 mm, dwell 0.05 s (v = 0 exactly), back: one reversal at the far end, z = 0 in the dwell.
    ref = PointToPointReference(distance_m=0.01, move_time_s=0.2, dwell_s=0.05)
    steps = np.arange(1000)
    _, v, _ = ref.sample(steps * TU)
    term = term_on(ref)
    current = term.currents(block_of(ref, steps))
    first = term.reversals[0]
    assert 0.2 <= first.time_s <= 0.25
    assert first.position_m == 0.01
    dwell = (steps * TU > 0.2) & (steps * TU < 0.25)
    assert np.all(v[dwell] == 0.0)
    assert_array_equal(current[dwell], 0.0)
    assert np.all(current[1:400][v[1:400] > 0.0] > 0.0)
    assert np.all(current[500:900][v[500:900] < 0.0] < 0.0)
