"""The identified axis as a scenario file that ``python -m servo_axis run`` takes as it is."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

from servo_axis.identify.data import Record
from servo_axis.identify.driver import OfflineIdentification, absolute_files, fitted_scenario


def scenario_of(ident: OfflineIdentification, base: Record, *, name: str) -> dict[str, Any]:
    """The scenario: ``base``'s (the held-out run's, else the excitation run's) with the
    identified plant section, the excitation off and ``scenario.name`` set.

    The controllers and the nominal model stay the base run's, so that the
    scenario runs what the axis ran; the identified rigid body is in the
    file's header for a ``nominal`` section of one's own.
    """
    scenario = copy.deepcopy(fitted_scenario(ident, base))
    # The file is written elsewhere: data files the base names by a relative path, absolute.
    absolute_files(scenario, base.scenario_path.parent)
    shared = scenario.setdefault("/**", {}).setdefault("ros__parameters", {})
    meta = shared.setdefault("scenario", {})
    meta["name"] = name
    meta["description"] = (
        f"{ident.model} identified from {base.source} (python -m servo_axis identify)"
    )
    ff = scenario.get("feedforward", {}).get("ros__parameters", {})
    if isinstance(ff.get("excitation"), dict):
        ff["excitation"]["enabled"] = False
    return scenario


def header(ident: OfflineIdentification, command: str) -> str:
    """The comment block at the top of the file: the command, each key with its error, the notes."""
    lines = [
        f"# {ident.model} identified by python -m servo_axis identify (docs/how-to/identify-your-axis.md):",
        f"#   {command}",
        "#",
        "# key = value +- standard error (source)",
    ]
    for k in ident.keys:
        std = "" if k.std != k.std else f" +- {k.std:.3g}"
        lines.append(f"#   {k.key} = {k.value:.6g}{std} ({k.source})")
    if ident.notes:
        lines.append("#")
        lines.append("# not identified, or identified with a choice:")
        for note in ident.notes:
            lines.append(f"#   - {note}")
    return "\n".join(lines) + "\n"


def write_scenario(
    path: Path, ident: OfflineIdentification, base: Record, *, command: str
) -> dict[str, Any]:
    """Write the scenario file (header and YAML) and return the scenario."""
    scenario = scenario_of(ident, base, name=Path(path).stem)
    text = yaml.safe_dump(scenario, sort_keys=False, default_flow_style=False, width=100)
    Path(path).write_text(header(ident, command) + text)
    return scenario
