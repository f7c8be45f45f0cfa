#!/usr/bin/env python3
"""Seeded families of variants for the results of papers 001 and 003 as bands (issue 21).

``write`` draws the variants with ``numpy.random.default_rng(SEED)`` and
writes the two studies (``src/servo_axis/studies/``), each point an
explicit list of overrides, variant 0 the shipped case:

* ``ilc_family_001`` (base ``pilc_ref_change_silc``, 10 trials): Ref. 1 and
  Ref. 2 of other amplitude (0.5-3.5 mm), either direction and other move
  time (0.4-0.7 s, start 0.05-0.25 s); plant J, D (of the 001 plant,
  0.8 J_n and 1.2 D_n), T_c and the pre-sliding width each times a factor
  log-uniform in [0.5, 2]. Kept only if what the methods assume holds:
  eq. (7) on the plant's rigid part below 1 (S-ILC's and the f^np step's
  convergence), the pre-sliding width (<= 20 um) well inside the 100 um of
  eq. (27). Each variant run with ``silc``, ``pilc_bf`` and ``pilc_bfft``
  (points 3 v, 3 v + 1, 3 v + 2); the laws' own parameters (Nq 16,
  x_mu 5 um, 100 um) are not touched.
* ``dlpid_family_003`` (base ``dlpid_tilt_lpf2``, 20 s): the sine reference of
  other amplitude (0.3-0.6 rad), frequency (0.3-0.8 Hz), offset (lowest
  angle 0.1-0.4 rad) and direction (starting at the bottom or the top);
  plant J, D, U, C each times a factor log-uniform in [0.5, 2]. Kept only if
  eq. (16) is met in every period (lowest angle >= 0.1 rad, peak velocity >=
  0.2 rad/s, peak acceleration >= 0.5 rad/s^2) and the true values lie
  inside the projection bounds of eq. (6). Each variant run with the PID
  alone (the feedforward's PTC and MNC off: the estimates are computed but
  not used) and with DLPID (points 2 v, 2 v + 1); the RMSD reduction is
  paired per variant.

``table`` reads a study's ``results.parquet`` and prints the shipped case,
min / median / max over the family and the variants where the paper's
ordering fails, as Markdown.

    .venv/bin/python scripts/study_families.py write
    .venv/bin/python -m servo_axis sweep ilc_family_001 --workers 2
    .venv/bin/python scripts/study_families.py table ilc_family_001
"""

from __future__ import annotations

import argparse
import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from servo_axis import numerics
from servo_axis.core.feedback.pid import design_pid_pole_placement
from servo_axis.core.learning.ilc import IlcParams, convergence_measure
from servo_axis.core.models.base import NominalModel

REPO = Path(__file__).resolve().parents[1]
STUDIES = REPO / "src" / "servo_axis" / "studies"
SEED = 21  # issue 21
VARIANTS = 16  # besides the shipped case
LAWS = ("silc", "pilc_bf", "pilc_bfft")
SCHEMES = ("pid", "dlpid")

# The 001 plant and loop (pilc_ref_change_silc.yaml).
J_N, D_N, KT, LEAD = 0.015, 0.1, 0.715, 1.91e-3
J_001, D_001, TC_001, WIDTH_001 = 0.012, 0.12, 3.2, 10e-6
# The 003 plant (dlpid_tilt_lpf2.yaml) and the projection bounds of eq. (6) (schema defaults).
J_003, D_003, U_003, C_003 = 0.005, 0.013, 0.3, 0.02
BOUNDS_003 = {"J": (1e-4, 0.1), "D": (1e-4, 0.1), "U": (0.0, 2.0), "C": (0.0, 1.0)}


def _factor(rng: np.random.Generator) -> float:
    """A factor log-uniform in [0.5, 2]."""
    return float(2.0 ** rng.uniform(-1.0, 1.0))


def _eq7_on_plant(inertia: float, damping: float) -> float:
    nominal = NominalModel(inertia_kgm2=J_N, damping_Nms_per_rad=D_N, torque_constant_Nm_per_A=KT)
    params = IlcParams(
        samples_per_trial=1000,
        nq=16,
        period_s=1e-3,
        lead_m_per_rad=LEAD,
        nominal=nominal,
        pid=design_pid_pole_placement(bandwidth_hz=30.0, **nominal.as_kwargs()),
    )
    plant = NominalModel(
        inertia_kgm2=inertia, damping_Nms_per_rad=damping, torque_constant_Nm_per_A=KT
    )
    return convergence_measure(params=params, plant=plant, points=1025)


