"""An installed plugin that cannot be loaded breaks only what uses it.

``test/data/broken_plugin`` is a plugin package whose four entry points are
broken four ways: a module that does not exist (the own-plugin tutorial's
failure: a pyproject.toml naming a module the package never ships), a
module that fails on an import of its own, an object that is not an entry,
and an entry its kind's checks refuse. It is installed as pip installs it,
its modules and a ``*.dist-info`` with its entry points, into a temporary
folder (``broken_plugin_site`` of test/conftest.py) that only the
subprocesses of this test get on ``PYTHONPATH``; the
entry points are then read by ``importlib.metadata`` itself. Everything
goes through ``python -m servo_axis``. That a run which does not use them
still runs (real nodes) is in ``test/integration/test_outside_plugin.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[3]
DIST = "servo-axis-broken-plugin 0.1.0"

#: name -> (kind, entry point, what its error says)
BROKEN = {
    "missing_axis": (
        "plant model",
        "servo_axis_broken.no_such_module:PLANT_MODEL",
        "ModuleNotFoundError: No module named 'servo_axis_broken.no_such_module'",
    ),
    "failing_term": (
        "feedforward term",
        "servo_axis_broken.failing:TERM",
        "ModuleNotFoundError: No module named 'servo_axis_no_such_dependency' (at ",
    ),
    "wrong_law": (
        "learning law",
        "servo_axis_broken.wrong:LAW",
        "expected a LearningLawEntry, got dict",
    ),
    "clashing_method": (
        "identification method",
        "servo_axis_broken.clashing:METHOD",
        "schema: keys ['rls_period_s'] are the identifier node's own",
    ),
}


def servo_axis(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]),
    }
    return subprocess.run(
        [sys.executable, "-m", "servo_axis", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=site,
    )


def test_list_marks_each_broken_plugin_and_names_it_once_on_stderr(
    broken_plugin_site: Path,
) -> None:
    done = servo_axis(broken_plugin_site, "list")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    for name, (_kind, value, error) in BROKEN.items():
        (row,) = [line for line in lines if line.split()[:1] == [name]]
        assert "broken: " in row and error in row and f"[{value}, {DIST}]" in row, row
    # The shipped extensions are all still there, with their keys.
    for name in ("ball_screw", "friction_table", "rptc", "dlpid"):
        (row,) = [line for line in lines if line.split()[:1] == [name]]
        assert "broken" not in row and "[servo_axis.plugins." in row
    warnings = done.stderr.splitlines()
    assert len(warnings) == len(BROKEN), done.stderr
    for name, (kind, value, error) in BROKEN.items():
        (line,) = [w for w in warnings if f"{kind} '{name}' " in w]
        assert line.startswith(f"warning: {kind} '{name}' cannot be loaded: entry point '{name}' ")
        assert f"= '{value}'" in line and f"(distribution {DIST})" in line and error in line
    assert "failing.py:5)" in done.stderr  # the line of the plugin that failed


@pytest.mark.parametrize(
    ("name", "section", "keys", "key"),
    [
        ("missing_axis", "plant", {"model": "missing_axis"}, "model"),
        (
            "failing_term",
            "feedforward",
            {"failing_term": {"enabled": True}},
            "failing_term.enabled",
        ),
    ],
)
def test_a_run_that_selects_a_broken_plugin_is_one_line_before_anything_starts(
    broken_plugin_site: Path,
    tmp_path: Path,
    name: str,
    section: str,
    keys: dict[str, object],
    key: str,
) -> None:
    scenario = yaml.safe_load((REPO / "config" / "ptc_nominal.yaml").read_text())
    scenario[section]["ros__parameters"].update(keys)
    path = tmp_path / "uses_it.yaml"
    path.write_text(yaml.safe_dump(scenario))
    out = tmp_path / "run"
    done = servo_axis(broken_plugin_site, "run", str(path), "--out", str(out))
    kind, value, error = BROKEN[name]
    assert done.returncode == 2
    # One line: this plugin's, not the warnings of the others.
    assert done.stderr.count("\n") == 1, done.stderr
    line = done.stderr.strip()
    # Named after the scenario file it comes from.
    assert line.startswith(f"error: scenario {path}: "), line
    assert f": parameter '{key}': {kind} '{name}' cannot be loaded: " in line, line
    assert f"entry point '{name}' = '{value}' of group " in line and error in line
    assert not out.exists() and done.stdout == ""  # no header: nothing was started
