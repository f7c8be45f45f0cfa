"""The identifier's compiled kernels compute exactly what they replace.

``core/identification/online/dlpid_kernels.py`` is compiled with numba; with
``NUMBA_DISABLE_JIT=1`` the very same functions run as plain Python. A DLPID
and a conditional RLS are run both ways in a process of their own, and
every output must agree to the last bit; in this process, the kernels are
checked against the numpy code they replaced (the filter objects of
:mod:`servo_axis.core.feedback.discrete` and the conditional RLS written
with numpy), also to the last bit.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from servo_axis.core.feedback.discrete import tustin
from servo_axis.core.identification.online.dlpid import Dlpid, DlpidParams
from servo_axis.core.identification.online.dlpid_kernels import second_order_bank
from servo_axis.core.identification.online.rls import ConditionalRls, RlsParams

RLS = RlsParams(
    initial=(20e-4, 100e-4, 0.1),
    lower=(1e-5, 0.0, 0.0),
    upper=(1.0, 1.0, 10.0),
    forgetting=(0.999, 0.999, 0.995),
    initial_covariance=1e3,
    names=("J", "D", "U"),
)

RUN = r"""
import json, math
import numpy as np
from servo_axis.core.identification.online.dlpid import Dlpid, DlpidParams
from servo_axis.core.identification.online.rls import ConditionalRls, RlsParams

rls = RlsParams(initial=(20e-4, 100e-4, 0.1), lower=(1e-5, 0.0, 0.0), upper=(1.0, 1.0, 10.0),
                forgetting=(0.999, 0.999, 0.995), initial_covariance=1e3, names=("J", "D", "U"))
out = {}
for mode in ("double_layer", "single_layer"):
    ident = Dlpid(DlpidParams(rls=rls, mode=mode))
    rows = []
    for k in range(3000):
        t = k * 4e-4
        angle = 0.5 * math.sin(2 * math.pi * 1.5 * t) + 0.3
        torque = 0.2 * math.cos(2 * math.pi * 1.5 * t) + 0.1 * math.sin(angle)
        e = ident.update(k, angle, torque)
        row = list(ident.signals)
        if e is not None:
            row += [e.J, e.D, e.U, e.C, e.kappa]
        rows.append([x.hex() for x in row])
    out[mode] = rows
r = ConditionalRls(rls)
rng = np.random.default_rng(5)
rows = []
for k in range(2000):
    phi = rng.standard_normal(3) * (1.0, 3.0, 0.5)
    r.update(phi, float(phi @ (3e-3, 2e-2, 0.4)) + 1e-3 * rng.standard_normal(), rng.random(3) < 0.7)
    rows.append([x.hex() for x in [*r.theta, *r.covariance.ravel()]])
out["rls"] = rows
from servo_axis.core.identification.online.pe import PeIndex
pe = PeIndex(3, 7)
rows = []
for k in range(300):
    kappa = pe.update(rng.standard_normal(3) * (1.0, 3.0, 0.5))
    rows.append([x.hex() for x in [kappa, *pe._sum.ravel()]])
out["pe"] = rows
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


@pytest.mark.parametrize("case", ["double_layer", "single_layer", "rls"])
def test_compiled_and_interpreted_agree_to_the_bit(
    both: tuple[dict[str, list[object]], dict[str, list[object]]], case: str
) -> None:
    compiled, interpreted = both
    assert len(compiled[case]) > 100
    assert compiled[case] == interpreted[case]


def test_the_filter_bank_is_the_filter_objects() -> None:
    wc = 2.0 * math.pi * 20.0
    den = np.array([1.0, 2.0 * wc, wc * wc])
    nums = ([wc * wc], [wc * wc, 0.0], [wc * wc, 0.0, 0.0], [wc * wc])
    filters = [tustin(np.array(num), den, 4e-4) for num in nums]
    for f, x in zip(filters, (0.3, 0.3, 0.3, -0.1), strict=True):
        f.settle(x)
    coef = np.array([[*f.b, *f.a[1:]] for f in filters])
    z = np.array([f.state for f in filters])
    rng = np.random.default_rng(1)
    for angle, torque in rng.standard_normal((500, 2)).tolist():
        got = second_order_bank(coef, z, angle, torque)
        want = tuple(f.update(x) for f, x in zip(filters, (angle,) * 3 + (torque,), strict=True))
        assert got == want
        assert z.tolist() == [f.state for f in filters]


