"""The compiled sub-step loops compute exactly what the same code computes interpreted.

The kernel modules (``core/models/ball_screw_kernels.py``,
``tilting_table_kernels.py``, ``core/feedforward/ptc_kernels.py``,
``core/friction/gms_kernels.py``) are compiled with numba; with
``NUMBA_DISABLE_JIT=1`` the very same functions run as plain Python. Every
plant model that uses a kernel is run both ways in a process of its own,
through stick, slip, reversals, saturation and sensor noise, and every
output must agree to the last bit.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

RUN = r"""
import json, math
import numpy as np
from servo_axis.core.friction.maxwell_slip import MaxwellSlip
from servo_axis.core.friction.model import FrictionParams
from servo_axis.core.models.ball_screw import BALL_SCREW_MODES, BallScrewParams, BallScrewPlant
from servo_axis.core.models.elastic_ball_screw import ElasticBallScrewParams, ElasticBallScrewPlant
from servo_axis.core.models.tilting_table import TiltingTableParams, TiltingTablePlant
from servo_axis.core.sensors import SensorParams

def currents(n, amplitude, hz, period, saturate=True):
    t = np.arange(n) * period
    # A chirp with reversals, and a stretch beyond the current limit.
    over = 40.0 * (t > 0.8 * t[-1]) if saturate else 0.0 * t
    return (amplitude * np.sin(2 * np.pi * hz * t * (1 + 2 * t)) + over).tolist()

def run(plant, cmds):
    rows = []
    for c in cmds:
        o = plant.step(c)
        rows.append([o.encoder_rad, o.scale_m, o.angle_rad, o.velocity_rad_s, o.position_m,
                     o.velocity_m_s, o.motor_torque_Nm, o.friction_force_N])
    return [[x.hex() for x in r] for r in rows]

out = {}
friction = FrictionParams(rolling_coulomb_Nm=3.2, elements=8, coulomb_Nm=0.3, viscous_Nms_per_rad=0.01)
screw = BallScrewParams(modes=BALL_SCREW_MODES, dead_time_s=70e-6, sim_step_s=10e-6,
                        friction=friction, encoder=SensorParams(resolution=1e-6, noise_std=1e-6))
out["ball_screw"] = run(BallScrewPlant(screw, rng=np.random.default_rng(3)),
                        currents(300, 6.0, 3.0, 1e-3))
out["elastic"] = run(ElasticBallScrewPlant(ElasticBallScrewParams()), currents(400, 3.0, 4.0, 5e-4))
out["elastic_ideal_current"] = run(
    ElasticBallScrewPlant(ElasticBallScrewParams(current_bandwidth_hz=0.0, contact_zone_m=0.0)),
    currents(200, 3.0, 4.0, 5e-4))
out["elastic_contact"] = run(
    ElasticBallScrewPlant(ElasticBallScrewParams(
        nut_friction="contact", contact_zone_m=0.0, contact_travel_m=19e-6, nut_preload_N=80.0,
        contact_presliding_m=1e-6, nut_friction_Nm=0.1, bearing_friction_Nm=0.1)),
    currents(400, 3.0, 4.0, 5e-4))
out["tilting"] = run(TiltingTablePlant(TiltingTableParams(), rng=np.random.default_rng(4)),
                     currents(600, 0.35, 10.0, 4e-4, saturate=False))
out["tilting_smooth"] = run(
    TiltingTablePlant(TiltingTableParams(coulomb_Nm=0.0), rng=np.random.default_rng(4)),
    currents(300, 0.35, 10.0, 4e-4))
slip = MaxwellSlip(coulomb_Nm=3.2, width_rad=5e-3, elements=7)
out["maxwell_slip"] = [slip.move(d).hex() for d in (1e-3 * np.sin(np.arange(200) / 7.0)).tolist()]
from servo_axis.core.feedforward.ptc import MultiratePtc
rng = np.random.default_rng(6)
ptc = MultiratePtc(inertia_kgm2=2e-3, damping_Nms_per_rad=1e-2, torque_constant_Nm_per_A=1.0,
                   control_period_s=4e-4, compiled=True)
