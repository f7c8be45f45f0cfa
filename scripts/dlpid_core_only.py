#!/usr/bin/env python3
"""Paper 003's four schemes as plain calls of the core objects (no ROS, no scenario files yet).

PID alone, the previous MARC (single-layer RLS of J, D, U; adaptive PTC +
unbalance compensation, eq. (17)) and the proposal (DLPID: RLS + the
friction layer of eq. (8); adaptive PTC + MNC, eq. (12)-(15)) with the
friction low-pass at 2 Hz and at 100 Hz, on the tilting table of Table I
(noise +-1e-5 rad, seeded). PID by pole placement at -10 pi rad/s on the
nominal model of the initial estimates; T_u = T_y = 0.4 ms, T_r = 0.8 ms,
T_RLS = 4 ms; an estimate computed from the samples up to step k applies
from step k + 1 + 10 (one RLS period of latency).

The reference (003 Fig. 6 is not given numerically; our choice): a tilt
0.6 + 0.5 sin(2 pi 0.5 t - pi / 2) rad with a 0.5 s smooth start: it
passes every condition of eq. (16) in every period (angle up to 1.1 rad,
speed up to 1.57 rad/s, acceleration up to 4.9 rad/s^2).

Prints the RMSD of the tracking error, its reduction against PID, the final
estimates against the plant's and the peak-to-peak of J, D, U over the last
period. This is the reference the identifier node will be held to.

    .venv/bin/python scripts/dlpid_core_only.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from servo_axis.core.feedback.loop import FeedbackLoop, SafetyLimits
from servo_axis.core.feedback.pid import DiscretePid, design_pid_pole_placement
from servo_axis.core.feedforward.generator import FeedforwardGenerator
from servo_axis.core.feedforward.mnc import MncParams, NonlinearityCompensator
from servo_axis.core.identification.dlpid import Dlpid, DlpidParams
from servo_axis.core.identification.rls import RlsParams
from servo_axis.core.models.base import NominalModel
from servo_axis.core.models.tilting_table import TiltingTableParams, TiltingTablePlant
from servo_axis.core.reference import SineReference
from servo_axis.core.timing import SampleGrid

TU = 4e-4
R_STEPS = 10  # T_RLS / T_u
LATENCY_STEPS = 10
TRUE = {"J": 50e-4, "D": 130e-4, "U": 0.3, "C": 0.02}
INITIAL = {"J": 20e-4, "D": 100e-4, "U": 0.1, "C": 0.01}
TILT = SineReference(
    amplitude_m=0.5, frequency_hz=0.5, offset_m=0.6, phase_rad=-math.pi / 2, ramp_s=0.5
)


def run(scheme: str, seconds: float, q_hz: float = 2.0) -> dict[str, object]:
    plant = TiltingTablePlant(
        TiltingTableParams(initial_angle_rad=0.1), rng=np.random.default_rng(1)
    )
    nominal = NominalModel(
        inertia_kgm2=INITIAL["J"], damping_Nms_per_rad=INITIAL["D"], torque_constant_Nm_per_A=1.0
    )
    gains = design_pid_pole_placement(bandwidth_hz=5.0, **nominal.as_kwargs())  # -10 pi rad/s
    loop = FeedbackLoop(
        pid=DiscretePid(gains=gains, period_s=TU),
        dob=None,
        lead_m_per_rad=1.0,
        limits=SafetyLimits(following_error_m=10.0, travel_m=10.0, current_A=100.0),
    )
    adaptive = scheme != "pid"
    proposal = scheme.startswith("proposal")
    terms = []
    if adaptive:
        terms.append(
            NonlinearityCompensator(
                MncParams(
                    unbalance_Nm=INITIAL["U"],
                    coulomb_Nm=INITIAL["C"] if proposal else 0.0,
                    friction=proposal,
                    control_period_s=TU,
                ),
                reference=TILT,
            )
        )
    gen = FeedforwardGenerator(
        reference=TILT,
        grid=SampleGrid(control_period_s=TU),
        lead_m_per_rad=1.0,
        nominal=nominal,
        ptc_enabled=adaptive,
        terms=terms,
        estimate_period_steps=R_STEPS if adaptive else None,
        estimate_latency_steps=LATENCY_STEPS,
    )
    dlpid = None
    if adaptive:
        rls = RlsParams(
            initial=(INITIAL["J"], INITIAL["D"], INITIAL["U"]),
            lower=(1e-4, 1e-4, 0.0),
            upper=(1e-1, 1e-1, 2.0),
            forgetting=(0.999, 0.999, 0.995),
            initial_covariance=1e3,
            names=("J", "D", "U"),
        )
        dlpid = Dlpid(
            DlpidParams(
                rls=rls,
                friction_cutoff_hz=q_hz,
                initial_friction_Nm=INITIAL["C"],
                mode="double_layer" if proposal else "single_layer",
            )
        )
    n = round(seconds / TU)
    refs = TILT.sample(np.arange(n) * TU)[0]
    error = np.empty(n)
    estimates = []
    for k in range(n):
        y = plant.output().encoder_rad
        if adaptive:
            ((r, _, u_ff),) = gen.samples(k, k + 1)
        else:
            r, u_ff = float(refs[k]), 0.0
        u = loop.update(angle_rad=y, reference_rad=r, feedforward_A=u_ff).current_A
        error[k] = refs[k] - plant.output().angle_rad
        if dlpid is not None:
            e = dlpid.update(k, y, u)
            if e is not None:
                estimates.append((k, e.J, e.D, e.U, e.C))
                gen.set_estimate(
                    k + 1 + LATENCY_STEPS,
                    inertia_kgm2=e.J,
                    damping_Nms_per_rad=e.D,
                    unbalance_Nm=e.U,
                    coulomb_Nm=e.C if proposal else 0.0,
                )
        plant.step(u)
    out: dict[str, object] = {"rmsd": float(np.sqrt(np.mean(error**2)))}
    if estimates:
        e = np.array(estimates)
        out["final"] = dict(zip("JDUC", e[-1, 1:], strict=True))
        last = e[e[:, 0] * TU > seconds - 1.0 / TILT.frequency_hz]
        out["p2p"] = dict(zip("JDU", np.ptp(last[:, 1:4], axis=0), strict=True))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    rows = {}
    for scheme, q in (
        ("pid", 2.0),
        ("previous_marc", 2.0),
        ("proposal_lpf100", 100.0),
        ("proposal_lpf2", 2.0),
    ):
        t0 = time.perf_counter()
        rows[scheme] = run(scheme, args.seconds, q)
        print(f"{scheme}: {time.perf_counter() - t0:.1f} s wall", flush=True)
    base = rows["pid"]["rmsd"]
    print(
        f"\n{args.seconds:g} s; RMSD of theta_d - theta (rad); final estimate / true; p2p over the last period"
    )
    for scheme, row in rows.items():
        rmsd = float(row["rmsd"])  # type: ignore[arg-type]
        line = f"{scheme:<16} RMSD {rmsd:.3e} ({100 * (1 - rmsd / float(base)):5.1f} % below PID)"  # type: ignore[arg-type]
        if "final" in row:
            final = row["final"]
            p2p = row["p2p"]
            line += "  " + " ".join(f"{k} {final[k] / TRUE[k]:.3f}" for k in "JDUC")  # type: ignore[index]
            line += "  p2p " + " ".join(f"{k} {p2p[k]:.2e}" for k in "JDU")  # type: ignore[index]
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