def reference_rls_update(
    r: ConditionalRls, phi: np.ndarray, u: float, mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The numpy conditional RLS step the kernel replaced (``theta``, ``P`` after it)."""
    e = np.flatnonzero(mask)
    d = np.flatnonzero(~mask)
    theta, p = r.theta, r.covariance
    y = u - float(phi[d] @ theta[d])
    phi_e = phi[e]
    s = (1.0 / np.sqrt(np.array(r.params.forgetting)))[e]
    p_bar = p.copy()
    p_bar[e, :] *= s[:, None]
    p_bar[:, e] *= s[None, :]
    p_ee = p_bar[np.ix_(e, e)]
    gain = p_ee @ phi_e / (1.0 + float(phi_e @ p_ee @ phi_e))
    t = np.eye(len(e)) - np.outer(gain, phi_e)
    p_new = p_bar
    p_new[np.ix_(e, e)] = t @ p_ee
    if len(d):
        p_ed = t @ p_bar[np.ix_(e, d)]
        p_new[np.ix_(e, d)] = p_ed
        p_new[np.ix_(d, e)] = p_ed.T
    p_out = 0.5 * (p_new + p_new.T)
    inc = gain * (y - float(phi_e @ theta[e]))
    old = theta[e]
    trial = old + inc
    lo, hi = np.array(r.params.lower)[e], np.array(r.params.upper)[e]
    blocked = ((trial >= hi) & (inc >= 0.0)) | ((trial <= lo) & (inc <= 0.0))
    theta = theta.copy()
    theta[e] = np.clip(np.where(blocked, old, trial), lo, hi)
    return theta, p_out


def test_the_rls_kernel_is_the_numpy_update() -> None:
    r = ConditionalRls(RLS)
    rng = np.random.default_rng(7)
    true = np.array([3e-3, 2e-2, 0.4])
    for k in range(3000):
        phi = rng.standard_normal(3) * (1.0, 3.0, 0.5) * (10.0 if k % 97 == 0 else 1.0)
        u = float(phi @ true) + 1e-3 * rng.standard_normal()
        mask = rng.random(3) < 0.6
        if not mask.any():
            mask[k % 3] = True
        want = reference_rls_update(r, phi, u, mask)
        r.update(phi, u, mask)
        assert r.theta.tolist() == want[0].tolist()
        assert r.covariance.tolist() == want[1].tolist()


def test_dlpid_state_round_trip_after_the_kernels() -> None:
    a = Dlpid(DlpidParams(rls=RLS))
    for k in range(700):
        a.update(k, 0.4 * math.sin(k * 0.01), 0.1 * math.cos(k * 0.01))
    b = Dlpid(DlpidParams(rls=RLS))
    b.load_state(json.loads(json.dumps(a.state())))
    for k in range(700, 1400):
        ea = a.update(k, 0.4 * math.sin(k * 0.01), 0.1 * math.cos(k * 0.01))
        eb = b.update(k, 0.4 * math.sin(k * 0.01), 0.1 * math.cos(k * 0.01))
        assert ea == eb
    np.testing.assert_array_equal(a.rls.covariance, b.rls.covariance)


def test_the_pe_kernel_is_the_numpy_update() -> None:
    """PeIndex with its compiled running sum and direct eigvalsh = the numpy formulation."""
    from servo_axis.core.identification.online.pe import PeIndex

    window, n = 7, 3
    pe = PeIndex(n, window)
    buffer, total, slot, count = np.zeros((window, n)), np.zeros((n, n)), 0, 0
    rng = np.random.default_rng(11)
    for _ in range(500):
        v = rng.standard_normal(n) * (1.0, 3.0, 0.5)
        kappa = pe.update(v)
        # What update_checked was: np.outer, elementwise -= / +=, np.linalg.eigvalsh.
        old = buffer[slot]
        if count >= window:
            total -= np.outer(old, old)
        buffer[slot] = v
        total += np.outer(v, v)
        slot, count = (slot + 1) % window, count + 1
        if count % window == 0:
            total = buffer.T @ buffer
        expected = float(np.linalg.eigvalsh(total / window)[0]) if count >= window else 0.0
        assert kappa.hex() == expected.hex()
        assert pe._sum.tobytes() == total.tobytes() and pe._buffer.tobytes() == buffer.tobytes()
