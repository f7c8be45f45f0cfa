"""A study file: a base scenario, the points (a grid or a list), the figures, the backend.

A study is a YAML mapping::

    name: pid_bandwidth            # optional; default: the file's stem
    scenario: pid_disturbance      # a shipped scenario's name or a path (relative to the study)
    backend: plain                 # plain (default: the plain-call loops) or nodes
    set:                           # optional: overrides of every point
      /**.duration_s: 0.5
    grid:                          # the product of the lists ...
      feedback.bandwidth_hz: [20, 40, 80]
      plant.disturbance.frequency_hz: [2, 4]
    # points:                      # ... or a list of override mappings
    #   - {feedback.bandwidth_hz: 20}
    figures:                       # paths into the summary of a run
      - tracking_error.all_samples.max_m
      - tracking_error.cycles[-1].rms_m

An override key is dotted. Its first component names the section of the
scenario file when it is one (``/**``, ``plant``, ``feedback``,
``feedforward``, ``learning``, ``identifier``, ``recorder`` or
``/<axis>/<role>``): ``feedforward.learning.cycle_s`` is the key
``learning.cycle_s`` of the ``feedforward`` section, ``/**.duration_s`` the
shared ``duration_s``. Otherwise the whole key must be present in exactly one
section of the base scenario and is set there (``disturbance.amplitude_Nm``
is the plant's). Nothing here imports rclpy.
"""

from __future__ import annotations

import copy
import difflib
import hashlib
import itertools
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from servo_axis.core.errors import ConfigError, did_you_mean
from servo_axis.params.overrides import Override
from servo_axis.params.scenario import (
    ROLES,
    SHARED_SECTION,
    axes_of,
    axis_section,
    check_shared_keys,
    find_scenario,
    flatten,
    load_scenario,
    not_found,
    resolve_table,
    shipped_file,
)

BACKENDS = ("plain", "nodes")
#: The top-level fields of a ``plain`` point's summary (:func:`servo_axis.sweep.point.plain_summary`):
#: those of ``summary.json`` that a plain-call loop computes, with the same paths.
PLAIN_SUMMARY_FIELDS = (
    "steps",
    "sim_time_s",
    "reference_period_s",
    "tracking_error",
    "ilc_convergence",
    "identification",
)
_KEYS = {"name", "scenario", "backend", "set", "grid", "points", "figures"}
_FIGURE = re.compile(r"^[A-Za-z_][\w]*(\[-?\d+\])*(\.[A-Za-z_][\w]*(\[-?\d+\])*)*$")
_PART = re.compile(r"([A-Za-z_]\w*)|\[(-?\d+)\]")


class StudyError(ConfigError):
    """A study file that cannot be run (the message names the key)."""


