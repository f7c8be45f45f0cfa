"""Overrides of a scenario's keys from the command line: ``run SCENARIO --set SECTION.KEY=VALUE``.

``SECTION`` is a section of the scenario file: ``shared`` (or ``/**``) for
the keys every node reads, a node's (``plant``, ``feedback``,
``feedforward``, ``learning``, ``identifier``, ``recorder``), or, in a
multi-axis scenario, ``/<axis>/<node>``. ``KEY`` is the key as the scenario
loader flattens it, dotted where the file nests (``friction.elements``,
``reference.amplitude_m``). ``VALUE`` is read as YAML, as the file's value
would be (``8`` an integer, ``1.5e-3`` a number, ``true`` a boolean,
``[1, 2]`` a list, ``.nan`` NaN, anything else a string); a mapping
(``{enabled: true, cutoff_hz: 80}``) sets each of its keys.

An override is checked as the key would be in the file (the run plans the
scenario with every override applied); what it gets wrong is one line
naming it (:func:`blame`). Nothing here imports rclpy.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import yaml

from servo_axis.core.errors import ConfigError, did_you_mean
from servo_axis.params.scenario import (
    ROLES,
    SHARED_SECTION,
    axes_of,
    axis_section,
    check_shared_keys,
    flatten,
    safe_load_text,
    yaml_problem,
)

#: The name of the shared section ``/**`` on the command line.
SHARED_NAME = "shared"

T = TypeVar("T")


@dataclass(frozen=True)
class Override:
    """One ``--set SECTION.KEY=VALUE``.

    Attributes
    ----------
    text : str
        As given (the summary records it, the errors quote it).
    section : str
        The section of the scenario file: ``/**``, a role or ``/<axis>/<role>``.
    key : str
        The dotted key within the section.
    value : object
        The value, read as YAML.
    """

    text: str
    section: str
    key: str
    value: Any


def parse_override(text: str) -> Override:
    """An override from ``SECTION.KEY=VALUE``; its section checked by name (not yet against a scenario).

    Raises
    ------
    ConfigError
        ``'<text>': ...`` for a missing ``=``, section or key, an unknown
        section (with the closest name), a value that is not YAML.
    """
    where, eq, raw = text.partition("=")
    if not eq:
        raise ConfigError(f"{text!r}: expected SECTION.KEY=VALUE (e.g. feedback.bandwidth_hz=30)")
    section, dot, key = where.strip().partition(".")
    if where.strip().startswith(SHARED_SECTION + "."):
        section, key = SHARED_SECTION, where.strip()[len(SHARED_SECTION) + 1 :]
    if not dot or not key or not section or "" in key.split("."):
        raise ConfigError(
            f"{text!r}: expected SECTION.KEY=VALUE, the key after its section and a dot "
            "(e.g. shared.duration_s=1, plant.friction.elements=8)"
        )
    if section == SHARED_NAME:
        section = SHARED_SECTION
    if section != SHARED_SECTION and section not in ROLES and axis_section(section) is None:
        names = [SHARED_NAME, *ROLES]
        hint = did_you_mean(section, names) or f"expected {', '.join(names)} or /<axis>/<node>"
        if section.startswith("/") and section.count("/") == 2:
            role = section.rpartition("/")[2]
            hint = did_you_mean(role, ROLES) or f"the node is one of {', '.join(ROLES)}"
        raise ConfigError(f"{text!r}: unknown section '{section}'; {hint}")
    if not raw.strip():
        raise ConfigError(f"{text!r}: no value after '='")
    try:
        value = safe_load_text(raw)
    except yaml.YAMLError as err:
        raise ConfigError(f"{text!r}: the value is not YAML: {yaml_problem(err)}") from None
    return Override(text=text, section=section, key=key, value=value)


def apply_overrides(scenario: dict[str, Any], overrides: Sequence[Override]) -> dict[str, Any]:
    """A copy of ``scenario`` with ``overrides`` applied in order (the last one of a key wins).

        Each is set in the section it names, where the file has the key (nested
        or dotted) or nested as the loader would flatten it; the shared keys
        are checked as the loader checks them
    (:func:`~servo_axis.params.scenario.check_shared_keys`).
        The node sections are checked by whoever plans the result.

        Raises
        ------
        ConfigError
            ``--set <text>: ...`` for a section the scenario does not have
            (an axis of another scenario, a node it does not start), a key that
            names a group of keys, a value that is a mapping where the key is a value.
    """
    out = copy.deepcopy(scenario)
    axes = axes_of(out)
    for o in overrides:
        _check_section(o, out, axes)
        params = out.setdefault(o.section, {"ros__parameters": {}})["ros__parameters"]
        leaves = flatten(o.value, f"{o.key}.") if isinstance(o.value, dict) else {o.key: o.value}
        if not leaves:
            raise ConfigError(f"--set {o.text}: an empty mapping sets nothing")
        for key, value in leaves.items():
            _set(params, key.split("."), value, o)
        if o.section == SHARED_SECTION:
            check_shared_keys(out, f"--set {o.text}")
    return out


def _check_section(o: Override, scenario: dict[str, Any], axes: list[str]) -> None:
    """The section of ``o`` is one ``scenario`` has (``/**`` always is)."""
    if o.section == SHARED_SECTION:
        return
    found = axis_section(o.section)
    if found is None:
        if o.section not in scenario:
            have = [SHARED_NAME, *(s for s in scenario if s != SHARED_SECTION)]
            raise ConfigError(
                f"--set {o.text}: the scenario has no '{o.section}' section (it starts no "
                f"{o.section} node); its sections: {', '.join(have)}"
            )
        return
    axis, role = found
    if not axes:
        raise ConfigError(
            f"--set {o.text}: a single-axis scenario has no per-axis sections; "
            f"set {role}.{o.key} instead"
        )
    if axis not in axes:
        hint = did_you_mean(axis, axes) or f"its axes: {', '.join(axes)}"
        raise ConfigError(f"--set {o.text}: the scenario has no axis '{axis}'; {hint}")
    if role not in scenario and o.section not in scenario:
        raise ConfigError(f"--set {o.text}: the scenario starts no {role} node on axis '{axis}'")


def _set(params: dict[str, Any], parts: list[str], value: Any, o: Override) -> None:
    """Set ``parts`` (a dotted key) in ``params``, where the file spells it, else nested."""
    for j in range(len(parts), 0, -1):  # the longest spelling present: "a.b" before "a"
        head, rest = ".".join(parts[:j]), parts[j:]
        if head not in params:
            continue
        here = params[head]
        if not rest:
            if isinstance(here, dict):
                keys = ", ".join(sorted(f"{head}.{k}" for k in flatten(here)))
                raise ConfigError(
                    f"--set {o.text}: '{head}' of section '{o.section}' is a group of keys "
                    f"({keys}), not one value"
                )
            params[head] = value
            return
        if isinstance(here, dict):
            _set(here, rest, value, o)
            return
    node = params
    for part in parts[:-1]:
        node = node.setdefault(part, {})
    node[parts[-1]] = value


def blame(
    err: ConfigError, overrides: Sequence[Override], attempt: Callable[[Sequence[Override]], T]
) -> ConfigError:
    """``err`` (raised with every override applied) as one line naming the override at fault.

    ``attempt(overrides)`` plans the scenario with those overrides. The
    override at fault is the last of the shortest prefix of ``overrides``
    whose plan fails with ``err``'s message: ``--set <its text>: <err>``.
    An error the scenario has without any override (a bad ``--out``) is
    returned as it is.
    """
    message = str(err)
    if not overrides or message.startswith("--set "):
        return err
    try:
        attempt(())
    except ConfigError as alone:
        if str(alone) == message:
            return err  # the scenario's own problem, or the run's, whatever was set
    for i in range(1, len(overrides) + 1):
        try:
            attempt(overrides[:i])
        except ConfigError as first:
            if str(first) == message:
                return type(err)(f"--set {overrides[i - 1].text}: {message}")
    return err
    try:
        attempt(())
    except ConfigError:
        return err  # the scenario's own problem, whatever was set
    for i in range(1, len(overrides) + 1):
        try:
            attempt(overrides[:i])
        except ConfigError as first:
            culprit = overrides[i - 1]
            return type(err)(f"--set {culprit.text}: {first}")
    return err