rows = []
for i0 in range(0, 400, 7):
    ptc.replace_model(from_instant=i0 + 3, inertia_kgm2=float(1e-3 + 1e-3 * rng.random()),
                      damping_Nms_per_rad=float(1e-2 * rng.random()), torque_constant_Nm_per_A=1.0)
    f = ptc.feedforward(rng.standard_normal((8, 2)), i0)
    rows.append([x.hex() for x in [*f.current_A, *f.position_rad, *f.velocity_rad_s]])
    ptc.forget_before(i0 + 7)
out["ptc"] = rows
from servo_axis.core.friction.gms_model import GmsModel
from servo_axis.core.friction.gms_params import GmsParams
from servo_axis.core.friction.gms_kernels import exact_sum
gms = GmsModel(GmsParams(stiffness_Nm_per_m=(2e5, 8e4, 2e4), weights=(0.3, 0.3, 0.4),
                         coulomb_Nm=0.4, static_Nm=0.6, stribeck_velocity_m_s=1e-3,
                         stribeck_exponent=1.5, attraction_per_s=5e4, viscous_Nms_per_m=2.0),
               compiled=True)
t = np.arange(600) * 5e-4
x = (2.5e-4 * (1 - np.cos(2 * np.pi * 3 * t))).tolist()
v = (2.5e-4 * 2 * np.pi * 3 * np.sin(2 * np.pi * 3 * t)).tolist()
out["gms"] = [f.hex() for f in gms.update_many(x, v, [5e-4] * 600)]
out["fsum"] = [exact_sum(a, np.empty(len(a) + 1)).hex()
               for a in (rng.standard_normal((300, 9)) * 10.0 ** rng.integers(-8, 8, (300, 9)))]