@dataclass(frozen=True)
class Study:
    """A checked study.

    Attributes
    ----------
    name : str
        The study's name.
    scenario : str
        The base scenario: a shipped name, or an absolute path.
    backend : str
        ``plain`` or ``nodes``.
    parameters : tuple of str
        The swept keys (the columns of the table), in order.
    points : tuple of dict
        Per point, the overrides (``set`` first, then the point's own).
    figures : dict
        Column name -> path into the summary.
    """

    name: str
    scenario: str
    backend: str
    parameters: tuple[str, ...]
    points: tuple[dict[str, Any], ...]
    figures: dict[str, str]
    fixed: dict[str, Any] = field(default_factory=dict)
    source: str = ""

    def fingerprint(self) -> str:
        """A hash of what the results depend on (base scenario bytes, points, figures, backend)."""
        return self._hash(figures=True)

    def runs_fingerprint(self) -> str:
        """A hash of what the runs depend on: :meth:`fingerprint` without the figures.

        Two studies with the same runs fingerprint run the same points; only the
        values they pick from each summary may differ (a corrected figure path).
        """
        return self._hash(figures=False)

    def _hash(self, *, figures: bool) -> str:
        content: dict[str, Any] = {
            "scenario": find_scenario(self.scenario).read_text(),
            "backend": self.backend,
            "points": list(self.points),
        }
        if figures:
            content["figures"] = self.figures
        text = json.dumps(content, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _fail(path: Path, key: str, problem: str) -> StudyError:
    return StudyError(f"study {path}: '{key}': {problem}")


def _scalar(value: Any) -> bool:
    """A parameter value: a number, a string, a bool, or a list of them (``forgetting: [...]``)."""
    if isinstance(value, list):
        return all(isinstance(v, bool | int | float | str) for v in value)
    return value is None or isinstance(value, bool | int | float | str)


def study_dir() -> Path:
    """The shipped studies' folder (``src/servo_axis/studies/``)."""
    return Path(__file__).resolve().parents[1] / "studies"


def find_study(name_or_path: str | Path) -> Path:
    """A study file from a path, or from the name of a shipped study (``reversal_004``)."""
    found = shipped_file(name_or_path, study_dir())
    if found is not None:
        return found
    names = sorted(p.stem for p in study_dir().glob("*.yaml"))
    raise StudyError(not_found("study", name_or_path, names, None))


def load_study(path: Path | str, extra: Sequence[Override] = ()) -> Study:
    """Read and check a study file or shipped study (each point's overrides are checked once).

    ``extra`` (``sweep --set``, :mod:`servo_axis.params.overrides`) is added
    to the study's ``set``, after it, so that it overrides the same keys of
    every point but the swept ones; an error it causes names it.

    Raises
    ------
    StudyError
        One line that names the file and the key.
    """
    path = find_study(path)
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as err:
        raise StudyError(f"study {path}: cannot read it: {err.strerror}") from err
    except yaml.YAMLError as err:
        raise StudyError(f"study {path}: not valid YAML: {str(err).splitlines()[0]}") from err
    if not isinstance(data, dict):
        raise StudyError(f"study {path}: expected a mapping")
    for key in data:
        if key not in _KEYS:
            hint = did_you_mean(key, _KEYS)
            raise _fail(
                path,
                str(key),
                f"unknown key; {hint + ' ' if hint else ''}expected one of {sorted(_KEYS)}",
            )
    if "scenario" not in data or not isinstance(data["scenario"], str):
        raise _fail(path, "scenario", "required: a shipped scenario's name or a path")
    scenario_text = data["scenario"]
    candidate = path.parent / scenario_text
    scenario = str(candidate.resolve()) if candidate.is_file() else scenario_text
    try:
        base = load_scenario(find_scenario(scenario))
    except ConfigError as err:
        raise _fail(path, "scenario", str(err)) from err
    backend = data.get("backend", "plain")
    if backend not in BACKENDS:
        raise _fail(path, "backend", f"{backend!r}; expected one of {list(BACKENDS)}")
    fixed = data.get("set") or {}
    if not isinstance(fixed, dict) or not all(_scalar(v) for v in fixed.values()):
        raise _fail(path, "set", "expected a mapping of dotted keys to values")
    given: dict[str, str] = {}  # study key -> the --set that gave it
    for o in extra:
        value = o.value
        leaves = flatten(value, f"{o.key}.") if isinstance(value, dict) else {o.key: value}
        for key, leaf in leaves.items():
            given[f"{o.section}.{key}"] = o.text
            fixed = {**fixed, f"{o.section}.{key}": leaf}
    if ("grid" in data) == ("points" in data):
        raise _fail(path, "grid", "give either 'grid' or 'points' (one of them)")
    own: list[dict[str, Any]]
    if "grid" in data:
        grid = data["grid"]
        if not isinstance(grid, dict) or not grid:
            raise _fail(path, "grid", "expected a mapping of dotted keys to lists of values")
        for key, values in grid.items():
            if not isinstance(values, list) or not values or not all(_scalar(v) for v in values):
                raise _fail(path, f"grid.{key}", "expected a non-empty list of values")
        keys = list(grid)
        own = [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())]
    else:
        raw = data["points"]
        if not isinstance(raw, list) or not raw:
            raise _fail(path, "points", "expected a non-empty list of override mappings")
        own = []
        for i, point in enumerate(raw):
            if not isinstance(point, dict) or not all(_scalar(v) for v in point.values()):
                raise _fail(path, f"points[{i}]", "expected a mapping of dotted keys to values")
            own.append(dict(point))
        keys = list(dict.fromkeys(k for p in own for k in p))
    figures = _figures(path, data.get("figures"))
    points = tuple({**fixed, **p} for p in own)
    for i, point in enumerate(points):
        trial = copy.deepcopy(base)
        for key, value in point.items():
            where = f"points[{i}].{key}" if "points" in data else key
            if key in given and key not in own[i]:
                where = f"--set {given[key]}"
            try:
                apply_override(trial, key, value)
                _check_section(trial, _section_of(trial, key)[0])
            except ConfigError as err:
                raise _fail(path, where, f"{err} (value {value!r})") from err
    # Before any point runs: a figure no summary can have would only show up as a
    # failed row of every point, after all of them ran.
    summary_kind = "axes" if axes_of(base) else backend
    unit = _error_unit(base)
    for name, where in figures.items():
        problem = figure_problem(where, summary_kind, unit=unit)
        if problem:
            raise _fail(path, f"figures.{name}", problem)
    return Study(
        name=str(data.get("name") or path.stem),
        scenario=scenario,
        backend=backend,
        parameters=tuple(str(k) for k in keys),
        points=points,
        figures=figures,
        fixed=dict(fixed),
        source=str(path),
    )