def _round(x: float, digits: int = 4) -> float:
    return float(f"{x:.{digits}g}")


def ilc_variants(rng: np.random.Generator) -> list[dict[str, Any]]:
    """The overrides of each 001 variant (without the law)."""
    out: list[dict[str, Any]] = [{}]  # the shipped case
    while len(out) < VARIANTS + 1:
        amps, moves, starts = [], [], []
        for _ in range(2):
            amps.append(_round(float(rng.choice([-1.0, 1.0])) * rng.uniform(0.5e-3, 3.5e-3), 3))
            moves.append(_round(rng.uniform(0.4, 0.7), 3))
            starts.append(_round(rng.uniform(0.05, 0.25), 3))
        inertia = _round(J_001 * _factor(rng))
        damping = _round(D_001 * _factor(rng))
        coulomb = _round(TC_001 * _factor(rng))
        width = _round(WIDTH_001 * _factor(rng))
        if _eq7_on_plant(inertia, damping) >= 1.0 or width > 20e-6:
            continue
        out.append(
            {
                "feedforward.reference.amplitudes_m": amps,
                "feedforward.reference.move_times_s": moves,
                "feedforward.reference.start_times_s": starts,
                "plant.inertia_kgm2": inertia,
                "plant.damping_Nms_per_rad": damping,
                "plant.friction.rolling_coulomb_Nm": coulomb,
                "plant.friction.presliding_width_m": width,
            }
        )
    return out


def dlpid_variants(rng: np.random.Generator) -> list[dict[str, Any]]:
    """The overrides of each 003 variant (without the scheme)."""
    out: list[dict[str, Any]] = [{}]
    while len(out) < VARIANTS + 1:
        amplitude = _round(rng.uniform(0.3, 0.6), 3)
        frequency = _round(rng.uniform(0.3, 0.8), 3)
        lowest = _round(rng.uniform(0.1, 0.4), 3)
        phase = float(rng.choice([-math.pi / 2.0, math.pi / 2.0]))
        true = {
            "J": _round(J_003 * _factor(rng)),
            "D": _round(D_003 * _factor(rng)),
            "U": _round(U_003 * _factor(rng)),
            "C": _round(C_003 * _factor(rng)),
        }
        w = 2.0 * math.pi * frequency
        if lowest < 0.1 or amplitude * w < 0.2 or amplitude * w * w < 0.5:
            continue
        if any(not lo < true[k] < hi for k, (lo, hi) in BOUNDS_003.items()):
            continue
        offset = _round(lowest + amplitude, 4)
        out.append(
            {
                "feedforward.reference.amplitude_m": amplitude,
                "feedforward.reference.frequency_hz": frequency,
                "feedforward.reference.offset_m": offset,
                "feedforward.reference.phase_rad": phase,
                "plant.initial_angle_rad": _round(offset + amplitude * math.sin(phase), 4),
                "plant.inertia_kgm2": true["J"],
                "plant.damping_Nms_per_rad": true["D"],
                "plant.unbalance_Nm": true["U"],
                "plant.coulomb_Nm": true["C"],
            }
        )
    return out


HEADER_001 = """\
# Paper 001 (F4: P-ILC vs BF vs S-ILC) as a band: a seeded family of {n} variants
# besides the shipped case (point 0-2), written by scripts/study_families.py
# (seed {seed}; do not edit by hand). Variant v is points 3 v (silc), 3 v + 1
# (pilc_bf), 3 v + 2 (pilc_bfft). Plain-call loops (simulate_learning).
#
#   python -m servo_axis sweep ilc_family_001 --workers 2
#   python scripts/study_families.py table ilc_family_001
"""

HEADER_003 = """\
# Paper 003 (F5: DLPID RMSD and estimates) as a band: a seeded family of {n}
# variants besides the shipped case (points 0-1), written by
# scripts/study_families.py (seed {seed}; do not edit by hand). Variant v is
# points 2 v (PID alone: PTC and MNC off) and 2 v + 1 (DLPID, q = 2 Hz).
# Plain-call loops (simulate_identification), 20 s.
#
#   python -m servo_axis sweep dlpid_family_003 --workers 2
#   python scripts/study_families.py table dlpid_family_003
"""


