"""Study edges a user meets: a figure typo, its correction, a missing scheduler, boolean keys."""

from __future__ import annotations

import math
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from servo_axis.__main__ import main
from servo_axis.sweep import engine
from servo_axis.sweep.engine import MANIFEST, plot_figures, run_study
from servo_axis.sweep.point import run_point
from servo_axis.sweep.spec import Study, StudyError, figure_problem, load_study

BASE = "scenario: pid_disturbance\nset: {/**.duration_s: 0.2}\ngrid: {feedback.bandwidth_hz: [30.0, 40.0]}\n"


def write(tmp_path: Path, figures: str) -> Path:
    path = tmp_path / "edge.yaml"
    path.write_text(BASE + f"figures: {figures}\n")
    return path


def test_a_figure_typo_is_refused_before_any_point_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, "{max: tracking_error.all_sample.max_m}")
    with pytest.raises(StudyError, match=r"'figures\.max': .*did you mean 'all_samples'"):
        load_study(path)
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no 'all_sample' at 'tracking_error'" in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("path", "kind", "problem"),
    [
        ("tracking_error.all_samples.max_m", "plain", None),
        ("tracking_error.cycles[-1].rms_m", "nodes", None),
        ("identification.final_ratio.inertia_kgm2", "plain", None),
        ("ilc_convergence.plant", "plain", None),  # a mapping: its keys are the run's
        ("axes.x.tracking_error.all_samples.max_m", "axes", None),
        ("realtime.misses", "nodes", None),
        ("realtime.misses", "plain", "no 'realtime' at '.' of a plain point's summary"),
        ("tracking_error.cycles.rms_m", "plain", "'tracking_error.cycles' is a list"),
        ("steps.x", "nodes", "'steps' is a value (int), not a block"),
        ("tracking_error[0]", "nodes", "[0] at 'tracking_error', which is a block"),
    ],
)
def test_a_figure_path_is_checked_against_the_summary_layout(
    path: str, kind: str, problem: str | None
) -> None:
    found = figure_problem(path, kind)
    assert (found is None) if problem is None else (found is not None and problem in found)


def test_a_rotary_table_s_figures_name_its_errors_in_rad(tmp_path: Path) -> None:
    """issue 43: the tilting table's summary held rad under ``rms_m``; now ``rms_rad``."""
    assert figure_problem("tracking_error.cycles[-1].rms_rad", "plain", unit="rad") is None
    assert figure_problem("sysid.bode_db", "plain") is None  # the excitation's block
    problem = figure_problem("tracking_error.all_samples.rms_m", "nodes", unit="rad")
    assert problem is not None and "did you mean 'rms_rad'?" in problem
    assert figure_problem("tracking_error.all_samples.rms_rad", "plain") is not None
    tilt = tmp_path / "tilt.yaml"
    tilt.write_text(
        "scenario: dlpid_tilt_pid\nset: {/**.duration_s: 0.2}\n"
        "grid: {feedback.bandwidth_hz: [5.0]}\nfigures: {rmsd: tracking_error.all_samples.rms_m}\n"
    )
    with pytest.raises(StudyError, match=r"'figures\.rmsd': .*rotary table are in rad"):
        load_study(tilt)
    tilt.write_text(tilt.read_text().replace("rms_m", "rms_rad"))
    study = load_study(tilt)
    row = run_point(0, study.scenario, study.points[0], study.figures)
    assert row["status"] == "ok", row["error"]
    # The figure is the run's RMSD in rad: the plain-call loop's r - y, independently.
    from servo_axis.params.scenario import find_scenario, load_scenario
    from servo_axis.simulate import simulate
    from servo_axis.sweep.spec import apply_override, dump_scenario

    data = load_scenario(find_scenario("dlpid_tilt_pid"))
    for key, value in {"/**.duration_s": 0.2, "feedback.bandwidth_hz": 5.0}.items():
        apply_override(data, key, value)
    dump_scenario(data, tmp_path / "point.yaml")
    traj = simulate(tmp_path / "point.yaml")
    assert math.isclose(
        row["rmsd"],
        float(((traj.reference_rad - traj.encoder_rad) ** 2).mean() ** 0.5),
        rel_tol=1e-9,
    )


def test_the_shipped_identification_study_loads() -> None:
    """Its figures are paths into the ``sysid`` block of a plain point (refused before)."""
    study = load_study("identification_excitation")
    assert len(study.points) == 12 and study.figures["bode_db"] == "sysid.bode_db"


