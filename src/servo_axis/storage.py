"""Files the suite reads and writes besides bags: friction tables, learning and identifier memories.

Core formats the text (:meth:`FrictionTable.to_text`,
:func:`servo_axis.core.learning.base.encode_memory`); this module does the
I/O: a memory is written atomically (temporary file, then rename), so that a
unit killed mid-write leaves the previous memory. GMS friction parameters
(:func:`~servo_axis.core.friction.gms_text.gms_to_text`, paper 004 Fig. 4(b))
are written the same way.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from servo_axis.core.errors import SignalError, TableError
from servo_axis.core.feedforward.friction_table import FrictionTable
from servo_axis.core.friction.gms_params import GmsParams
from servo_axis.core.friction.gms_text import gms_from_text, gms_to_text
from servo_axis.core.learning.base import LearningLaw, decode_memory, encode_memory


def load_friction_table(path: Path | str) -> FrictionTable:
    """Read a friction table file (TableError naming the file; OSError if unreadable)."""
    return FrictionTable.from_text(Path(path).read_text(), source=str(path))


def save_friction_table(path: Path | str, table: FrictionTable) -> None:
    """Write a friction table file."""
    Path(path).write_text(table.to_text())


def save_gms_parameters(
    path: Path | str, params: GmsParams, *, plant_model: str, plant_fingerprint: str
) -> None:
    """Write a GMS parameter file atomically (:func:`gms_to_text`)."""
    text = gms_to_text(params, plant_model=plant_model, plant_fingerprint=plant_fingerprint)
    _write_atomically(Path(path), text)


def load_gms_parameters(path: Path | str) -> tuple[GmsParams, str, str]:
    """``(params, plant_model, plant_fingerprint)`` of a GMS parameter file.

    Raises
    ------
    TableError
        Naming the file, when it cannot be read or is malformed
        (:func:`~servo_axis.core.friction.gms_text.gms_from_text`).
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise TableError(f"{source}: cannot read it: {err}") from err
    return gms_from_text(text, source=source)


def save_memory(path: Path | str, law: LearningLaw, *, scenario: str) -> None:
    """Persist a learning law's memory atomically."""
    _write_atomically(Path(path), encode_memory(law, scenario=scenario))


def load_memory(path: Path | str, law: LearningLaw, *, scenario: str) -> dict[str, Any]:
    """The state of a memory file after checking it belongs to ``law`` and ``scenario``."""
    return decode_memory(Path(path).read_text(), law, scenario=scenario, source=str(path))


#: The identifier memory's format: its ``kind`` and ``version`` keys.
IDENTIFIER_MEMORY_KIND = "servo_axis.identifier_memory"
IDENTIFIER_MEMORY_VERSION = 1


def save_identifier_memory(
    path: Path | str,
    state: dict[str, Any],
    last_estimate: list[float] | None,
    *,
    method: str,
    scenario: str,
) -> None:
    """Persist an online identifier's state and its last published estimate atomically.

    JSON keeps every float exactly (``repr``), so a resumed identifier goes
    on bit-identically.
    """
    text = json.dumps(
        {
            "kind": IDENTIFIER_MEMORY_KIND,
            "version": IDENTIFIER_MEMORY_VERSION,
            "method": method,
            "scenario": scenario,
            "state": state,
            "last_estimate": last_estimate,
        },
        allow_nan=False,
    )
    _write_atomically(Path(path), text)


def load_identifier_memory(
    path: Path | str, *, method: str, scenario: str
) -> tuple[dict[str, Any], list[float] | None]:
    """``(state, last_estimate)`` of an identifier memory file of ``method`` and ``scenario``.

    Raises
    ------
    SignalError
        A file that is not an identifier memory, or one of another method
        or scenario (the state itself is checked by the identifier's
        ``load_state``).
    OSError
        If it cannot be read.
    """
    source = str(path)
    try:
        data = json.loads(Path(path).read_text())
    except json.JSONDecodeError as err:
        raise SignalError(f"{source}: not JSON ({err})") from err
    if not isinstance(data, dict) or data.get("kind") != IDENTIFIER_MEMORY_KIND:
        raise SignalError(f"{source}: not an identifier memory (kind {IDENTIFIER_MEMORY_KIND!r})")
    if data.get("version") != IDENTIFIER_MEMORY_VERSION:
        raise SignalError(
            f"{source}: version {data.get('version')!r}, expected {IDENTIFIER_MEMORY_VERSION}"
        )
    for key, expected in (("method", method), ("scenario", scenario)):
        if data.get(key) != expected:
            raise SignalError(f"{source}: {key} {data.get(key)!r}, expected {expected!r}")
    state, last = data.get("state"), data.get("last_estimate")
    if not isinstance(state, dict):
        raise SignalError(f"{source}: state: expected a mapping")
    if last is not None and (
        not isinstance(last, list)
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in last)
    ):
        raise SignalError(f"{source}: last_estimate: expected a list of numbers or null")
    return state, last


def _write_atomically(target: Path, text: str) -> None:
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, target)
