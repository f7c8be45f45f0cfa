"""A plant model and a feedforward term from a package outside the source tree, by entry points.

``test/data/outside_plugin`` is a package of its own (``pyproject.toml``,
setuptools, two entry points): the plant model ``rigid_viscous_axis`` (a
rigid axis with viscous friction, stepped exactly) and the feedforward term
``viscous_ff`` (``b v / (R K_T)``). It is installed offline into a temporary
folder (``pip install --no-deps --no-build-isolation --target``, with the
setuptools of this environment) that only the subprocesses of this test get
on ``PYTHONPATH``: this environment is left as it was. Nothing under
``src/`` names it; a scenario does, and runs through the plain-call loop
(:func:`servo_axis.simulate.simulate`) and through ``python -m servo_axis run``
(a process per node, lockstep) with identical numbers, with the broken
plugins of ``test/data/broken_plugin`` installed beside it (each named once
on stderr, none stopping a run that does not use it). ``list`` and
``params`` show it; docs/parameters.md, the suite's own reference, stays
what it is without it (``pytest test/unit`` passes with it installed).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.recording.reader import read_raw
from servo_axis.run.processes import ros_environment
from servo_axis.wire import cdr

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
PLUGIN = REPO / "test" / "data" / "outside_plugin"
PERIOD_S = 1e-3
#: The plant of the scenario: J, b, K_T.
J, B, KT = 0.01, 0.3, 0.715

SCENARIO: dict[str, Any] = {
    "/**": {
        "ros__parameters": {
            "scenario": {
                "name": "outside_plugin",
                "description": "a plant model and a feedforward term of an outside package",
            },
            "control_period_s": PERIOD_S,
            "duration_s": 0.5,
            "nominal": {
                "torque_constant_Nm_per_A": KT,
                "inertia_kgm2": J,
                "damping_Nms_per_rad": 0.0,
            },
        }
    },
    "plant": {
        "ros__parameters": {
            "model": "rigid_viscous_axis",
            "inertia_kgm2": J,
            "viscous_Nms_per_rad": B,
            "torque_constant_Nm_per_A": KT,
        }
    },
    "feedback": {"ros__parameters": {"bandwidth_hz": 40.0}},
    "feedforward": {
        "ros__parameters": {
            "reference": {
                "kind": "sine",
                "amplitude_m": 0.005,
                "frequency_hz": 2.0,
                "offset_m": 0.005,
                "phase_rad": -1.5707963267948966,
            },
            "viscous_ff": {"enabled": True, "coefficient_Nms_per_rad": B},
        }
    },
    "recorder": {"ros__parameters": {}},
}


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


def write_scenario(path: Path, *, viscous_ff: bool = True) -> Path:
    data = yaml.safe_load(yaml.safe_dump(SCENARIO))
    data["feedforward"]["ros__parameters"]["viscous_ff"]["enabled"] = viscous_ff
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


SIMULATE = """
import sys
from pathlib import Path
import numpy as np
from servo_axis.simulate import simulate
t = simulate(Path(sys.argv[1]))
np.savez(sys.argv[2], **{f: getattr(t, f) for f in t.__dataclass_fields__})
"""


def simulated(site: Path, scenario: Path, out: Path) -> dict[str, np.ndarray]:
    python(site, dict(os.environ), "-c", SIMULATE, str(scenario), str(out))
    with np.load(out) as data:
        return {k: data[k] for k in data.files}


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
        # Its values: a class made from its schema at run time; the term's: its own.
        f"assert type(v).__name__ == 'RigidViscousAxisValues' and v.inertia_kgm2 == {J}\n"
        "from servo_axis_outside.viscous_term import ViscousFfValues\n"
        "ff = checked_values('feedforward', {'viscous_ff.coefficient_Nms_per_rad': 0.5})\n"
        "assert isinstance(ff, ViscousFfValues) and ff.viscous_ff.coefficient_Nms_per_rad == 0.5\n"
        "print(json.dumps([p.step(2.0).angle_rad for _ in range(400)]))\n"
    )
    got = np.array(yaml.safe_load(python(plugin_site, dict(os.environ), "-c", code)))
    a = B / J
    t = PERIOD_S * np.arange(1, 401)
    expected = KT * 2.0 / B * (t - (1.0 - np.exp(-a * t)) / a)
    assert_allclose(got, expected, rtol=1e-9, atol=1e-15)
    # the final velocity K_T i / b is approached: 0.4 s = 12 time constants
    assert_allclose(np.diff(got)[-1] / PERIOD_S, KT * 2.0 / B, rtol=1e-4)


def test_a_scenario_naming_the_outside_extensions_runs_identically_in_nodes_and_plain_calls(
    plugin_site: Path, broken_plugin_site: Path, ros_env: int, tmp_path: Path
) -> None:
    scenario = write_scenario(tmp_path / "outside_plugin.yaml")
    core = simulated(plugin_site, scenario, tmp_path / "core.npz")
    run_dir = tmp_path / "run"
    env = ros_environment(ros_env, tmp_path / "ros_log")
    # Broken plugins installed too: they stop only a scenario that uses them.
    done = python_run(
        [plugin_site, broken_plugin_site],
        env,
        "-m",
        "servo_axis",
        "run",
        str(scenario),
        "--out",
        str(run_dir),
        "--no-plots",
    )
    # The broken plant model and term are named once each, the loaded extensions not at all.
    for name in ("missing_axis", "failing_term"):
        assert done.stderr.count(f"'{name}' cannot be loaded") == 1, done.stderr
    assert "rigid_viscous_axis" not in done.stderr and "viscous_ff" not in done.stderr
    state: dict[int, Any] = {}
    command: dict[int, Any] = {}
    for m in read_raw(run_dir / "bag"):
        if m.topic in ("/x/state", "/x/command"):
            js = cdr.decode("sensor_msgs/msg/JointState", m.data)
            step = round(js.stamp_ns / (PERIOD_S * 1e9))
            (state if m.topic == "/x/state" else command)[step] = js
    steps = len(core["encoder_rad"])
    assert steps == 500 and sorted(state) == list(range(steps)) == sorted(command)
    # Bit for bit: the nodes and the plain calls build the same objects.
    assert_array_equal([state[k].position[0] for k in range(steps)], core["encoder_rad"])
    assert_array_equal([state[k].position[1] for k in range(steps)], core["scale_m"])
    assert_array_equal([command[k].effort[0] for k in range(steps)], core["command_Nm"])
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary.get("error_unit") is None  # the entry says linear: an error in m
    # The term does something: without it, the viscous friction the PTC's
    # nominal model (D_n = 0) does not know is left to the PID.
    bare = simulated(
        plugin_site, write_scenario(tmp_path / "bare.yaml", viscous_ff=False), tmp_path / "b.npz"
    )
    lead = 1.91e-3

    def rms(t: dict[str, np.ndarray]) -> float:
        return float(np.sqrt(np.mean((lead * t["reference_rad"] - t["scale_m"]) ** 2)))

    print(f"RMS error with viscous_ff {rms(core) * 1e6:.3f} um, without {rms(bare) * 1e6:.3f} um")
    assert rms(core) < 0.2 * rms(bare), (rms(core), rms(bare))


def test_list_and_params_show_the_outside_extensions_and_the_reference_stays_the_suite_s(
    plugin_site: Path,
) -> None:
    listed = python(plugin_site, dict(os.environ), "-m", "servo_axis", "list")
    (row,) = [line for line in listed.splitlines() if line.split()[:1] == ["rigid_viscous_axis"]]
    assert row.endswith(
        "[servo_axis_outside.rigid_axis:PLANT_MODEL, servo-axis-outside-plugin 0.1.0]"
    )
    assert "viscous_ff.coefficient_Nms_per_rad" in listed
    # Its keys with their defaults, units, ranges and meanings, from its own schema.
    shown = python(
        plugin_site, dict(os.environ), "-m", "servo_axis", "params", "rigid_viscous_axis"
    )
    head, *rows = shown.splitlines()
    assert head == (
        "plant (model rigid_viscous_axis)  [servo_axis_outside.rigid_axis:PLANT_MODEL, "
        "servo-axis-outside-plugin 0.1.0]"
    )
    (viscous,) = [r for r in rows if r.split()[:1] == ["viscous_Nms_per_rad"]]
    # Param(0.2, unit="N m s/rad", above=0.0, meaning=...) of rigid_axis.py
    assert viscous.split()[1:7] == ["0.2", "N", "m", "s/rad", ">", "0"]
    assert viscous.endswith("b: viscous friction torque per rad/s")
    every = python(plugin_site, dict(os.environ), "-m", "servo_axis", "params")
    assert "\nfeedforward (term viscous_ff)  [servo_axis_outside.viscous_term:TERM, " in every
    # docs/parameters.md is the shipped package's: unchanged by what is installed.
    script = str(REPO / "scripts" / "parameter_docs.py")
    checked = python(plugin_site, dict(os.environ), script, "--check")
    assert checked.strip().endswith("docs/parameters.md is up to date")
    page = (REPO / "docs" / "parameters.md").read_text()
    assert "rigid_viscous_axis" not in page and "python -m servo_axis params" in page
    # An unknown model names the installed ones, the outside one among them.
    bad = write_scenario(Path(plugin_site).parent / "bad.yaml")
    data = yaml.safe_load(bad.read_text())
    data["plant"]["ros__parameters"]["model"] = "no_such_axis"
    bad.write_text(yaml.safe_dump(data))
    code = (
        "import sys\n"
        "from servo_axis.params.resolve import node_values\n"
        "from servo_axis.params.scenario import load_scenario\n"
        "try:\n"
        f"    node_values(load_scenario({str(bad)!r}), 'plant')\n"
        "except Exception as err:\n"
        "    print(err)\n"
    )
    message = python(plugin_site, dict(os.environ), "-c", code).strip()
    assert message.startswith("parameter 'model': expected one of [")
    assert "'rigid_viscous_axis'" in message and "'ball_screw'" in message
    assert message.endswith("got 'no_such_axis'") and "\n" not in message