def _figures(path: Path, raw: Any) -> dict[str, str]:
    if isinstance(raw, list):
        raw = {str(f): f for f in raw}
    if not isinstance(raw, dict) or not raw:
        raise _fail(path, "figures", "expected a non-empty list of summary paths (or name: path)")
    for name, figure in raw.items():
        if not isinstance(figure, str) or not _FIGURE.match(figure):
            raise _fail(path, f"figures.{name}", f"{figure!r} is not a path like a.b[-1].c")
    return {str(k): str(v) for k, v in raw.items()}


def _summary_fields(kind: str) -> dict[str, Any]:
    """The top-level fields (name -> type) of a point's summary: ``plain``, ``nodes`` or ``axes``."""
    from servo_axis.analysis.summary import AxesSummary, RunSummary

    fields = _dataclass_fields(AxesSummary if kind == "axes" else RunSummary)
    if kind == "plain":
        plain = {k: v for k, v in fields.items() if k in PLAIN_SUMMARY_FIELDS}
        # A point with the excitation on: the identification's errors (identify/study.py),
        # a mapping whose keys the plant's model decides.
        return {**plain, "sysid": dict[str, Any] | None}
    return fields


def _dataclass_fields(cls: type) -> dict[str, Any]:
    """The fields ``summary.json`` writes of a dataclass, with their types."""
    import dataclasses
    import typing

    hints = typing.get_type_hints(cls)
    return {
        f.name: hints[f.name] for f in dataclasses.fields(cls) if f.metadata.get("summary", True)
    }


def _strip_none(kind: Any) -> Any:
    """``X`` of ``X | None``."""
    import types
    import typing

    if typing.get_origin(kind) in (types.UnionType, typing.Union):
        args = [a for a in typing.get_args(kind) if a is not type(None)]
        return args[0] if len(args) == 1 else Any
    return kind


def _error_unit(scenario: dict[str, Any]) -> str:
    """``rad`` when the scenario's plant model turns its table (``rotary``), else ``m``."""
    from servo_axis.analysis.tracking import axis_values, error_unit

    try:
        return error_unit(axis_values(scenario))
    except ConfigError:
        return "m"  # a multi-axis scenario: its sections are checked per point


def figure_problem(path: str, kind: str, *, unit: str = "m") -> str | None:
    """What is wrong with a figure path for a point's summary, or None when it may be there.

    The path is checked against the summary's layout (the dataclasses of
    :mod:`servo_axis.analysis.summary` and their type hints): each name a
    field of the block it is in, each ``[i]`` on a list. What only a run
    decides (a block absent from some runs, an index past the end, the keys of
    a mapping) is left to the run.

    Parameters
    ----------
    path : str
        ``a.b[-1].c``.
    kind : str
        ``plain`` (the plain-call loops' fields), ``nodes`` (``summary.json``
        of a single-axis run) or ``axes`` (of a multi-axis run).
    unit : str
        The tracking error's unit of the study's scenario: ``m``, or ``rad``
        on a rotary table, whose summary names the errors ``rms_rad``,
        ``max_rad`` (:func:`servo_axis.analysis.tracking.unit_keys`).
    """
    import dataclasses
    import typing

    node: Any = None
    fields: dict[str, Any] | None = _summary_fields(kind)
    done = ""
    for name, index in _PART.findall(path):
        if fields is not None:
            if not name:
                return f"{path!r}: [{index}] at '{done or '.'}', which is a block, not a list"
            if unit != "m" and done.startswith("tracking_error") and name in fields:
                if name.endswith("_m"):
                    return (
                        f"{path!r}: the errors of a rotary table are in {unit}: "
                        f"did you mean '{name[:-2]}_{unit}'?"
                    )
            elif unit != "m" and done.startswith("tracking_error"):
                if name.endswith(f"_{unit}") and f"{name[: -len(unit) - 1]}_m" in fields:
                    name = f"{name[: -len(unit) - 1]}_m"
            if name not in fields:
                close = difflib.get_close_matches(name, fields, n=1)
                hint = f"did you mean '{close[0]}'? " if close else ""
                return (
                    f"{path!r}: no '{name}' at '{done or '.'}' of a {kind} point's summary; "
                    f"{hint}expected one of {', '.join(fields)}"
                )
            node = _strip_none(fields[name])
            done = f"{done}.{name}" if done else name
        else:
            origin = typing.get_origin(node)
            if node is Any or origin is dict:
                node = Any if node is Any else _strip_none(typing.get_args(node)[1])
                done = f"{done}.{name}" if name else f"{done}[{index}]"
                fields = _dataclass_fields(node) if dataclasses.is_dataclass(node) else None
                continue
            if origin in (tuple, list):
                if name:
                    return f"{path!r}: '{done}' is a list; index it first: '{done}[-1]'"
                node = _strip_none(typing.get_args(node)[0])
                done = f"{done}[{index}]"
            else:
                return f"{path!r}: '{done}' is a value ({getattr(node, '__name__', node)}), not a block"
        if dataclasses.is_dataclass(node) and isinstance(node, type):
            fields = _dataclass_fields(node)
        else:
            fields = None
    return None


