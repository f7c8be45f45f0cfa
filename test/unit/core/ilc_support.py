"""Shared by the ILC tests: the 001 loop simulated independently of the module.

The plant is discretised by scipy, the PID runs as DiscretePid, and the
lifted matrices of S and S P are Toeplitz matrices of the simulated impulse
responses.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.signal

from servo_axis.core.feedback.pid import DiscretePid, PidGains, design_pid_pole_placement
from servo_axis.core.learning.filters import q_filter_taps
from servo_axis.core.learning.ilc import IlcParams
from servo_axis.core.models.base import NominalModel

PERIOD_S = 1e-3
LEAD = 1.91e-3
KT = 0.715
NOMINAL = NominalModel(inertia_kgm2=0.015, damping_Nms_per_rad=0.1, torque_constant_Nm_per_A=KT)
TRUE_PLANT = NominalModel(
    inertia_kgm2=0.8 * 0.015, damping_Nms_per_rad=1.2 * 0.1, torque_constant_Nm_per_A=KT
)
PID = design_pid_pole_placement(bandwidth_hz=30.0, **NOMINAL.as_kwargs())


def paper_params(samples: int, nq: int = 16) -> IlcParams:
    return IlcParams(
        samples_per_trial=samples,
        nq=nq,
        period_s=PERIOD_S,
        lead_m_per_rad=LEAD,
        nominal=NOMINAL,
        pid=PID,
    )


def min_jerk(
    rest: int, moves: list[tuple[float, int]], tail: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity, acceleration of minimum-jerk moves (distance m, samples) with rests."""
    pos, vel, acc = [np.zeros(rest)], [np.zeros(rest)], [np.zeros(rest)]
    x0 = 0.0
    for i, (dist, samples) in enumerate(moves):
        duration = samples * PERIOD_S
        tau = np.arange(samples) / samples
        pos.append(x0 + dist * (10 * tau**3 - 15 * tau**4 + 6 * tau**5))
        vel.append(dist / duration * (30 * tau**2 - 60 * tau**3 + 30 * tau**4))
        acc.append(dist / duration**2 * (60 * tau - 180 * tau**2 + 120 * tau**3))
        x0 += dist
        gap = tail if i == len(moves) - 1 else rest
        pos.append(np.full(gap, x0))
        vel.append(np.zeros(gap))
        acc.append(np.zeros(gap))
    return np.concatenate(pos), np.concatenate(vel), np.concatenate(acc)


def loop_responses(
    plant: NominalModel, pid: PidGains, samples: int
) -> tuple[np.ndarray, np.ndarray]:
    """Impulse responses of ``S`` (r -> e) and ``S P`` (f -> x), simulated sample by sample.

    x_k = R angle_k is measured at k, u_k = C(e_k / R) + f_k is held over
    [k T, (k+1) T).
    """
    a = np.array([[0.0, 1.0], [0.0, -plant.damping_Nms_per_rad / plant.inertia_kgm2]])
    b = np.array([[0.0], [plant.torque_constant_Nm_per_A / plant.inertia_kgm2]])
    ad, bd, *_ = scipy.signal.cont2discrete((a, b, np.eye(2), np.zeros((2, 1))), PERIOD_S, "zoh")
    out = []
    for which in ("r", "f"):
        ctl = DiscretePid(gains=pid, period_s=PERIOD_S)
        state = np.zeros(2)
        h = np.zeros(samples)
        for k in range(samples):
            x = LEAD * state[0]
            e = (1.0 if (which == "r" and k == 0) else 0.0) - x
            u = ctl.update(e / LEAD) + (1.0 if (which == "f" and k == 0) else 0.0)
            h[k] = e if which == "r" else x
            state = ad @ state + bd[:, 0] * u
        out.append(h)
    return out[0], out[1]


def lifted(h: np.ndarray) -> np.ndarray:
    """Lower-triangular Toeplitz convolution matrix of an impulse response."""
    return scipy.linalg.toeplitz(h, np.zeros_like(h))


def q_matrix(samples: int, nq: int) -> np.ndarray:
    """Lifted Q of eq. (24) with end-value extension, built entry by entry."""
    taps = q_filter_taps(nq)
    m = np.zeros((samples, samples))
    for i in range(samples):
        for k, c in enumerate(taps):
            m[i, min(max(i + k - nq, 0), samples - 1)] += c
    return m


def loop_matrices(plant: NominalModel, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Lifted ``S`` (r -> e) and ``S P`` (f -> x) under the 30 Hz PID."""
    h_s, h_sp = loop_responses(plant, PID, samples)
    return lifted(h_s), lifted(h_sp)


class RunningLoop:
    """The 001 loop run trial after trial without a reset, as the axis runs it.

    The plant's state and the PID's state carry over from one trial to the
    next (the loop of :func:`loop_responses`, sample by sample). ``d`` is an
    input disturbance in A (e.g. friction held at rest), subtracted from
    the input as in 001 eq. (2).
    """

    def __init__(self, plant: NominalModel) -> None:
        a = np.array([[0.0, 1.0], [0.0, -plant.damping_Nms_per_rad / plant.inertia_kgm2]])
        b = np.array([[0.0], [plant.torque_constant_Nm_per_A / plant.inertia_kgm2]])
        self._ad, bd, *_ = scipy.signal.cont2discrete(
            (a, b, np.eye(2), np.zeros((2, 1))), PERIOD_S, "zoh"
        )
        self._bd = bd[:, 0]
        self._ctl = DiscretePid(gains=PID, period_s=PERIOD_S)
        self._state = np.zeros(2)

    def trial(self, r: np.ndarray, f: np.ndarray, d: np.ndarray | None = None) -> np.ndarray:
        """Run one trial from the state the last one left; its error ``r - x``, m."""
        dist = np.zeros(len(r)) if d is None else d
        e = np.empty(len(r))
        for k in range(len(r)):
            e[k] = r[k] - LEAD * self._state[0]
            u = self._ctl.update(e[k] / LEAD) + f[k] - dist[k]
            self._state = self._ad @ self._state + self._bd * u
        return e
