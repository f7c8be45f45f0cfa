#!/usr/bin/env python3
"""Paper 003's four scenarios as plain calls of the core objects (no ROS).

``dlpid_tilt_pid``, ``dlpid_tilt_marc`` (previous MARC), ``dlpid_tilt_lpf100``
and ``dlpid_tilt_lpf2`` (the proposal) through
:func:`servo_axis.simulate.simulate_identification`: the loop the node graph
reproduces bit for bit (``test/integration/test_dlpid_runs.py``). Prints the
RMSD of theta_d - theta (true angle and measured angle), its reduction
against PID, the final estimates against the plant's and the peak-to-peak of
J, D, U over the last reference period: the table of docs/explanation/paper-003.md and of
003 Fig. 9.

    .venv/bin/python scripts/dlpid_core_only.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from servo_axis import numerics
from servo_axis.params.factories import build_reference
from servo_axis.params.resolve import node_values
from servo_axis.params.scenario import load_scenario
from servo_axis.simulate import simulate_identification

CONFIG = Path(__file__).resolve().parents[1] / "config"
SCHEMES = ("pid", "marc", "lpf100", "lpf2")
KEYS = ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm", "coulomb_Nm")


def run(path: Path) -> dict[str, object]:
    scenario = load_scenario(path)
    ff = node_values(scenario, "feedforward")
    plant = node_values(scenario, "plant")
    tu = plant["control_period_s"]
    result = simulate_identification(path)
    n = result.angle_rad.size
    target = build_reference(ff).sample(np.arange(n) * tu)[0]
    out: dict[str, object] = {
        "rmsd": float(np.sqrt(np.mean((target - result.angle_rad) ** 2))),
        "rmsd_measured": float(np.sqrt(np.mean((target - result.trajectory.encoder_rad) ** 2))),
    }
    e = result.estimates
    if len(e):
        true = np.array([plant[k] for k in KEYS])
        out["ratio"] = e[-1, 2:6] / np.where(true > 0, true, np.nan)
        last = e[e[:, 0] * tu > n * tu - 1.0 / ff["reference.frequency_hz"]]
        out["p2p"] = np.ptp(last[:, 2:5], axis=0)
    return out


def main() -> int:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=None, help="shorten the runs")
    args = parser.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scheme in SCHEMES:
            path = CONFIG / f"dlpid_tilt_{scheme}.yaml"
            if args.seconds is not None:
                data = load_scenario(path)
                data["/**"]["ros__parameters"]["duration_s"] = args.seconds
                path = Path(tmp) / path.name
                path.write_text(yaml.safe_dump(data, sort_keys=False))
            t0 = time.perf_counter()
            rows[scheme] = run(path)
            print(f"{scheme}: {time.perf_counter() - t0:.1f} s wall", flush=True)
    base = float(rows["pid"]["rmsd"])  # type: ignore[arg-type]
    print("\nRMSD of theta_d - theta (rad; true angle, measured angle); final estimate / true;")
    print("peak-to-peak of J, D, U over the last reference period")
    for scheme, row in rows.items():
        rmsd = float(row["rmsd"])  # type: ignore[arg-type]
        line = (
            f"{scheme:<7} RMSD {rmsd:.4e} ({float(row['rmsd_measured']):.4e}) "  # type: ignore[arg-type]
            f"{100 * (1 - rmsd / base):5.1f} % below PID"
        )
        if "ratio" in row:
            ratio, p2p = row["ratio"], row["p2p"]
            line += "  J D U C " + " ".join(f"{r:.3f}" for r in ratio)  # type: ignore[attr-defined]
            line += "  p2p " + " ".join(f"{v:.2e}" for v in p2p)  # type: ignore[attr-defined]
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