def write() -> None:
    rng = np.random.default_rng(SEED)
    ilc = ilc_variants(rng)
    points = [copy.deepcopy({**v, "learning.law": law}) for v in ilc for law in LAWS]
    study = {
        "name": "ilc_family_001",
        "scenario": "pilc_ref_change_silc",
        "backend": "plain",
        "points": points,
        "figures": {
            "rms_trial5_m": "tracking_error.cycles[4].rms_m",
            "rms_trial6_m": "tracking_error.cycles[5].rms_m",
            "max_trial6_m": "tracking_error.cycles[5].max_m",
            "rms_trial10_m": "tracking_error.cycles[9].rms_m",
            "max_trial10_m": "tracking_error.cycles[9].max_m",
            "eq7_plant": "ilc_convergence.plant",
        },
    }
    _dump(STUDIES / "ilc_family_001.yaml", HEADER_001.format(n=VARIANTS, seed=SEED), study)
    dl = dlpid_variants(rng)
    off = {"feedforward.ptc.enabled": False, "feedforward.mnc.enabled": False}
    on = {"feedforward.ptc.enabled": True, "feedforward.mnc.enabled": True}
    study = {
        "name": "dlpid_family_003",
        "scenario": "dlpid_tilt_lpf2",
        "backend": "plain",
        "points": [copy.deepcopy({**v, **scheme}) for v in dl for scheme in (off, on)],
        "figures": {
            "rmsd_rad": "tracking_error.all_samples.rms_rad",
            "J_ratio": "identification.final_ratio.inertia_kgm2",
            "D_ratio": "identification.final_ratio.damping_Nms_per_rad",
            "U_ratio": "identification.final_ratio.unbalance_Nm",
            "C_ratio": "identification.final_ratio.coulomb_Nm",
        },
    }
    _dump(STUDIES / "dlpid_family_003.yaml", HEADER_003.format(n=VARIANTS, seed=SEED), study)


def _dump(path: Path, header: str, study: dict[str, Any]) -> None:
    path.write_text(header + yaml.safe_dump(study, sort_keys=False, width=200))
    print(f"wrote {path.relative_to(REPO)} ({len(study['points'])} points)")


def _spread(values: np.ndarray, scale: float, fmt: str) -> str:
    v = values * scale
    return f"{fmt.format(np.min(v))} / {fmt.format(np.median(v))} / {fmt.format(np.max(v))}"


def table(name: str, folder: Path | None) -> None:
    import pyarrow.parquet as pq

    out = folder or REPO / "studies" / name
    rows = pq.read_table(out / "results.parquet").to_pylist()
    if any(r["status"] != "ok" for r in rows):
        failed = [r["point"] for r in rows if r["status"] != "ok"]
        print(f"failed points: {failed}")
    wall = sum(r["wall_time_s"] for r in rows)
    print(f"{len(rows)} points, sum of the points' wall times {wall:.1f} s")
    if name.startswith("ilc_family"):
        _ilc_table(rows)
    else:
        _dlpid_table(rows)


