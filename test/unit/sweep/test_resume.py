"""A study stopped part way resumes from its manifest: finished points are not run again."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from servo_axis.sweep.engine import MANIFEST, run_study
from servo_axis.sweep.spec import StudyError, load_study


def test_a_second_call_runs_only_the_points_the_manifest_lacks(tmp_path: Path) -> None:
    path = tmp_path / "resume.yaml"
    path.write_text(
        "scenario: pid_disturbance\nset: {/**.duration_s: 0.3}\n"
        "grid: {feedback.bandwidth_hz: [30.0, 40.0, 50.0]}\n"
        "figures: {max: tracking_error.all_samples.max_m}\n"
    )
    study = load_study(path)
    out = tmp_path / "out"
    first = run_study(study, out, workers=1, plots=False, progress=False)
    assert [r["status"] for r in first] == ["ok"] * 3
    manifest = json.loads((out / MANIFEST).read_text())
    del manifest["rows"]["1"]  # as if the study had been stopped before point 1 ended
    manifest["rows"]["0"]["wall_time_s"] = -1.0  # a marker: point 0 must not run again
    (out / MANIFEST).write_text(json.dumps(manifest))
    second = run_study(study, out, workers=1, plots=True, progress=False)
    assert second[0]["wall_time_s"] == -1.0
    assert second[1]["wall_time_s"] > 0
    assert [r["max"] for r in second] == [r["max"] for r in first]
    assert sorted(p.name for p in out.glob("*.png")) == ["max__vs__feedback.bandwidth_hz.png"]

    path.write_text(path.read_text().replace("50.0", "60.0"))
    with pytest.raises(StudyError, match="holds another study's results"):
        run_study(load_study(path), out, workers=1, progress=False)


class _Client:
    """What :func:`check_workers` asks of a dask client: ``run(f)`` on every worker."""

    def __init__(self, answers: dict[str, dict[str, str]]) -> None:
        self.answers = answers

    def run(self, function: object) -> dict[str, dict[str, str]]:
        return self.answers


def test_a_worker_with_other_versions_is_refused_by_name() -> None:
    from servo_axis.sweep.engine import VersionMismatchError, check_workers, versions

    mine = versions()
    assert check_workers(_Client({"tcp://a:1": mine, "tcp://b:2": mine})) == 2
    other = {**mine, "scipy": "1.11.0"}
    with pytest.raises(
        VersionMismatchError,
        match=rf"worker tcp://b:2 refused: .*scipy 1\.11\.0 \(client {mine['scipy']}\)",
    ):
        check_workers(_Client({"tcp://a:1": mine, "tcp://b:2": other}))
