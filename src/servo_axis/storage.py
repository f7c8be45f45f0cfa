"""Files the suite reads and writes besides bags: friction tables and learning memories.

Core formats the text (:meth:`FrictionTable.to_text`,
:func:`servo_axis.core.learning.base.encode_memory`); this module does the
I/O: a memory is written atomically (temporary file, then rename), so that a
unit killed mid-write leaves the previous memory.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from servo_axis.core.feedforward.friction_table import FrictionTable
from servo_axis.core.learning.base import LearningLaw, decode_memory, encode_memory


def load_friction_table(path: Path | str) -> FrictionTable:
    """Read a friction table file (TableError naming the file; OSError if unreadable)."""
    return FrictionTable.from_text(Path(path).read_text(), source=str(path))


def save_friction_table(path: Path | str, table: FrictionTable) -> None:
    """Write a friction table file."""
    Path(path).write_text(table.to_text())


def save_memory(path: Path | str, law: LearningLaw, *, scenario: str) -> None:
    """Persist a learning law's memory atomically."""
    target = Path(path)
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_text(encode_memory(law, scenario=scenario))
    os.replace(tmp, target)


def load_memory(path: Path | str, law: LearningLaw, *, scenario: str) -> dict[str, Any]:
    """The state of a memory file after checking it belongs to ``law`` and ``scenario``."""
    return decode_memory(Path(path).read_text(), law, scenario=scenario, source=str(path))
