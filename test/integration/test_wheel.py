"""The package ships whole: the wheel holds every file a shipped scenario names, and runs.

The wheel is built once (``pip wheel . --no-deps --no-build-isolation``).
A new virtual environment (``venv --without-pip``) gets the wheel's contents
on ``PYTHONPATH`` and this environment's site-packages for the dependencies
(ROS 2 from PyPI, numpy, ...; their shared libraries on ``LD_LIBRARY_PATH``
and their ``share/`` on ``AMENT_PREFIX_PATH``, as the ROS wheels' bootstrap
would set them for this environment), so nothing of the checkout is on the
path: a scenario that names a data file runs from there, from a working
directory outside the checkout.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from servo_axis.params.scenario import flatten, load_scenario

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
SCENARIOS = REPO / "src" / "servo_axis" / "scenarios"


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            str(REPO),
            "--no-deps",
            "--no-build-isolation",
            "--quiet",
            "--wheel-dir",
            str(out),
        ],
        check=True,
        cwd=REPO,
        timeout=300,
    )
    (path,) = out.glob("servo_axis-*.whl")
    return path


def referenced_files(scenario: Path) -> list[str]:
    """The files a scenario names (keys ending in ``.file``), relative to the package."""
    found = []
    for section in load_scenario(scenario).values():
        for key, value in flatten(section["ros__parameters"]).items():
            if key.endswith(".file") and isinstance(value, str) and value:
                target = (scenario.parent / value).resolve()
                found.append(target.relative_to(SCENARIOS.parents[1]).as_posix())
    return found


def test_the_wheel_holds_every_file_a_shipped_scenario_names(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    scenarios = sorted(SCENARIOS.glob("*.yaml"))
    assert len(scenarios) >= 20
    named = {s.name: referenced_files(s) for s in scenarios}
    assert "servo_axis/scenarios/gms_elastic_ball_screw.txt" in named["slow_reversal_gms.yaml"]
    assert (
        "servo_axis/scenarios/friction_table_ball_screw_x.csv" in named["ptc_friction_table.yaml"]
    )
    for scenario, files in named.items():
        assert f"servo_axis/scenarios/{scenario}" in names
        for file in files:
            assert (REPO / "src" / file).is_file(), f"{scenario}: {file} is not in the checkout"
            assert file in names, f"{scenario} names {file}, which the wheel lacks"
    assert "servo_axis/data/fastdds_localhost.xml" in names
    # The outside nodes the docs point to (examples/ of a checkout links to them).
    examples = sorted(p.name for p in (REPO / "examples").glob("*.py"))
    assert {"pd_controller.py", "sine_reference.py", "watch_run.py"} <= set(examples)
    for example in examples:
        assert f"servo_axis/examples/{example}" in names, f"the wheel lacks examples/{example}"
    info = next(n for n in names if n.endswith(".dist-info/METADATA")).rsplit("/", 1)[0]
    licence = zipfile.ZipFile(wheel).read(f"{info}/licenses/LICENSE").decode()
    assert "Apache License" in licence and "Version 2.0, January 2004" in licence
    entry = zipfile.ZipFile(wheel).read(f"{info}/entry_points.txt").decode()
    assert "servo-axis = servo_axis.__main__:console" in entry


def test_a_shipped_scenario_with_a_data_file_runs_from_the_installed_wheel(
    wheel: Path, tmp_path: Path, ros_env: int
) -> None:
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    deps = Path(sysconfig.get_paths()["purelib"])
    (venv_site,) = (venv / "lib").glob("python3*/site-packages")
    (venv_site / "dependencies.pth").write_text(f"{deps}\n")  # no .pth of deps/ is run
    libs = [str(p) for p in sorted(deps.glob("ros_*.libs"))] + [str(Path(sys.prefix) / "lib")]
    env = {
        "PATH": "/usr/bin:/bin",
        "HOME": os.environ.get("HOME", "/tmp"),
        "PYTHONPATH": str(site),
        "LD_LIBRARY_PATH": os.pathsep.join(libs),
        "AMENT_PREFIX_PATH": sys.prefix,
        "_ROS_WHEELS_BOOTSTRAP_COMPLETE": "1",  # what ros_wheels_bootstrapper sets
        "ROS_DOMAIN_ID": str(ros_env),
    }
    away = tmp_path / "elsewhere"
    away.mkdir()
    python = str(venv / "bin" / "python")
    where = subprocess.run(
        [python, "-c", "import servo_axis; print(servo_axis.__file__)"],
        env=env,
        cwd=away,
        capture_output=True,
        text=True,
        check=True,
    )
    assert where.stdout.strip() == str(site / "servo_axis" / "__init__.py")
    # The console command of the wheel's entry point.
    helped = subprocess.run(
        [
            python,
            "-c",
            "from importlib.metadata import entry_points as e; import sys; "
            "sys.argv = ['servo-axis', '--help']; sys.exit(e(group='console_scripts')"
            "['servo-axis'].load()())",
        ],
        env=env,
        cwd=away,
        capture_output=True,
        text=True,
    )
    assert helped.returncode == 0, helped.stderr
    assert helped.stdout.startswith("usage: servo-axis [-h] COMMAND ...")
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [python, "-m", "servo_axis", "run", "slow_reversal_gms", "--out", str(out)],
        env=env,
        cwd=away,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        stdout, stderr = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 0, stderr
    assert "run directory:" in stdout
    assert (out / "summary.json").is_file() and (out / "cycle_errors.png").is_file()
    assert str(site / "servo_axis" / "scenarios") in (out / "summary.json").read_text()
    assert list(away.iterdir()) == []  # nothing written where it ran
