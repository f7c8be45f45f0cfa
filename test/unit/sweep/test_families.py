"""The seeded families of papers 001 and 003 (scripts/study_families.py, issue 21).

The shipped study files are what the script's seed draws; every point is a
valid scenario (the sweep checks them all); and a point's columns are the metric of a direct plain call
(the same RMS over the same samples), on two shortened points.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.testing import assert_allclose

from servo_axis.simulate import simulate_identification, simulate_learning
from servo_axis.sweep.point import run_point
from servo_axis.sweep.spec import scenario_for

REPO = Path(__file__).resolve().parents[3]
STUDIES = REPO / "src" / "servo_axis" / "studies"


def _script() -> Any:
    spec = importlib.util.spec_from_file_location(
        "study_families", REPO / "scripts" / "study_families.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_shipped_families_are_the_seeded_draw() -> None:
    script = _script()
    rng = np.random.default_rng(script.SEED)
    ilc, dlpid = script.ilc_variants(rng), script.dlpid_variants(rng)
    for name, variants, per in (("ilc_family_001", ilc, 3), ("dlpid_family_003", dlpid, 2)):
        study = yaml.safe_load((STUDIES / f"{name}.yaml").read_text())
        assert study["backend"] == "plain"
        points = study["points"]
        assert len(points) == per * (script.VARIANTS + 1)
        assert variants[0] == {}  # variant 0: the shipped case
        for v, variant in enumerate(variants):
            for point in points[per * v : per * (v + 1)]:
                assert {k: point[k] for k in variant} == variant
    # What the methods assume holds at every 001 variant: eq. (7) on the plant below 1.
    for variant in ilc[1:]:
        inertia, damping = variant["plant.inertia_kgm2"], variant["plant.damping_Nms_per_rad"]
        assert script._eq7_on_plant(inertia, damping) < 1.0


def _scenario(tmp_path: Path, study: str, point: dict[str, Any]) -> Path:
    data, _ = scenario_for(study, point)
    path = tmp_path / "point.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_a_family_point_s_columns_are_the_rms_of_a_direct_plain_call(tmp_path: Path) -> None:
    # (load_study checks every point against the schema: 10-30 s for these files.)
    ilc = yaml.safe_load((STUDIES / "ilc_family_001.yaml").read_text())
    point = {**ilc["points"][3 * 1 + 2], "/**.duration_s": 7.0}  # variant 1, pilc_bfft, 7 trials
    figures = {k: v for k, v in ilc["figures"].items() if "trial10" not in k}
    row = run_point(0, ilc["scenario"], point, figures)
    assert row["status"] == "ok", row["error"]
    e = simulate_learning(_scenario(tmp_path, ilc["scenario"], point)).error_m  # trials 1..6
    rms = np.sqrt(np.mean(e**2, axis=1))
    assert_allclose(row["rms_trial5_m"], rms[4], rtol=1e-12)
    assert_allclose(row["rms_trial6_m"], rms[5], rtol=1e-12)
    assert_allclose(row["max_trial6_m"], np.max(np.abs(e[5])), rtol=1e-12)

    dl = yaml.safe_load((STUDIES / "dlpid_family_003.yaml").read_text())
    point = {**dl["points"][2 * 1 + 1], "/**.duration_s": 2.0}  # variant 1, DLPID, 2 s
    row = run_point(1, dl["scenario"], point, dl["figures"])
    assert row["status"] == "ok", row["error"]
    run = simulate_identification(_scenario(tmp_path, dl["scenario"], point))
    traj = run.trajectory
    # RMSD of th_d - th over every sample, th the measured (encoder) angle.
    rmsd = np.sqrt(np.mean((traj.reference_rad - traj.encoder_rad) ** 2))
    assert_allclose(row["rmsd_rad"], rmsd, rtol=1e-12)
    true_j = point["plant.inertia_kgm2"]
    assert_allclose(row["J_ratio"], run.estimates[-1, 2] / true_j, rtol=1e-12)