def _section_of(scenario: dict[str, Any], key: str) -> tuple[str, str]:
    """``(section, key within it)`` of an override key (see the module's docstring)."""
    head, _, rest = key.partition(".")
    if rest and (head == SHARED_SECTION or head in ROLES or axis_section(head) is not None):
        return head, rest
    holders = [s for s, v in scenario.items() if _has(v.get("ros__parameters") or {}, key)]
    close = did_you_mean(head, [SHARED_SECTION, *ROLES]) if rest else ""
    if not holders and close:
        raise ConfigError(f"unknown section '{head}'; {close}")
    if len(holders) != 1:
        raise ConfigError(
            f"in no section of the scenario; name it: '<section>.{key}' "
            f"(sections: {', '.join(scenario)})"
            if not holders
            else f"in several sections ({', '.join(holders)}); name one: '<section>.{key}'"
        )
    return holders[0], key


def _check_section(scenario: dict[str, Any], section: str) -> None:
    """Check the parameters of the roles a section sets (names, types, ranges)."""
    from servo_axis.params.resolve import Resolved

    if section == SHARED_SECTION:
        check_shared_keys(scenario, "")
    roles = [r for r in ROLES if r in scenario] if section == SHARED_SECTION else [section]
    resolved = Resolved(scenario)
    for role in roles:
        if role in ROLES and role != "recorder":
            resolved.values(role)


def _has(params: dict[str, Any], dotted: str) -> bool:
    node: Any = params
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def apply_override(
    scenario: dict[str, Any], key: str, value: Any, *, check_only: bool = False
) -> None:
    """Set one dotted override in a scenario mapping (in place, unless ``check_only``)."""
    section, inner = _section_of(scenario, key)
    if check_only:
        scenario = copy.deepcopy(scenario)
    params = scenario.setdefault(section, {"ros__parameters": {}}).setdefault("ros__parameters", {})
    parts = inner.split(".")
    node = params
    for part in parts[:-1]:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ConfigError(f"'{part}' of section '{section}' is a value, not a mapping")
        node = child
    old = node.get(parts[-1])
    if isinstance(old, dict):
        raise ConfigError(f"section '{section}' has a mapping at '{inner}', not a value")
    node[parts[-1]] = value


def scenario_for(study_scenario: str, overrides: dict[str, Any]) -> tuple[dict[str, Any], Path]:
    """The base scenario with the overrides applied, and the base file.

    Relative ``file`` keys are made absolute (relative to the base file's
    directory), so the result may be written anywhere.
    """
    base_path = find_scenario(study_scenario)
    scenario = load_scenario(base_path)
    for key, value in overrides.items():
        apply_override(scenario, key, value)
    _absolute_files(scenario, base_path.parent)
    return scenario, base_path


def _absolute_files(node: Any, directory: Path) -> None:
    if isinstance(node, dict):
        for key, value in node.items():
            if key == "file" and isinstance(value, str):
                node[key] = resolve_table(value, directory)
            else:
                _absolute_files(value, directory)


def figure(summary: Any, path: str) -> Any:
    """The value at ``path`` (``a.b[-1].c``) of a summary mapping.

    Raises
    ------
    KeyError
        With the part of the path that is not there.
    """
    node = summary
    done = ""
    for name, index in _PART.findall(path):
        if name:
            if not isinstance(node, dict) or name not in node:
                raise KeyError(f"figure {path!r}: no '{name}' in the summary at '{done or '.'}'")
            node = node[name]
            done = f"{done}.{name}" if done else name
        else:
            i = int(index)
            if not isinstance(node, list) or not -len(node) <= i < len(node):
                raise KeyError(f"figure {path!r}: no [{i}] at '{done}'")
            node = node[i]
            done = f"{done}[{i}]"
    return node


def dump_scenario(scenario: dict[str, Any], path: Path) -> None:
    """Write a scenario mapping as YAML."""
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
