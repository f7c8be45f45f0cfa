"""A plant model from a package outside the source tree, found by its entry point.

``test/data/outside_plugin`` is a package of its own (``pyproject.toml``,
setuptools, two entry points): the plant model ``rigid_viscous_axis`` (a
rigid axis with viscous friction, stepped exactly) and the feedforward term
``viscous_ff`` (``b v / (R K_T)``). It is installed offline into a temporary
folder (``pip install --no-deps --no-build-isolation --target``, with the
setuptools of this environment) that only the subprocesses of this test get
on ``PYTHONPATH``: this environment is left as it was. Nothing under
``src/`` names it. The tutorial that shows it (``docs/tutorials/own-plugin.md``)
installs it, lists it and its keys (``list``, ``params``), runs its scenario
through the node graph against the plain-call loop, checks that
docs/parameters.md, the suite's own reference, stays what it is with it
installed, and uninstalls it: ``test_docs_pages.py::test_tutorials_own_plugin``.
Here: its scenario runs through ``python -m servo_axis run`` (a process per
node, lockstep) with the broken plugins of ``test/data/broken_plugin``
installed beside it, each named once on stderr, none stopping a run that
does not use it.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from servo_axis.run.processes import ros_environment

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
PLUGIN = REPO / "test" / "data" / "outside_plugin"
PERIOD_S = 1e-3
#: The plant of the scenario: J, b, K_T.
J, B, KT = 0.01, 0.3, 0.715


@pytest.fixture(scope="module")
def plugin_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder the outside package is installed into (a copy is built: no build/ in test/)."""
    work = tmp_path_factory.mktemp("outside_plugin")
    source = work / "source"
    shutil.copytree(PLUGIN, source)
    site = work / "site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "--quiet",
            "--target",
            str(site),
            str(source),
        ],
        check=True,
        timeout=300,
        env={**os.environ, "PIP_NO_INPUT": "1"},
    )
    assert (site / "servo_axis_outside" / "rigid_axis.py").is_file()
    return site


def python_run(
    site: Path | list[Path], env: dict[str, str], *args: str, timeout: float = 300.0
) -> subprocess.CompletedProcess[str]:
    """This interpreter with the plugin folder(s) on PYTHONPATH (exit code 0)."""
    sites = [str(s) for s in (site if isinstance(site, list) else [site])]
    env = {**env, "PYTHONPATH": os.pathsep.join([*sites, env.get("PYTHONPATH", "")])}
    done = subprocess.run(
        [sys.executable, *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        cwd=REPO,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    return done


def python(site: Path, env: dict[str, str], *args: str, timeout: float = 300.0) -> str:
    """This interpreter with the plugin on PYTHONPATH: its stdout (exit code 0)."""
    return python_run(site, env, *args, timeout=timeout).stdout


def test_the_step_response_of_the_outside_plant_is_its_closed_form(
    plugin_site: Path, tmp_path: Path
) -> None:
    # Built through the registry (plant.model), a current step from rest:
    # theta(t) = (K_T i / b) (t - (1 - e^(-a t)) / a), a = b / J.
    code = (
        "import json\n"
        "from servo_axis.params.factories import build_plant, checked_values\n"
        f"v = checked_values('plant', {{'model': 'rigid_viscous_axis', 'inertia_kgm2': {J},"
        f" 'viscous_Nms_per_rad': {B}, 'torque_constant_Nm_per_A': {KT}}})\n"
        "p = build_plant(v)\n"
        "print(json.dumps([p.step(2.0).angle_rad for _ in range(400)]))\n"
    )
    got = np.array(yaml.safe_load(python(plugin_site, dict(os.environ), "-c", code)))
    a = B / J
    t = PERIOD_S * np.arange(1, 401)
    expected = KT * 2.0 / B * (t - (1.0 - np.exp(-a * t)) / a)
    assert_allclose(got, expected, rtol=1e-9, atol=1e-15)
    # the final velocity K_T i / b is approached: 0.4 s = 12 time constants
    assert_allclose(np.diff(got)[-1] / PERIOD_S, KT * 2.0 / B, rtol=1e-4)


def test_broken_plugins_beside_it_stop_only_the_runs_that_use_them(
    plugin_site: Path, broken_plugin_site: Path, ros_env: int, tmp_path: Path
) -> None:
    run_dir = tmp_path / "run"
    done = python_run(
        [plugin_site, broken_plugin_site],
        ros_environment(ros_env, tmp_path / "ros_log"),
        "-m",
        "servo_axis",
        "run",
        str(PLUGIN / "viscous_axis.yaml"),
        "--out",
        str(run_dir),
        "--no-plots",
    )
    # The broken plant model and term are named once each, the loaded extensions not
    # at all; the run is whole.
    for name in ("missing_axis", "failing_term"):
        assert done.stderr.count(f"'{name}' cannot be loaded") == 1, done.stderr
    assert "rigid_viscous_axis" not in done.stderr and "viscous_ff" not in done.stderr
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["health"]["outcome"] == "complete" and summary["health"]["exit_code"] == 0
    assert summary["steps"] == 500 and summary["message_counts"]["/x/state"] == 500
