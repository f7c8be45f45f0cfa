"""What a node process and the runner import before the first step.

Every run starts four to six Python processes on a machine that may have
two cores: a module imported at start-up that the run never uses costs
every run its import time (scipy.signal alone ~1 s of a 5 s lockstep run
of ptc_nominal). scipy's parts are imported where a computation needs
them, not at module level.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

NODES = ("plant", "feedback", "feedforward", "recorder", "learning", "identifier")
#: scipy sub-packages no start-up needs (each 0.1 to 1 s to import).
HEAVY = ("scipy.signal", "scipy.stats", "scipy.optimize", "scipy.interpolate")


def _modules_after(code: str) -> list[str]:
    code += "\nimport sys, json\nprint(json.dumps(sorted(sys.modules)))\n"
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    return list(json.loads(done.stdout.splitlines()[-1]))


@pytest.mark.parametrize("role", NODES)
def test_a_node_module_and_every_extension_load_no_scipy(role: str) -> None:
    modules = _modules_after(
        f"import servo_axis.nodes.{role}\n"
        "from servo_axis.params.registry import REGISTRIES\n"
        "assert all(len(r) > 0 for r in REGISTRIES.values())\n"
    )
    assert f"servo_axis.nodes.{role}" in modules
    assert "servo_axis.plugins.excitation" in modules  # the registries did load
    assert [m for m in modules if m.split(".")[0] == "scipy"] == []


def test_planning_a_shipped_scenario_loads_no_heavy_scipy_part(tmp_path: object) -> None:
    # Planning an ILC scenario designs its law (the plant's ZOH
    # model by scipy.signal.cont2discrete), as its learning unit would.
    modules = _modules_after(
        "from pathlib import Path\n"
        "from servo_axis.params.scenario import find_scenario, load_scenario, scenario_names\n"
        "from servo_axis.params.run_plan import plan_run\n"
        "planned = 0\n"
        "for name in scenario_names():\n"
        "    path = find_scenario(name)\n"
        "    scenario = load_scenario(path)\n"
        "    if 'law' in scenario.get('learning', {}).get('ros__parameters', {}):\n"
        "        continue\n"
        f"    plan_run(scenario, path, out_dir=Path({str(tmp_path)!r}) / name)\n"
        "    planned += 1\n"
        "assert planned == len(scenario_names()) - 3, planned\n"
    )
    assert "servo_axis.params.run_plan" in modules
    assert [m for m in modules if m.startswith(HEAVY)] == []
