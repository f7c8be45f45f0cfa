"""``identify`` on a run of the node graph: the same fit as the plain calls, a scenario that runs, bad input.

One short excitation run (``measure_frf_ball_screw`` cut to 3 s: periods
of 0.5 s, 1 to settle and 3 averaged) through ``python -m servo_axis run``;
``identify`` on its directory must give exactly what the plain-call loop of
the same scenario gives (the node graph reproduces it bit for bit), the
scenario it writes must run through the node graph as it is, and bad input
must be one line and exit 2.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from numpy.testing import assert_allclose
from run_support import CONFIG

from servo_axis.__main__ import main
from servo_axis.identify.data import from_simulation
from servo_axis.identify.driver import identify
from servo_axis.params.scenario import load_scenario
from servo_axis.run.processes import ros_environment

pytestmark = pytest.mark.integration


def _cli(domain: int, tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "servo_axis", *args],
        env=ros_environment(domain, tmp_path / "ros_log"),
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def test_identify_a_node_graph_run(
    ros_env: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = load_scenario(CONFIG / "measure_frf_ball_screw.yaml")
    data["/**"]["ros__parameters"]["duration_s"] = 3.0
    data["feedforward"]["ros__parameters"]["excitation"].update(
        period_s=0.5, periods=3, settle_periods=1, start_s=1.0
    )
    scenario = tmp_path / "frf_short.yaml"
    scenario.write_text(yaml.safe_dump(data, sort_keys=False))
    run = tmp_path / "frf"
    done = _cli(
        ros_env,
        tmp_path,
        "run",
        str(scenario),
        "--out",
        str(run),
        "--domain-id",
        str(ros_env),
        "--no-plots",
    )
    assert done.returncode == 0, done.stderr[-3000:]

    out = tmp_path / "fitted.yaml"
    code = main(
        [
            "identify",
            str(run),
            "--model",
            "ball_screw",
            "--out",
            str(out),
            "--report",
            str(tmp_path / "report"),
        ]
    )
    assert code == 0, capsys.readouterr().err
    # The fit of the recorded run is the fit of the plain-call loop, key for key.
    plain = identify("ball_screw", [from_simulation(scenario)])
    written = yaml.safe_load(out.read_text())["plant"]["ros__parameters"]
    assert_allclose(written["inertia_kgm2"], plain.key("inertia_kgm2").value, rtol=1e-12)
    assert_allclose(
        written["modes"]["frequency_hz"][0], plain.key("modes.frequency_hz[0]").value, rtol=1e-12
    )
    truth = data["plant"]["ros__parameters"]
    assert_allclose(written["inertia_kgm2"], truth["inertia_kgm2"], rtol=0.03)
    assert_allclose(written["modes"]["frequency_hz"], truth["modes"]["frequency_hz"], rtol=0.03)
    for name in ("report.md", "bode_encoder.png"):
        assert (tmp_path / "report" / name).is_file()

    # The run directory is all identify needs: the scenario file moved, and one
    # edited in its place (another excitation, another plant) change nothing.
    scenario.rename(tmp_path / "moved.yaml")
    edited = load_scenario(tmp_path / "moved.yaml")
    edited["feedforward"]["ros__parameters"]["excitation"]["settle_periods"] = 2
    edited["plant"]["ros__parameters"]["current_limit_A"] = 12.3  # a key the fit copies
    scenario.write_text(yaml.safe_dump(edited, sort_keys=False))
    (tmp_path / "after_the_move").mkdir()
    again_out = tmp_path / "after_the_move" / out.name  # the name is the file's stem
    assert main(["identify", str(run), "--model", "ball_screw", "--out", str(again_out)]) == 0
    assert yaml.safe_load(again_out.read_text()) == yaml.safe_load(out.read_text())

    def fitted(path: Path) -> list[str]:  # the header's "key = value +- error (source)" lines
        return [s for s in path.read_text().splitlines() if s.startswith("#   ") and " = " in s]

    assert len(fitted(out)) > 3 and fitted(again_out) == fitted(out)

    # The written scenario runs as it is (the excitation off: the measurement's move).
    again = tmp_path / "again"
    done = _cli(
        ros_env,
        tmp_path,
        "run",
        str(out),
        "--out",
        str(again),
        "--domain-id",
        str(ros_env),
        "--no-plots",
    )
    assert done.returncode == 0, done.stderr[-3000:]

    # Bad input: one line on stderr, exit 2.
    bad = {
        "no excitation": (str(again), "ball_screw"),
        "the data do not determine": (str(run), "elastic_ball_screw"),
        "not a run directory": (str(tmp_path / "missing"), "ball_screw"),
    }
    capsys.readouterr()
    for words, (run_dir, model) in bad.items():
        code = main(["identify", run_dir, "--model", model, "--out", str(tmp_path / "x.yaml")])
        err = capsys.readouterr().err
        assert code == 2, (words, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], (words, err)
    assert not (tmp_path / "x.yaml").exists()