def test_the_corrected_study_runs_in_the_same_folder(tmp_path: Path) -> None:
    # A path the layout allows but this run lacks: every point fails on it.
    path = write(tmp_path, "{conv: ilc_convergence.plant}")
    out = tmp_path / "out"
    first = run_study(load_study(path), out, workers=1, plots=False, progress=False)
    assert [r["status"] for r in first] == ["failed", "failed"]
    assert "no 'ilc_convergence'" in first[0]["error"]
    path = write(tmp_path, "{max: tracking_error.all_samples.max_m}")
    second = run_study(load_study(path), out, workers=1, plots=False, progress=False)
    assert [r["status"] for r in second] == ["ok", "ok"]
    assert all(r["max"] > 0 and "conv" not in r for r in second)
    # Other points are still another study.
    (tmp_path / "edge.yaml").write_text(
        (tmp_path / "edge.yaml").read_text().replace("40.0", "50.0")
    )
    with pytest.raises(StudyError, match="holds another study's results"):
        run_study(load_study(path), out, workers=1, progress=False)


def test_an_unreachable_scheduler_leaves_no_folder(tmp_path: Path) -> None:
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "out"
    with pytest.raises(StudyError, match=rf"--scheduler tcp://127.0.0.1:{port}: no dask sched"):
        run_study(
            load_study(write(tmp_path, "[tracking_error.all_samples.max_m]")),
            out,
            scheduler=f"tcp://127.0.0.1:{port}",
            connect_timeout_s=1.0,
            progress=False,
        )
    assert not out.exists()


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[Any]]:
    """The figures plot_figures closes, kept open for inspection."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kept: list[Any] = []
    monkeypatch.setattr(plt, "close", kept.append)
    yield kept
    monkeypatch.undo()
    for fig in kept:
        plt.close(fig)


def test_a_key_that_follows_from_the_swept_one_splits_no_line(
    tmp_path: Path, figures: list[Any]
) -> None:
    """reversal_004: gms.enabled and sigmoid.enabled are each other's negation. Against
    gms.enabled that made ten one-point lines under a ten-entry legend; now one line per
    frequency from GMS to sigmoid, and against the frequency one line per law."""
    freqs = (0.5, 1.0, 1.5, 2.0, 3.0)
    keys = ("reference.frequency_hz", "gms.enabled", "sigmoid.enabled")
    rows = [
        {
            "point": i,
            keys[0]: f,
            keys[1]: gms,
            keys[2]: not gms,
            "max_m": (2.0 + f) * 1e-6 * (1.1 if gms else 1.0),
            "status": "ok",
        }
        for i, (gms, f) in enumerate((g, f) for g in (True, False) for f in freqs)
    ]
    study = Study(
        name="rev",
        scenario="fast_reversal_gms",
        backend="plain",
        parameters=keys,
        points=tuple({k: r[k] for k in keys} for r in rows),
        figures={"max_m": "tracking_error.all_samples.max_m"},
    )
    written = plot_figures(rows, study, tmp_path)
    assert [p.name for p in written] == [f"max_m__vs__{k}.png" for k in keys]
    by_freq, by_gms, _ = (fig.axes[0] for fig in figures)
    assert [len(line.get_xdata()) for line in by_gms.get_lines()] == [2] * 5
    labels = by_gms.get_legend().get_texts()
    assert [t.get_text() for t in labels] == [f"reference.frequency_hz={f}" for f in freqs]
    assert [len(line.get_xdata()) for line in by_freq.get_lines()] == [5, 5]
    assert [t.get_text() for t in by_freq.get_legend().get_texts()] == [
        "gms.enabled=True",
        "gms.enabled=False",
    ]
    assert math.isclose(by_freq.get_lines()[0].get_ydata()[-1], 5.5, rel_tol=1e-12)


def test_points_that_differ_in_every_key_are_markers_without_a_legend(
    tmp_path: Path, figures: list[Any]
) -> None:
    keys = ("a", "b")
    rows = [
        {"point": i, "a": float(i), "b": float(i * i % 5), "y": float(i), "status": "ok"}
        for i in range(5)
    ]
    study = Study("s", "pid_disturbance", "plain", keys, tuple({}), {"y": "steps"})
    plot_figures(rows, study, tmp_path)
    ax = figures[1].axes[0]  # y against b: a is another value for every point
    (line,) = ax.get_lines()
    assert line.get_linestyle() == "None" and ax.get_legend() is None
    assert sorted(line.get_ydata()) == [0.0, 1.0, 2.0, 3.0, 4.0]


def test_the_manifest_names_its_runs_fingerprint(tmp_path: Path) -> None:
    study = load_study(write(tmp_path, "[tracking_error.all_samples.max_m]"))
    run_study(study, tmp_path / "out", workers=1, plots=False, progress=False)
    import json

    data = json.loads((tmp_path / "out" / MANIFEST).read_text())
    assert data["runs_fingerprint"] == study.runs_fingerprint() != study.fingerprint()
    assert engine.resume_command(study, tmp_path / "out", None) == (
        f"python -m servo_axis sweep {tmp_path / 'edge.yaml'} --out {tmp_path / 'out'}"
    )
