"""Scenario files: loading, finding by name, per-node and per-axis views.

A scenario is a ROS parameter file: a ``/**`` block of shared keys and one
section per node (``plant``, ``feedback``, ``feedforward``, ``learning``,
``recorder``), or ``/<axis>/<node>`` sections for a multi-axis scenario.
The scenarios of the project ship with the package (``servo_axis/scenarios``;
``config/`` of a source checkout is the same folder), so that
``python -m servo_axis run rptc_detailed`` works from an installed package.
Nothing here imports rclpy.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from servo_axis.core.errors import ConfigError, ParameterFileError, closest, did_you_mean
from servo_axis.params.param import BUILTIN
from servo_axis.params.registry import term_files
from servo_axis.params.schemas import SHARED

#: Node roles, in the order of the sections of a scenario file.
ROLES = ("plant", "feedback", "feedforward", "learning", "identifier", "recorder")
#: The order in which the runner starts them (recorder first, plant last).
START_ORDER = ("recorder", "learning", "identifier", "feedforward", "feedback", "plant")
SHARED_SECTION = "/**"


def scenario_dir() -> Path:
    """The folder of the scenarios shipped with the package."""
    return Path(str(resources.files("servo_axis") / "scenarios"))


def scenario_names() -> list[str]:
    """Names of the shipped scenarios (file stems), sorted."""
    return sorted(p.stem for p in scenario_dir().glob("*.yaml"))


def find_scenario(name_or_path: str | Path) -> Path:
    """A scenario file from a path, or from the name of a shipped scenario.

    Raises
    ------
    ConfigError
        If ``name_or_path`` is neither an existing file nor a shipped
        scenario's name (the message lists the names).
    """
    found = shipped_file(name_or_path, scenario_dir())
    if found is not None:
        return found
    raise ConfigError(not_found("scenario", name_or_path, scenario_names(), "list"))


def not_found(kind: str, name_or_path: str | Path, names: list[str], listing: str | None) -> str:
    """Why ``name_or_path`` is no file and no shipped ``kind``: the closest names, or how to list them.

    A bare name (no folder, no ``.yaml``) is taken for a shipped one's
    name (the closest ones, or those it begins: ``ptc``), anything else for
    a path. ``listing`` is the command that lists the shipped ones (None:
    the names are given).
    """
    path = Path(name_or_path)
    text = str(name_or_path)
    if path.is_dir():
        return f"{kind} {text}: is a directory, expected a {kind} file (YAML) or a shipped name"
    if path.parent != Path(".") or path.suffix in (".yaml", ".yml"):
        why = (
            "no such file" if path.parent.is_dir() else f"no such file (no directory {path.parent})"
        )
        if path.stem in names:
            why += f"; the shipped {kind} {path.stem} is named by its name alone"
        return f"{kind} {text}: {why}"
    stem = text.removesuffix(".yaml")
    found = closest(stem, names, n=3) or [n for n in names if n.startswith(stem)][:3]
    if found:
        hint = "did you mean " + " or ".join(f"'{n}'" for n in found) + "?"
    elif listing is None:
        hint = f"the shipped ones: {', '.join(names)}"
    else:
        hint = f"`python -m servo_axis {listing}` shows the {len(names)} shipped ones"

    return f"{kind} {text!r}: neither a file nor a shipped {kind}; {hint}"


def shipped_file(name_or_path: str | Path, folder: Path) -> Path | None:
    """``name_or_path`` if it is a file, else ``folder/<name>.yaml`` if it is one; None otherwise.

    A bare name (no folder part), with or without ``.yaml``, names a file of
    ``folder`` (the shipped scenarios, studies, ...).
    """
    path = Path(name_or_path)
    if path.is_file():
        return path
    shipped = folder / f"{path.stem if path.suffix == '.yaml' else path.name}.yaml"
    return shipped if path.parent == Path(".") and shipped.is_file() else None


#: libyaml's parser where PyYAML has it (a scenario in 0.2 ms instead of 2 ms:
#: the core-only loop reads its file on every call); the values are built by
#: the same safe constructor.
_FAST_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def safe_load_text(text: str) -> Any:
    """``yaml.safe_load(text)``, parsed by libyaml when PyYAML has it.

    A text libyaml refuses is parsed again by PyYAML's own parser, so an
    error says what ``yaml.safe_load`` says (its words and position).
    """
    try:
        return yaml.load(text, Loader=_FAST_LOADER)
    except yaml.YAMLError:
        return yaml.safe_load(text)


def load_scenario(path: Path) -> dict[str, Any]:
    """Read a scenario (a ROS parameter file) and check its top-level layout."""
    try:
        data = safe_load_text(Path(path).read_text())
    except OSError as err:
        raise ConfigError(f"scenario {path}: cannot read it: {err}") from err
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        raise ConfigError(f"scenario {path}: not valid YAML: {yaml_problem(err)}") from err
    if not isinstance(data, dict):
        raise ConfigError(f"scenario {path}: expected a mapping of node sections")
    for key, value in data.items():
        if key != SHARED_SECTION and key not in ROLES and axis_section(key) is None:
            raise ConfigError(f"scenario {path}: unknown section '{key}'; {section_hint(key)}")
        if not isinstance(value, dict) or set(value) != {"ros__parameters"}:
            raise ConfigError(f"scenario {path}: section '{key}' must hold only 'ros__parameters'")
    if "plant" not in data:
        raise ConfigError(f"scenario {path}: a 'plant' section is required")
    check_shared_keys(data, f"scenario {path}")
    return data


def section_hint(key: object) -> str:
    """What an unknown section of a scenario file may have meant."""
    text = str(key)
    if text.startswith("/") and text.count("/") == 2:  # /<axis>/<node>
        axis, role = text.split("/")[1:]
        if not axis.isidentifier():
            return f"'{axis}' is not an axis name (letters, digits, '_')"
        hint = did_you_mean(role, ROLES)
        return hint or f"the node of '/<axis>/<node>' is one of {', '.join(ROLES)}"
    return did_you_mean(text, [SHARED_SECTION, *ROLES]) or (
        f"expected '/**', one of {', '.join(ROLES)} or '/<axis>/<node>'"
    )


def check_shared_keys(scenario: dict[str, Any], where: str) -> None:
    """Every key of the shared ``/**`` section is a shared parameter.

    Every node reads the whole ``/**`` section, so a key there that is not
    shared is refused by the first node checked (``unknown parameter
    'duraton_s' for node 'plant'``), which named the node but not the
    section the key is in.

    Raises
    ------
    ParameterFileError
        ``<where>: unknown parameter '<key>' in the shared section '/**'``,
        with the closest shared key and the list of them.
    """
    unknown = sorted(set(flatten(shared(scenario))) - set(SHARED) - BUILTIN)
    if not unknown:
        return
    hint = did_you_mean(unknown[0], SHARED) or f"the shared keys: {', '.join(SHARED)}"
    prefix = f"{where}: " if where else ""
    raise ParameterFileError(
        f"{prefix}unknown parameter '{unknown[0]}' in the shared section '/**', which every "
        f"node reads ({hint}; a node's own key goes in its section)"
    )


def params_files(args: list[str]) -> list[str]:
    """The files of the ``--params-file FILE`` options of a ROS command line."""
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a == "--params-file"]


def check_params_files(args: list[str]) -> None:
    """Every ``--params-file`` of a node's command line exists and is YAML, before rcl reads it.

    rcl's own refusal is an exception with a C source location and a log
    line; this names the file and the problem in one line.

    Raises
    ------
    ConfigError
        ``parameter file <path>: ...`` for a file that cannot be read or is
        not valid YAML (the position of the error in the message).
    """
    for name in params_files(args):
        try:
            yaml.safe_load(Path(name).read_text())
        except OSError as err:
            raise ConfigError(f"parameter file {name}: cannot read it: {err.strerror}") from err
        except (yaml.YAMLError, UnicodeDecodeError) as err:
            raise ConfigError(
                f"parameter file {name}: not valid YAML: {yaml_problem(err)}"
            ) from err


def yaml_problem(err: Exception) -> str:
    """A YAML error in one line: the problem and where (1-based line, column)."""
    if not isinstance(err, yaml.MarkedYAMLError) or err.problem is None:
        return " ".join(str(err).split())
    text = str(err.problem)
    if err.problem_mark is not None:
        text += f" at line {err.problem_mark.line + 1}, column {err.problem_mark.column + 1}"
    if err.context and err.context_mark is not None:
        mark = err.context_mark
        text += f" ({err.context} from line {mark.line + 1}, column {mark.column + 1})"
    return text


def axis_section(key: str) -> tuple[str, str] | None:
    """``(axis, role)`` of a per-axis section key ``/<axis>/<role>``, else None."""
    parts = key.split("/")
    if len(parts) == 3 and parts[0] == "" and parts[1].isidentifier() and parts[2] in ROLES:
        return parts[1], parts[2]
    return None


def axes_of(scenario: dict[str, Any]) -> list[str]:
    """Axes of a multi-axis scenario (from its ``/<axis>/<node>`` sections), sorted; [] if none."""
    return sorted({a[0] for key in scenario if (a := axis_section(key)) is not None})


def merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """Nested mappings merged; ``over`` wins."""
    out = dict(base)
    for k, v in over.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def axis_view(scenario: dict[str, Any], axis: str, scenario_dir: Path) -> dict[str, Any]:
    """The single-axis scenario of one axis of a multi-axis scenario.

    Each ``/<axis>/<node>`` section is merged into the node's common section
    (nested keys merge, the axis wins), ``axis`` is set to the axis name and
    a relative file path of a feedforward term (``friction_table.file``, ...)
    is made absolute, so that the result runs and is reported like any
    single-axis scenario.
    """
    view: dict[str, Any] = {}
    common = shared(scenario)
    common["axis"] = axis
    about = dict(common.get("scenario", {}))
    about["name"] = f"{about.get('name', 'scenario')}/{axis}"
    common["scenario"] = about
    view[SHARED_SECTION] = {"ros__parameters": common}
    for role in ROLES:
        own = scenario.get(f"/{axis}/{role}", {}).get("ros__parameters", {})
        if role in scenario or own:
            base = scenario.get(role, {}).get("ros__parameters", {})
            view[role] = {"ros__parameters": merge(base, own)}
    return with_term_files(view, lambda key, path: resolve_table(path, scenario_dir))


def with_term_files(scenario: dict[str, Any], change: Callable[[str, str], str]) -> dict[str, Any]:
    """``scenario`` with each file a feedforward term names replaced by ``change(key, path)``.

    The keys are those of :func:`~servo_axis.params.registry.term_files`
    (``friction_table.file``, ``gms.file``, an outside term's), nested
    (``friction_table: {file: ...}``) or dotted; an empty one is left as it
    is. The other sections are shared with ``scenario``, the feedforward's
    is a new mapping.
    """
    if "feedforward" not in scenario:
        return scenario
    ff = dict(scenario["feedforward"].get("ros__parameters", {}))
    for key in term_files():  # friction_table.file, gms.file, an outside term's
        term, _, leaf = key.rpartition(".")
        if isinstance(ff.get(term), dict) and ff[term].get(leaf):
            ff[term] = {**ff[term], leaf: change(key, str(ff[term][leaf]))}
        elif ff.get(key):
            ff[key] = change(key, str(ff[key]))
    return {**scenario, "feedforward": {"ros__parameters": ff}}


def resolve_table(path_text: str, scenario_dir: Path) -> str:
    """A table path of a scenario: relative ones are relative to the scenario's directory."""
    if path_text and not Path(path_text).is_absolute():
        return str(scenario_dir / path_text)
    return path_text


def shared(scenario: dict[str, Any]) -> dict[str, Any]:
    """The ``/**`` parameters of a scenario."""
    return dict(scenario.get(SHARED_SECTION, {}).get("ros__parameters", {}))


def flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested YAML mappings as dotted keys (``{a: {b: 1}}`` is ``{"a.b": 1}``)."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def node_params(scenario: dict[str, Any], role: str) -> dict[str, Any]:
    """The section of one node, flattened to dotted keys, on top of the shared ones."""
    return {
        **flatten(shared(scenario)),
        **flatten(scenario.get(role, {}).get("ros__parameters", {})),
    }


def roles_of(scenario: dict[str, Any]) -> list[str]:
    """Nodes a scenario starts: those with a section, in start order."""
    return [r for r in START_ORDER if r in scenario]


class _QuotingDumper(yaml.SafeDumper):  # type: ignore[misc]
    """Quotes every string: rcl's parameter parser reads a bare ``y``, ``on``
    or ``1e3`` as a bool or a number, PyYAML writes them bare. Never writes
    an alias: rcl refuses them ("Will not support aliasing"), and PyYAML
    writes one for a list that two sections share."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


_QuotingDumper.add_representer(
    str, lambda dumper, value: dumper.represent_scalar("tag:yaml.org,2002:str", value, style='"')
)


def dump_params(data: dict[str, Any]) -> str:
    """A ROS parameter file's text, every string quoted."""
    return str(yaml.dump(data, Dumper=_QuotingDumper, sort_keys=False))