def _ilc_table(rows: list[dict[str, Any]]) -> None:
    by = {law: [r for r in rows if r["learning.law"] == law] for law in LAWS}
    labels = {"silc": "S-ILC", "pilc_bf": "P-ILC (B.F.)", "pilc_bfft": "P-ILC (B.F.+F.T.)"}
    cols = [
        ("rms_trial6_m", "RMS trial 6 (um)"),
        ("max_trial6_m", "max trial 6 (um)"),
        ("rms_trial10_m", "RMS trial 10 (um)"),
        ("max_trial10_m", "max trial 10 (um)"),
    ]
    print("| law | " + " | ".join(f"{c}: shipped; min / median / max" for _, c in cols) + " |")
    print("| --- |" + " --- |" * len(cols))
    for law in LAWS:
        r = by[law]
        cells = [
            f"{r[0][k] * 1e6:.3f}; {_spread(np.array([x[k] for x in r[1:]]), 1e6, '{:.3f}')}"
            for k, _ in cols
        ]
        print(f"| {labels[law]} | " + " | ".join(cells) + " |")
    n = len(by["silc"])
    swept = [k for k in by["silc"][0] if "." in k and k != "learning.law"]
    for key in ("rms_trial6_m", "max_trial6_m"):
        fails = []
        for v in range(n):
            s, bf, ft = (by[law][v][key] for law in LAWS)
            if not ft < bf < s:
                fails.append(f"v{v} (S {s * 1e6:.3f}, BF {bf * 1e6:.3f}, BF+FT {ft * 1e6:.3f})")
        print(f"{key}: BF+FT < BF < S-ILC fails in {len(fails)} of {n}: {', '.join(fails)}")
    for key in ("rms_trial10_m", "max_trial10_m"):
        ft_bf = [v for v in range(n) if not by["pilc_bfft"][v][key] < by["pilc_bf"][v][key]]
        s_low = [
            v
            for v in range(n)
            if by["silc"][v][key] < min(by["pilc_bf"][v][key], by["pilc_bfft"][v][key])
        ]
        print(
            f"{key}: BF+FT < BF fails in {len(ft_bf)} of {n}: {ft_bf}; S-ILC lowest in {len(s_low)}: {s_low}"
        )
    eq7_all = [by["silc"][v]["eq7_plant"] for v in range(n)]
    print(
        "eq. (7) on the plant per variant: "
        + ", ".join(f"v{v} {x:.3f}" for v, x in enumerate(eq7_all))
    )
    for v in range(1, n):
        row = by["silc"][v]
        print(f"v{v}: " + ", ".join(f"{k.split('.')[-1]} {row[k]}" for k in swept))
    eq7 = np.array([r["eq7_plant"] for r in by["silc"]])
    print(f"eq. (7) on the plant: {eq7.min():.3f} .. {eq7.max():.3f}")


def _dlpid_table(rows: list[dict[str, Any]]) -> None:
    pid = [r for r in rows if r["point"] % 2 == 0]
    dl = [r for r in rows if r["point"] % 2 == 1]
    reduction = np.array(
        [1.0 - d["rmsd_rad"] / p["rmsd_rad"] for p, d in zip(pid, dl, strict=True)]
    )
    print("| figure | shipped | min / median / max over the family |")
    print("| --- | --- | --- |")
    print(
        f"| RMSD, PID alone (rad) | {pid[0]['rmsd_rad']:.4g} | "
        f"{_spread(np.array([r['rmsd_rad'] for r in pid[1:]]), 1.0, '{:.4g}')} |"
    )
    print(
        f"| RMSD, DLPID (rad) | {dl[0]['rmsd_rad']:.4g} | "
        f"{_spread(np.array([r['rmsd_rad'] for r in dl[1:]]), 1.0, '{:.4g}')} |"
    )
    print(
        f"| RMSD reduction against PID (%) | {reduction[0] * 100:.1f} | "
        f"{_spread(reduction[1:], 100.0, '{:.1f}')} |"
    )
    for key, label in (
        ("J_ratio", "J^/J"),
        ("D_ratio", "D^/D"),
        ("U_ratio", "U^/U"),
        ("C_ratio", "C^/C"),
    ):
        print(
            f"| {label} (final) | {dl[0][key]:.3f} | "
            f"{_spread(np.array([r[key] for r in dl[1:]]), 1.0, '{:.3f}')} |"
        )
    fails = [f"v{v} ({reduction[v] * 100:.1f} %)" for v in range(len(dl)) if reduction[v] < 0.9]
    print(f"reduction below 90 % (the paper: 96.2 % in simulation): {', '.join(fails) or 'none'}")
    off = [
        f"v{v} ({k} {r[k]:.2f})"
        for v, r in enumerate(dl)
        for k in ("J_ratio", "D_ratio", "U_ratio")
        if abs(r[k] - 1.0) > 0.05
    ]
    print(f"J, D, U estimates off by more than 5 %: {', '.join(off) or 'none'}")


def main() -> None:
    # The portable numbers (servo_axis.numerics): this process starts again in the pin.
    numerics.restart()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("write", help="write the two study files")
    t = sub.add_parser("table", help="print a study's band as Markdown")
    t.add_argument("name", choices=("ilc_family_001", "dlpid_family_003"))
    t.add_argument(
        "--out", type=Path, default=None, help="the study's folder (default studies/NAME)"
    )
    args = parser.parse_args()
    if args.command == "write":
        write()
    else:
        table(args.name, args.out)


if __name__ == "__main__":
    main()
