"""The scenario a run recorded: what every later command reads, never the file the run began from.

A run directory (each axis's directory, for a run of several axes) holds
``scenario.yaml``, the single-axis scenario exactly as it ran, and under
``inputs/<term>/`` a copy of each data file it uses (``friction_table.file``,
``gms.file``, an outside term's files), which ``scenario.yaml`` names
relative to itself and the nodes read (:func:`input_copies` at planning,
the runner's ``prepare`` writes them). So ``identify``, ``summary``,
``compare``, ``friction-table``, ``gms-fit`` and the plots give the same
result however the scenario file and its data files have been moved or
edited since, and ``python -m servo_axis run <run>/scenario.yaml`` runs the
same scenario again.

:func:`recorded_scenario` reads it. A run made before runs kept it (no
``scenario.yaml``) is read from its ``params.yaml``, the parameter file its
nodes got (the scenario's sections with what the runner added, its data
files named by absolute path where they were): that is what the run used,
whatever became of the scenario file. Such a run keeps no copy of its data
files, and nothing recorded tells whether one has changed since (no
checksum was kept): one that is gone is one line saying so.

Nothing here imports rclpy.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from servo_axis.core.errors import ConfigError, ServoAxisError
from servo_axis.params.registry import term_files
from servo_axis.params.resolve import Resolved
from servo_axis.params.scenario import (
    SHARED_SECTION,
    load_scenario,
    resolve_table,
    safe_load_text,
    with_term_files,
)

#: The recorded scenario in a run (or axis) directory.
SCENARIO_FILE = "scenario.yaml"
#: The parameter file the nodes got, written by the runner.
PARAMS_FILE = "params.yaml"
#: The folder of the copies of the data files the scenario names.
INPUTS_DIR = "inputs"


def input_copies(
    view: dict[str, Any] | Resolved, scenario_dir: Path
) -> dict[str, tuple[Path, str]]:
    """Where each data file of a single-axis scenario is copied in its run directory.

    Parameters
    ----------
    view : dict or Resolved
        The single-axis scenario (file paths as its file gives them), or it
        read once with its file in ``scenario_dir``.
    scenario_dir : Path
        The folder a relative file path is relative to (the scenario file's).

    Returns
    -------
    dict
        ``{key: (source, copy)}`` for each file key of a term that is on
        (``<term>.enabled``, or a term without that key) whose file exists:
        the absolute source and ``inputs/<term>/<file name>``, relative to
        the run directory. A file that does not exist is left out (the plan
        refuses it, naming the key); a view whose feedforward section does
        not check gives none (its error is the plan's to report).
    """
    resolved = Resolved.of(view, scenario_dir / SCENARIO_FILE)
    if not resolved.has("feedforward"):
        return {}
    try:
        values = resolved.feedforward
    except ServoAxisError:
        return {}
    copies: dict[str, tuple[Path, str]] = {}
    for key in term_files():
        term = key.rpartition(".")[0]
        source = Path(values[key]) if values[key] else None
        if source is None or not values.get(f"{term}.enabled", True) or not source.is_file():
            continue
        copies[key] = (source, f"{INPUTS_DIR}/{term}/{source.name}")
    return copies


def recorded_view(
    view: dict[str, Any], copies: Mapping[str, tuple[Path, str]], scenario_dir: Path
) -> dict[str, Any]:
    """``view`` naming the copies of :func:`input_copies`, relative to the run directory.

    A file not copied (of a term that is off, or missing: the plan refuses
    that) is named by its absolute path.
    """

    def named(key: str, path: str) -> str:
        return copies[key][1] if key in copies else resolve_table(path, scenario_dir.resolve())

    return with_term_files(view, named)


def file_sha256(path: Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def header(source: Path, *, axis: str = "") -> str:
    """The comment that opens a recorded ``scenario.yaml``: where it came from, what it is for."""
    what = f"Axis {axis} of the scenario" if axis else "The scenario"
    try:
        digest = f"\n#   (SHA-256 {file_sha256(source)} then)"
    except OSError:
        digest = ""
    return (
        f"# {what} of this run as it ran, recorded by `python -m servo_axis run` from\n"
        f"#   {source}{digest}.\n"
        f"# The data files it names are copies in {INPUTS_DIR}/, relative to this file. Later\n"
        "# commands read this file, never the original; `python -m servo_axis run` of this\n"
        + (
            "# file runs this axis alone again.\n"
            if axis
            else "# file runs the same scenario again.\n"
        )
    )


@dataclass(frozen=True)
class RecordedScenario:
    """A run's scenario as it ran, and where it was read from.

    Attributes
    ----------
    scenario : dict
        The single-axis scenario.
    path : Path
        The file whose folder a relative data-file path is relative to
        (``scenario.yaml`` of the run; for a ``params.yaml`` the scenario
        file the run was started from).
    source : Path
        The file it was read from (``scenario.yaml`` or ``params.yaml``).
    """

    scenario: dict[str, Any]
    path: Path
    source: Path

    @property
    def started_from(self) -> Path:
        """The scenario file the run was started from (its header's), else :attr:`source`."""
        if self.source.name == SCENARIO_FILE:
            lines = self.source.read_text().splitlines()[:3]
            if len(lines) > 1 and lines[0].startswith("# ") and lines[1].startswith("#   "):
                return Path(lines[1].removeprefix("#   "))
        return self.source


def scenario_of_params(path: Path) -> dict[str, Any]:
    """A run's ``params.yaml`` (``/**/<role>`` or ``/<ns>/<role>`` sections) as a scenario.

    Raises
    ------
    ConfigError
        If it cannot be read or is not a parameter file.
    """
    try:
        data = safe_load_text(Path(path).read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: cannot read it: {err}") from None
    if not isinstance(data, dict) or not all(isinstance(k, str) for k in data):
        raise ConfigError(f"{path}: not a parameter file (expected node sections)")
    return {k if k == SHARED_SECTION else k.rsplit("/", 1)[-1]: v for k, v in data.items()}


def recorded_scenario(run_dir: Path, scenario_file: str = "") -> RecordedScenario:
    """The scenario a single-axis run (or one axis of several) ran, from its directory.

    Parameters
    ----------
    run_dir : Path
        The run directory (an axis's directory for a multi-axis run).
    scenario_file : str
        The summary's ``scenario_file`` (the file the run was started from):
        a relative data-file path of a ``params.yaml`` is relative to its
        folder; only named otherwise.

    Raises
    ------
    ConfigError
        If the directory holds neither ``scenario.yaml`` nor ``params.yaml``,
        either cannot be read, or a data file it names is gone (one line
        naming the key, the file and what to do).
    """
    run_dir = Path(run_dir)
    copy = run_dir / SCENARIO_FILE
    params = run_dir / PARAMS_FILE
    if copy.is_file():
        found = RecordedScenario(load_scenario(copy), copy, copy)
    elif params.is_file():
        base = Path(scenario_file) if scenario_file else params
        found = RecordedScenario(scenario_of_params(params), base, params)
    else:
        raise ConfigError(
            f"{run_dir}: no {SCENARIO_FILE} or {PARAMS_FILE}: not a directory written by "
            "`python -m servo_axis run`"
        )
    inside = run_dir.resolve()
    for key, path in _data_files(found):
        if path.is_file():
            continue
        if path.resolve().is_relative_to(inside):
            why = "its copy is missing from the run directory"
        else:  # a run (or an axis of several) made before runs copied their data files
            why = (
                "the run was made before runs kept copies of their data files, and the file "
                "is gone from where it was: put it back there"
            )
        raise ConfigError(f"{found.source}: {key} {path}: {why}")
    return found


def _data_files(found: RecordedScenario) -> list[tuple[str, Path]]:
    """The data files the scenario's terms that are on read, absolute."""
    if "feedforward" not in found.scenario:
        return []
    values = Resolved(found.scenario, found.path).feedforward
    out = []
    for key in term_files():
        term = key.rpartition(".")[0]
        if values[key] and values.get(f"{term}.enabled", True):
            out.append((key, Path(values[key])))  # made absolute by feedforward_values
    return out