print(json.dumps(out))
"""


def outputs(*, jit: bool) -> dict[str, list[object]]:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_DISABLE_JIT"}
    if not jit:
        env["NUMBA_DISABLE_JIT"] = "1"
    done = subprocess.run(
        [sys.executable, "-c", RUN], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result: dict[str, list[object]] = json.loads(done.stdout)
    return result


@pytest.fixture(scope="module")
def both() -> tuple[dict[str, list[object]], dict[str, list[object]]]:
    return outputs(jit=True), outputs(jit=False)


@pytest.mark.parametrize(
    "case",
    [
        "ball_screw",
        "elastic",
        "elastic_ideal_current",
        "elastic_contact",
        "tilting",
        "tilting_smooth",
        "maxwell_slip",
    ],
)
def test_compiled_equals_interpreted_bit_for_bit(
    both: tuple[dict[str, list[object]], dict[str, list[object]]], case: str
) -> None:
    compiled, interpreted = both
    assert len(compiled[case]) == len(interpreted[case]) > 0
    mismatched = [
        i for i, (a, b) in enumerate(zip(compiled[case], interpreted[case], strict=True)) if a != b
    ]
    assert not mismatched, f"{case}: first differing step {mismatched[0]}"


def test_the_cases_move_through_what_they_should(
    both: tuple[dict[str, list[object]], dict[str, list[object]]],
) -> None:
    # Not a trivial comparison: the table sticks and slips, the screw reverses.
    compiled, _ = both
    velocity = np.array([[float.fromhex(x) for x in r] for r in compiled["tilting"]])[:, 3]
    assert np.any(velocity == 0.0) and np.any(velocity > 0.0) and np.any(velocity < 0.0)
    screw = np.array([[float.fromhex(x) for x in r] for r in compiled["ball_screw"]])
    assert np.any(np.diff(np.sign(screw[:, 3])) != 0)
    np.testing.assert_allclose(np.abs(screw[:, 6]).max(), 0.715 * 30.0, rtol=1e-12)
    contact = np.array([[float.fromhex(x) for x in r] for r in compiled["elastic_contact"]])
    assert np.any(np.diff(np.sign(contact[:, 3])) != 0)


def test_the_compiled_ptc_is_the_numpy_ptc() -> None:
    """MultiratePtc(compiled=True) (ptc_model, ptc_segment) = the numpy formulation, to the bit."""
    from servo_axis.core.feedforward.ptc import MultiratePtc

    kwargs = {
        "inertia_kgm2": 2e-3,
        "damping_Nms_per_rad": 1e-2,
        "torque_constant_Nm_per_A": 0.7,
        "control_period_s": 4e-4,
    }
    fast, plain = MultiratePtc(**kwargs, compiled=True), MultiratePtc(**kwargs)
    rng = np.random.default_rng(9)
    i0 = 0
    for _ in range(300):
        m = int(rng.integers(1, 13))
        steps = sorted(set(rng.integers(i0 + 1, i0 + m + 3, size=2).tolist()))
        for step in [s for s in steps if s > fast._models[-1].from_instant]:
            model = {
                "inertia_kgm2": float(10.0 ** rng.uniform(-4, -1)),
                "damping_Nms_per_rad": float(rng.random() * 0.1),
                "torque_constant_Nm_per_A": 0.7,
            }
            fast.replace_model(from_instant=step, **model)
            plain.replace_model(from_instant=step, **model)
        x = rng.standard_normal((m + 1, 2)) * 10.0 ** rng.uniform(-3, 2)
        a, b = fast.feedforward(x, i0), plain.feedforward(x, i0)
        for name in ("current_A", "position_rad", "velocity_rad_s"):
            assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
        for f, p in zip(fast._models, plain._models, strict=True):
            for name in ("ad", "bd", "a_matrix", "b_matrix", "b_inv"):
                assert (
                    getattr(f, name).tobytes() == np.ascontiguousarray(getattr(p, name)).tobytes()
                )
        i0 += m
        fast.forget_before(i0)
        plain.forget_before(i0)


def test_the_exact_sum_is_math_fsum() -> None:
    """exact_sum (CPython's fsum, ported) = math.fsum, sign of zero included."""
    import math

    from servo_axis.core.friction.gms_kernels import exact_sum

    rng = np.random.default_rng(12)
    for t in range(20000):
        n = int(rng.integers(0, 22))
        kind = t % 4
        if kind == 0:
            v = rng.standard_normal(n) * 10.0 ** rng.integers(-300, 300, n)
        elif kind == 1:
            v = rng.standard_normal(n)
            v = np.concatenate([v, -v[: n // 2]])
            rng.shuffle(v)
        elif kind == 2:
            v = np.round(rng.standard_normal(n) * 4) / 4 * 2.0 ** rng.integers(-60, 60)
        else:
            v = rng.choice([0.0, -0.0, 5e-324, -5e-324, 1.0, -1.0, 2.0**53, 1e16, -1e16, 0.1], n)
        v = np.ascontiguousarray(v, dtype=float)
        assert exact_sum(v, np.empty(len(v) + 1)).hex() == math.fsum(v.tolist()).hex()


@pytest.mark.parametrize("static", [0.4, 0.55])
def test_the_compiled_gms_block_is_update_sample_by_sample(static: float) -> None:
    """GmsModel.update_many (gms_block) = update() per sample: torques and state, to the bit."""
    from servo_axis.core.friction.gms_model import GmsModel
    from servo_axis.core.friction.gms_params import GmsParams

    params = GmsParams(
        stiffness_Nm_per_m=(2.6e5, 8.3e4, 2.1e4, 1.2e4),
        weights=(0.24, 0.3, 0.2, 0.26),
        coulomb_Nm=0.4,
        static_Nm=static,
        stribeck_velocity_m_s=1e-3,
        stribeck_exponent=2.0,
        attraction_per_s=5e5,
        viscous_Nms_per_m=0.5,
    )
    fast, plain = GmsModel(params, compiled=True), GmsModel(params)
    rng = np.random.default_rng(3)
    t = np.arange(5000) * 5e-4
    x = 2.5e-4 * (1 - np.cos(2 * np.pi * 2 * t)) + 1e-7 * rng.standard_normal(t.size)
    v = 2.5e-4 * 2 * np.pi * 2 * np.sin(2 * np.pi * 2 * t)
    v[::97] = 0.0
    periods = (5e-4 * rng.integers(1, 3, t.size)).tolist()
    j = 0
    while j < t.size:
        n = int(rng.integers(0, 300))
        sl = slice(j, j + n)
        got = fast.update_many(x[sl].tolist(), v[sl].tolist(), periods[sl])
        expected = [
            plain.update(a, b, c)
            for a, b, c in zip(x[sl].tolist(), v[sl].tolist(), periods[sl], strict=True)
        ]
        assert [g.hex() for g in got] == [e.hex() for e in expected]
        assert fast.forces_Nm == plain.forces_Nm and fast.slipping == plain.slipping
        j += n
        if j > 2500 and j < 2800:
            fast.reset()
            plain.reset()
