"""simulate_identification (paper 003) on 1 s copies of the shipped scenarios: its schedule."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.core.identification.online.dlpid import Dlpid
from servo_axis.params import factories, resolve
from servo_axis.params.scenario import load_scenario
from servo_axis.simulate import IdentificationRun, simulate_identification
from servo_axis.wire.cdr import ESTIMATE_LABELS
from servo_axis.wire.layouts import check_estimate_values

CONFIG = Path(__file__).resolve().parents[2] / "config"
DURATION_S = 1.0
COLUMN = {label: i for i, label in enumerate(ESTIMATE_LABELS)}
PARAMETERS = ["inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm", "coulomb_Nm"]
FLAGS = [label for label in ESTIMATE_LABELS if label.startswith("updated_")]


def short_copy(
    tmp_path: Path, name: str, sections: dict[str, dict[str, Any]] | None = None
) -> Path:
    """The scenario ``name`` cut to DURATION_S, with top-level keys of ``sections`` replaced."""
    data = yaml.safe_load((CONFIG / f"{name}.yaml").read_text())
    data["/**"]["ros__parameters"]["duration_s"] = DURATION_S
    for section, change in (sections or {}).items():
        data[section]["ros__parameters"].update(change)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def schedule(path: Path) -> tuple[int, int, int]:
    """``(steps, R, L)``: run length, RLS period and latency in control samples."""
    scenario = load_scenario(path)
    iv = resolve.node_values(scenario, "identifier")
    tu = iv["control_period_s"]
    steps = round(iv["duration_s"] / tu)
    return steps, round(iv["rls_period_s"] / tu), round(iv["latency_s"] / tu)


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, IdentificationRun]]:
    tmp = tmp_path_factory.mktemp("scenarios")
    out = {}
    for name in ("dlpid_tilt_lpf2", "dlpid_tilt_lpf100", "dlpid_tilt_marc", "dlpid_tilt_pid"):
        path = short_copy(tmp, name)
        out[name] = (path, simulate_identification(path))
    return out


IDENTIFIED = ["dlpid_tilt_lpf2", "dlpid_tilt_lpf100", "dlpid_tilt_marc"]


@pytest.mark.parametrize("name", IDENTIFIED)
def test_one_estimate_per_rls_period_that_applies_inside_the_run(
    runs: dict[str, tuple[Path, IdentificationRun]], name: str
) -> None:
    path, run = runs[name]
    steps, r, latency = schedule(path)
    assert len(run.trajectory.encoder_rad) == steps == round(DURATION_S / 4e-4)
    assert run.estimates.shape[1] == len(ESTIMATE_LABELS)
    expected = []
    n = 0
    while (k := (n + 1) * r - 1) + 1 + latency < steps:
        expected.append(k)
        n += 1
    assert len(expected) > 100
    assert_array_equal(run.estimates[:, COLUMN["step"]], expected)
    # Each applies from k + 1 + L, and the last that would apply inside the run is in.
    assert_array_equal(
        run.estimates[:, COLUMN["applies_from_step"]],
        run.estimates[:, COLUMN["step"]] + 1 + latency,
    )
    assert expected[-1] + r + 1 + latency >= steps


@pytest.mark.parametrize("name", IDENTIFIED)
def test_every_row_is_an_estimate_message_the_feedforward_accepts(
    runs: dict[str, tuple[Path, IdentificationRun]], name: str
) -> None:
    _, run = runs[name]
    for row in run.estimates:
        e = check_estimate_values(row.tolist())
        assert e.values() == row.tolist()


def test_marc_estimates_no_friction(runs: dict[str, tuple[Path, IdentificationRun]]) -> None:
    _, marc = runs["dlpid_tilt_marc"]
    assert np.all(marc.estimates[:, COLUMN["coulomb_Nm"]] == 0.0)
    assert np.all(marc.estimates[:, COLUMN["updated_coulomb"]] == 0.0)
    # DLPID on the same run does estimate it.
    _, dlpid = runs["dlpid_tilt_lpf2"]
    assert np.any(dlpid.estimates[:, COLUMN["updated_coulomb"]] == 1.0)
    assert np.any(dlpid.estimates[:, COLUMN["coulomb_Nm"]] > 0.0)


@pytest.mark.parametrize("name", IDENTIFIED)
def test_no_update_before_the_filters_warm_up(
    runs: dict[str, tuple[Path, IdentificationRun]], name: str
) -> None:
    path, run = runs[name]
    iv = resolve.node_values(load_scenario(path), "identifier")
    ident = factories.build_identifier(iv)
    assert isinstance(ident, Dlpid)
    warmup = ident.params.warmup_samples
    steps = run.estimates[:, COLUMN["step"]]
    early = run.estimates[steps + 1 <= warmup]  # samples 0..k: k + 1 of them
    assert len(early) >= 10
    flags = [COLUMN[f] for f in FLAGS]
    assert np.all(early[:, flags] == 0.0)
    # Nothing moved: the initial estimates of the scenario, and no PE index yet.
    initial = [
        iv["nominal.inertia_kgm2"],
        iv["nominal.damping_Nms_per_rad"],
        iv["initial.unbalance_Nm"],
        iv.get("initial.coulomb_Nm", 0.0),
    ]
    for row in early:
        assert row[[COLUMN[p] for p in PARAMETERS]].tolist() == initial
        assert row[COLUMN["kappa"]] == 0.0
    # Later, the layers do run (the test above is not vacuous).
    assert np.any(run.estimates[steps + 1 > warmup][:, flags] == 1.0)


def test_pid_alone_has_no_estimates_and_no_feedforward_current(
    runs: dict[str, tuple[Path, IdentificationRun]],
) -> None:
    _, pid = runs["dlpid_tilt_pid"]
    assert pid.estimates.shape == (0, len(ESTIMATE_LABELS))
    assert np.all(pid.trajectory.feedforward_Nm == 0.0)
    assert len(pid.trajectory.feedforward_Nm) == round(DURATION_S / 4e-4)
    # The axis moved all the same, along the reference.
    assert np.ptp(pid.trajectory.reference_rad) > 0.1
    # With the identifier the feedforward does give a current.
    _, lpf2 = runs["dlpid_tilt_lpf2"]
    assert np.any(lpf2.trajectory.feedforward_Nm != 0.0)


def test_the_run_is_deterministic(runs: dict[str, tuple[Path, IdentificationRun]]) -> None:
    path, run = runs["dlpid_tilt_lpf2"]
    again = simulate_identification(path)
    assert_array_equal(again.estimates, run.estimates)
    assert_array_equal(again.trajectory.command_Nm, run.trajectory.command_Nm)


def test_true_parameters_inside_tight_bounds_stay_there(tmp_path: Path) -> None:
    original = yaml.safe_load((CONFIG / "dlpid_tilt_lpf2.yaml").read_text())
    truth = original["plant"]["ros__parameters"]
    j, d, u, c = (
        truth["inertia_kgm2"],
        truth["damping_Nms_per_rad"],
        truth["unbalance_Nm"],
        truth["coulomb_Nm"],
    )
    rel = 0.01

    def tight(v: float) -> list[float]:
        return [v * (1.0 - rel), v * (1.0 + rel)]

    nominal = {
        **original["/**"]["ros__parameters"]["nominal"],
        "inertia_kgm2": j,
        "damping_Nms_per_rad": d,
    }
    path = short_copy(
        tmp_path,
        "dlpid_tilt_lpf2",
        {
            "/**": {"nominal": nominal, "duration_s": DURATION_S},
            "identifier": {
                "initial": {"unbalance_Nm": u, "coulomb_Nm": c},
                "bounds": {
                    "inertia_kgm2": tight(j),
                    "damping_Nms_per_rad": tight(d),
                    "unbalance_Nm": tight(u),
                    "coulomb_Nm": tight(c),
                },
            },
        },
    )
    run = simulate_identification(path)
    assert len(run.estimates) > 100
    est = run.estimates[:, [COLUMN[p] for p in PARAMETERS]]
    for i, v in enumerate((j, d, u, c)):
        lo, hi = tight(v)
        assert np.all((est[:, i] >= lo) & (est[:, i] <= hi)), PARAMETERS[i]
    assert_allclose(est, np.tile([j, d, u, c], (len(est), 1)), rtol=rel, atol=0.0)
    # The first estimates are the true values exactly (given as the initial ones).
    assert est[0].tolist() == [j, d, u, c]
    # And the bounds were hit, or the RLS moved: something was updated.
    assert np.any(run.estimates[:, [COLUMN[f] for f in FLAGS]] == 1.0)
