"""The run directory records its scenario and data files; later commands read those only.

Through :func:`servo_axis.run.prepare.prepare`, what ``python -m servo_axis
run`` does before it starts a process (no ROS): ``scenario.yaml`` and the
copies under ``inputs/``, and the nodes' ``params.yaml`` naming the copies.
Then :func:`servo_axis.params.recorded.recorded_scenario` on such a
directory, on one made before runs kept their scenario (a ``params.yaml``
as the runner wrote it then) and on what is not a run. The commands on a
real run whose scenario and table moved and were edited:
``test/integration/test_runs.py`` (summary, compare) and
``test/integration/test_docs_pages.py`` (friction-table on the
friction-models page's run, identify on recover-a-bag's).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from servo_axis.core.errors import ConfigError, ParameterFileError
from servo_axis.params.recorded import recorded_scenario
from servo_axis.params.resolve import feedforward_values, node_values
from servo_axis.params.run_params import handshake_overrides, write_run_params
from servo_axis.params.scenario import load_scenario, roles_of
from servo_axis.run.options import RunOptions
from servo_axis.run.prepare import prepare

CONFIG = Path(__file__).resolve().parents[3] / "config"
TABLE = "friction_table_ball_screw_x.csv"


@pytest.fixture
def sources(tmp_path: Path) -> Path:
    """ptc_friction_table.yaml and its table (named relative to it) in a folder of their own."""
    folder = tmp_path / "sources"
    folder.mkdir()
    shutil.copy(CONFIG / "ptc_friction_table.yaml", folder)
    shutil.copy(CONFIG / TABLE, folder)
    return folder


def test_the_run_directory_gets_the_scenario_and_a_copy_of_its_table(
    sources: Path, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    prepared = prepare(sources / "ptc_friction_table.yaml", RunOptions(out_dir=run, progress=None))
    axis = prepared.plan.axes[0]
    copy = run / "inputs" / "friction_table" / TABLE
    assert copy.read_bytes() == (sources / TABLE).read_bytes()
    # scenario.yaml is the file as it was, but for the table: its copy, relative to it.
    recorded = load_scenario(run / "scenario.yaml")
    original = load_scenario(sources / "ptc_friction_table.yaml")
    ff = recorded["feedforward"]["ros__parameters"]
    assert ff["friction_table"]["file"] == f"inputs/friction_table/{TABLE}"
    ff["friction_table"]["file"] = TABLE
    assert recorded == original
    assert (run / "scenario.yaml").read_text().startswith("# The scenario of this run as it ran")
    assert str(sources / "ptc_friction_table.yaml") in (run / "scenario.yaml").read_text()
    # The nodes read the copy, and the plan keeps where it came from.
    params = yaml.safe_load((run / "params.yaml").read_text())
    assert params["/**/feedforward"]["ros__parameters"]["friction_table.file"] == str(copy)
    assert axis.inputs["friction_table.file"] == (sources / TABLE, f"inputs/friction_table/{TABLE}")
    assert axis.source_path == sources / "ptc_friction_table.yaml"
    assert axis.scenario_path == run / "scenario.yaml"


def test_later_reads_take_the_recorded_scenario_wherever_the_run_and_the_file_are(
    sources: Path, tmp_path: Path
) -> None:
    prepare(
        sources / "ptc_friction_table.yaml", RunOptions(out_dir=tmp_path / "run", progress=None)
    )
    # The sources edited in place, then the run directory moved.
    edited = load_scenario(sources / "ptc_friction_table.yaml")
    edited["feedforward"]["ros__parameters"]["reference"]["amplitude_m"] = 0.002
    (sources / "ptc_friction_table.yaml").write_text(yaml.safe_dump(edited))
    (sources / TABLE).unlink()
    moved = tmp_path / "elsewhere"
    (tmp_path / "run").rename(moved)
    found = recorded_scenario(moved, str(sources / "ptc_friction_table.yaml"))
    assert found.source == found.path == moved / "scenario.yaml"
    values = feedforward_values(found.scenario, found.path)
    assert values["reference.amplitude_m"] == 0.01
    assert values["friction_table.file"] == str(moved / "inputs" / "friction_table" / TABLE)
    # A copy that has gone is one line naming it.
    (moved / "inputs" / "friction_table" / TABLE).unlink()
    with pytest.raises(ConfigError) as err:
        recorded_scenario(moved)
    assert str(err.value) == (
        f"{moved / 'scenario.yaml'}: friction_table.file "
        f"{moved / 'inputs' / 'friction_table' / TABLE}: its copy is missing from the run directory"
    )


def old_run(sources: Path, run: Path) -> Path:
    """A run directory as the runner left it before runs kept their scenario: params.yaml only."""
    data = load_scenario(sources / "ptc_friction_table.yaml")
    overrides = handshake_overrides(data, roles_of(data), run / "bag", sources)
    run.mkdir()
    write_run_params(data, overrides, run / "params.yaml")
    return sources / "ptc_friction_table.yaml"


def test_a_run_made_before_reads_its_params_yaml_not_the_edited_file(
    sources: Path, tmp_path: Path
) -> None:
    run = tmp_path / "old"
    scenario_file = old_run(sources, run)
    edited = load_scenario(scenario_file)
    edited["feedforward"]["ros__parameters"]["reference"]["amplitude_m"] = 0.002
    edited["/**"]["ros__parameters"]["lead_m_per_rad"] = 0.005
    scenario_file.write_text(yaml.safe_dump(edited))
    found = recorded_scenario(run, str(scenario_file))
    assert found.source == run / "params.yaml"
    values = feedforward_values(found.scenario, found.path)
    assert values["reference.amplitude_m"] == 0.01 and values["lead_m_per_rad"] == 0.00191
    assert values["friction_table.file"] == str(sources / TABLE)
    plant = node_values(found.scenario, "plant")
    assert plant["friction.rolling_coulomb_Nm"] == 3.2
    # Its table was never copied: once gone, one line saying what to do.
    (sources / TABLE).rename(tmp_path / TABLE)
    with pytest.raises(ConfigError) as err:
        recorded_scenario(run, str(scenario_file))
    message = str(err.value)
    assert message.startswith(f"{run / 'params.yaml'}: friction_table.file {sources / TABLE}: ")
    assert message.endswith("is gone from where it was: put it back there") and "\n" not in message


def test_what_no_run_wrote_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as err:
        recorded_scenario(tmp_path)
    assert str(err.value) == (
        f"{tmp_path}: no scenario.yaml or params.yaml: not a directory written by "
        "`python -m servo_axis run`"
    )


def test_a_missing_table_is_named_by_its_own_path_and_nothing_is_written(
    sources: Path, tmp_path: Path
) -> None:
    (sources / TABLE).unlink()
    run = tmp_path / "run"
    with pytest.raises(ParameterFileError) as err:
        prepare(sources / "ptc_friction_table.yaml", RunOptions(out_dir=run, progress=None))
    assert str(err.value) == (
        f"scenario {sources / 'ptc_friction_table.yaml'}: "
        f"parameter 'friction_table.file': no such file {sources / TABLE}"
    )
    assert not run.exists()
