"""ROS names and domain ids as the command line takes them, checked without rclpy.

The rules are those of ``rmw_validate_namespace`` and the ROS 2 domain id
range of the default RTPS port mapping: a check here refuses what rcl or the
DDS layer would refuse later, after processes have started. Nothing here
imports rclpy.
"""

from __future__ import annotations

import re

from servo_axis.core.errors import ConfigError

#: Highest ROS_DOMAIN_ID the default RTPS port mapping allows (ports stay below 65536).
MAX_DOMAIN_ID = 232
#: Longest namespace rmw accepts (``RMW_NAMESPACE_MAX_LENGTH``: 255 - 8 - 2 characters).
MAX_NAMESPACE_LENGTH = 245

_SEGMENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def namespace_problem(name: str) -> str | None:
    """What ROS would reject in the namespace ``name``, or None if it is valid.

    A namespace is absolute (starts with ``/``), its segments are
    ``[A-Za-z_][A-Za-z0-9_]*`` separated by single ``/``, it does not end in
    ``/`` (``/`` alone, the root, aside) and has at most
    :data:`MAX_NAMESPACE_LENGTH` characters.

    Parameters
    ----------
    name : str
        The namespace, e.g. ``/x`` or ``/machine/x``.

    Returns
    -------
    str or None
        One phrase naming the fault, None for a valid namespace.
    """
    if not name:
        return "it is empty"
    if not name.startswith("/"):
        return "it must be absolute (start with '/')"
    if len(name) > MAX_NAMESPACE_LENGTH:
        return f"it is {len(name)} characters long, at most {MAX_NAMESPACE_LENGTH} allowed"
    if name == "/":
        return None
    if "//" in name:
        return "it must not contain '//'"
    if name.endswith("/"):
        return "it must not end with '/'"
    for segment in name[1:].split("/"):
        if not _SEGMENT.fullmatch(segment):
            return f"segment {segment!r} must be letters, digits and '_' and not start with a digit"
    return None


def check_namespace(name: str, option: str = "--namespace") -> str:
    """``name`` if it is a valid ROS namespace (``/``: the root), else :class:`ConfigError` naming ``option``."""
    problem = namespace_problem(name)
    if problem is not None:
        raise ConfigError(f"{option}: {name!r} is not a valid ROS namespace: {problem}")
    return name


def domain_id_problem(value: str | int) -> str | None:
    """What is wrong with ``value`` as a ROS domain id (an integer 0..232), or None."""
    try:
        domain = int(str(value).strip())
    except ValueError:
        return f"{str(value)!r} is not an integer 0..{MAX_DOMAIN_ID}"
    if not 0 <= domain <= MAX_DOMAIN_ID:
        return f"{domain} is outside 0..{MAX_DOMAIN_ID} (the ROS 2 domain id range)"
    return None


def check_domain_id(value: str | int, option: str = "--domain-id") -> int:
    """``value`` as a ROS domain id (an integer 0..232), else :class:`ConfigError` naming ``option``."""
    problem = domain_id_problem(value)
    if problem is not None:
        raise ConfigError(f"{option}: {problem}")
    return int(str(value).strip())
