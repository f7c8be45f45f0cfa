"""Outside the parameter layer the checked values are read as attributes, never by key.

The values of a node's section are typed (:mod:`servo_axis.params.typed`):
``values.dob.cutoff_hz``, which mypy checks, not ``values["dob.cutoff_hz"]``,
which nothing checks until it runs. The mapping of dotted keys they also are
is for plugins written before and for code that walks a schema (a variable
key: ``values[key]``). This fails on a lookup of a literal parameter key (or
an f-string key) in a values object under any of its spellings anywhere in
``src/servo_axis`` but ``params/`` (the layer that makes them) and ``core/``
(which takes no parameter values: it imports nothing of ``params``).
"""

from __future__ import annotations

import ast
from pathlib import Path

from servo_axis.params.registry import REGISTRIES, parameter_sections

SRC = Path(__file__).resolve().parents[3] / "src" / "servo_axis"

#: How a values object is spelled: a variable, an attribute, or a call that returns one.
NAMES = {"values", "v", "_v", "pv", "fbv", "ffv", "lv", "iv"}
CALLS = {"node_values", "checked_values", "feedforward_values", "axis_values", "as_values"}


def _keys() -> set[str]:
    keys: set[str] = set()
    for schema in parameter_sections().values():
        keys |= set(schema)
    for registry in REGISTRIES.values():
        for name in registry:
            keys |= set(registry[name].schema)
    return keys


def _values_like(node: ast.expr) -> bool:
    if isinstance(node, ast.Name):
        return node.id in NAMES or node.id.endswith("_values")
    if isinstance(node, ast.Attribute):
        return node.attr in NAMES or node.attr.endswith("_values")
    if isinstance(node, ast.Call):
        func = node.func
        name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", "")
        return name in CALLS
    return False


def _literal_key(node: ast.expr, keys: set[str]) -> bool:
    if isinstance(node, ast.JoinedStr):
        return True
    return isinstance(node, ast.Constant) and node.value in keys


def lookups(path: Path, keys: set[str], root: Path = SRC) -> list[str]:
    """Each ``values["<key>"]`` / ``values.get("<key>")`` of ``path``: ``file:line: code``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Subscript):
            hit = _values_like(node.value) and _literal_key(node.slice, keys)
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "get"
            and node.args
        ):
            hit = _values_like(node.func.value) and _literal_key(node.args[0], keys)
        else:
            continue
        if hit:
            found.append(f"{path.relative_to(root)}:{node.lineno}: {ast.unparse(node)}")
    return found


def test_no_values_lookup_by_key_outside_the_parameter_layer() -> None:
    keys = _keys()
    assert {"dob.cutoff_hz", "control_period_s", "friction.coulomb_Nm", "mnc.enabled"} <= keys
    files = [
        p
        for p in sorted(SRC.rglob("*.py"))
        if p.relative_to(SRC).parts[0] not in ("params", "core")
    ]
    assert any(p.name == "feedback.py" for p in files)
    found = [hit for path in files for hit in lookups(path, keys)]
    assert not found, "read the attribute instead:\n" + "\n".join(found)


def test_the_check_finds_each_spelling(tmp_path: Path) -> None:
    code = (
        "a = values['dob.cutoff_hz']\n"
        "b = self._v['mode']\n"
        "c = node.values.get('control_period_s')\n"
        "d = node_values(s, 'plant')['model']\n"
        "e = pv[f'modes.{k}']\n"
        "f = values[key]\n"  # a variable key (walking a schema): allowed
        "g = summary['steps']\n"  # not values
        "h = SHARED['mode']\n"  # a schema's Param
    )
    path = tmp_path / "probe.py"
    path.write_text(code)
    found = lookups(path, _keys(), tmp_path)
    assert [line.split(":")[1] for line in found] == ["1", "2", "3", "4", "5"]
