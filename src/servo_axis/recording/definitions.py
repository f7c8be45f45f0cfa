"""Message definitions of installed ROS 2 message types, without rclpy.

The ``ros2msg`` definition text (:func:`message_definition`) and RIHS01 type hash
(:func:`type_hash`) are read from the ``.msg`` and ``.json`` files that a ROS
package installs under ``share/<pkg>/msg``; only :func:`message_class` imports
the generated Python classes, and only when it is called.
"""

from __future__ import annotations

import functools
import importlib
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

from servo_axis.recording.errors import BagError

__all__ = ["SEPARATOR", "message_class", "message_definition", "type_hash"]

#: The line between two definitions in ``ros2msg`` text.
SEPARATOR = "=" * 80

_PRIMITIVES = frozenset(
    {
        "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
        "int32", "uint32", "int64", "uint64", "string", "wstring",
    }
)  # fmt: skip

# The field type at the start of a .msg line: ``pkg/Type``, ``Type``, ``string<=8``,
# ``float64[]``, ``float64[3]``, ``int32[<=4]``; comments and blank lines do not match.
_FIELD_TYPE = re.compile(r"^\s*([A-Za-z][A-Za-z0-9_/]*)(?:<=\d+)?(?:\[[^\]]*\])?\s+\S")

_NAME = r"[A-Za-z][A-Za-z0-9_]*"
_TYPE_NAME = re.compile(rf"^({_NAME})/(?:(msg)/)?({_NAME})$")


def _split(type_name: str) -> tuple[str, str]:
    """``(package, Type)`` of ``pkg/msg/Type`` or ``pkg/Type``.

    Raises
    ------
    BagError
        If ``type_name`` is not a message type name.
    """
    match = _TYPE_NAME.match(type_name) if isinstance(type_name, str) else None
    if match is None:
        raise BagError(f"type_name: expected 'pkg/msg/Type', got {type_name!r}")
    return match.group(1), match.group(3)


@functools.cache
def _package_share(package: str) -> Path:
    """Share directory of an installed ROS package (``<prefix>/share/<pkg>``)."""
    # The ROS packages are pip-installed into the venv, which is then the only
    # ament prefix; a sourced ROS installation still wins through the variable.
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(package))
    except (ImportError, LookupError, ValueError):
        return Path(sys.prefix) / "share" / package


def _interface_file(type_name: str, suffix: str) -> Path:
    package, name = _split(type_name)
    return _package_share(package) / "msg" / f"{name}{suffix}"


@functools.cache
def _msg_text(type_name: str) -> str:
    """The installed ``.msg`` text of ``pkg/Type``.

    Raises
    ------
    BagError
        If no ``.msg`` file is installed for the type.
    """
    path = _interface_file(type_name, ".msg")
    try:
        return path.read_text()
    except OSError:
        raise BagError(
            f"type_name: unknown message type {type_name!r} (no definition at {path})"
        ) from None


def _dependencies(text: str, package: str) -> list[str]:
    """Nested types (``pkg/Type``) of a ``.msg`` text, sorted and unique like rosbag2."""
    deps: set[str] = set()
    for line in text.splitlines():
        match = _FIELD_TYPE.match(line)
        if match is None:
            continue
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        if field_type == "Header":
            deps.add("std_msgs/Header")
        elif "/" not in field_type:
            deps.add(f"{package}/{field_type}")
        else:
            dep_package, dep_name = _split(field_type)
            deps.add(f"{dep_package}/{dep_name}")
    return sorted(deps)


@functools.cache
def message_definition(type_name: str) -> str:
    """Full ``ros2msg`` definition text of a message type, nested types included.

    The text is built as rosbag2 (``LocalMessageDefinitionSource``) builds it:
    the type's ``.msg`` file, then, depth first with the nested types of each
    definition in sorted order and every type once, a newline, a line of 80
    ``=``, a line ``MSG: pkg/Type`` and that type's ``.msg`` file.

    Parameters
    ----------
    type_name : str
        Message type, ``pkg/msg/Type`` (or ``pkg/Type``), e.g.
        ``sensor_msgs/msg/JointState``.

    Returns
    -------
    str
        The definition text (schema data of the type's MCAP schema).

    Raises
    ------
    BagError
        If the type or one of its nested types has no installed ``.msg`` file.
    """
    package, name = _split(type_name)
    seen = {f"{package}/{name}"}

    def append(pkg_type: str, depth: int) -> list[str]:
        if depth > 64:
            raise BagError(f"type_name: {type_name!r} nests types more than 64 deep")
        text = _msg_text(pkg_type)
        parts = [text]
        for dep in _dependencies(text, pkg_type.split("/", 1)[0]):
            if dep in seen:
                continue
            seen.add(dep)
            parts.append(f"\n{SEPARATOR}\nMSG: {dep}\n")
            parts.extend(append(dep, depth + 1))
        return parts

    return "".join(append(f"{package}/{name}", 0))


@functools.cache
def type_hash(type_name: str) -> str | None:
    """The RIHS01 type hash of a message type, from its installed ``.json``.

    Parameters
    ----------
    type_name : str
        Message type, ``pkg/msg/Type``.

    Returns
    -------
    str or None
        ``RIHS01_<64 hex digits>`` (``type_hashes`` entry of the type in
        ``share/<pkg>/msg/<Type>.json``), or None if the file or entry is missing.
    """
    package, name = _split(type_name)
    path = _interface_file(type_name, ".json")
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    full = f"{package}/msg/{name}"
    for entry in data.get("type_hashes", []) if isinstance(data, dict) else []:
        if isinstance(entry, dict) and entry.get("type_name") == full:
            value = entry.get("hash_string")
            return str(value) if value else None
    return None


def message_class(type_name: str) -> Any:
    """Python class of a message type.

    The generated message packages are imported here, when called, so that
    importing this module never loads rclpy or rosidl.

    Parameters
    ----------
    type_name : str
        Message type, ``pkg/msg/Type``.

    Returns
    -------
    type
        The rosidl-generated message class.

    Raises
    ------
    BagError
        If the package or type is not installed.
    """
    package, name = _split(type_name)
    try:
        from rosidl_runtime_py.utilities import get_message
    except ImportError:
        pass
    else:
        try:
            return get_message(f"{package}/msg/{name}")
        except (ImportError, AttributeError, ValueError) as err:
            raise BagError(f"type_name: unknown message type {type_name!r}") from err
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as err:
        raise BagError(f"type_name: unknown message type {type_name!r}") from err
