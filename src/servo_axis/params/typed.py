"""Typed parameter values: a section's keys as a frozen dataclass, dotted keys as nested groups.

As generate_parameter_library gives a ROS 2 node ``params.<group>.<key>``, the
checked values of a node's section are a frozen dataclass whose attributes
follow its dotted keys: ``values.dob.cutoff_hz`` is the key ``dob.cutoff_hz``
(each group of keys, ``dob.*``, a :class:`Group` of its own). The classes of
the nodes' own keys (:mod:`servo_axis.params.values`) and of the suite's own
extensions (:mod:`servo_axis.plugins.values`) are generated source
(``scripts/typed_values.py`` writes them from the schemas with
:mod:`servo_axis.params.typed_source`; ``test/unit/params/test_typed_values.py``
fails while they are stale), so that mypy checks every name. The class of an
extension's section is the node's with the extension's keys added (a
subclass); an extension from outside the suite that names no class of its
own (``values=`` of its entry) gets one made here at run time from its schema
(:func:`derive`), with the same fields the generator would give it.

Each value class is also a read-only mapping of its dotted keys
(``values["dob.cutoff_hz"]``, ``dict(values)``, ``set(values)``): the access
of plugins written before typed values, which keeps working. The suite's own
code outside the parameter layer reads attributes only
(``test/unit/layout/test_values_access.py``). A list value is a tuple as an
attribute and a list through the mapping.

Nothing here imports rclpy.
"""

from __future__ import annotations

import dataclasses
import keyword
import typing
from collections.abc import Iterator, Mapping
from functools import cache
from typing import Any, TypeVar

from servo_axis.params.param import Param

G = TypeVar("G", bound="Group")

#: Names a key may not have as an attribute: the mapping's own methods.
RESERVED = frozenset({"keys", "items", "values", "get", "as_dict", "with_keys"})


class Group(Mapping[str, Any]):
    """The values of a group of keys (``dob.*``), or of a whole section (:class:`Values`).

    A subclass is a frozen dataclass with one field per key or subgroup; as a
    mapping it holds the dotted keys relative to the group
    (``values.dob["cutoff_hz"]``, ``values["dob.cutoff_hz"]``). Two of them are
    equal when their keys and values are; a mapping equals one with the same
    keys and values.
    """

    def __getitem__(self, key: str) -> Any:
        path = _leaves(type(self)).get(key)
        if path is None:
            raise KeyError(key)
        value: Any = self
        for name in path:
            value = getattr(value, name)
        return list(value) if isinstance(value, tuple) else value

    def __iter__(self) -> Iterator[str]:
        return iter(_leaves(type(self)))

    def __len__(self) -> int:
        return len(_leaves(type(self)))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Group) and type(other) is type(self):
            return all(getattr(self, n) == getattr(other, n) for n in _names(type(self)))
        if isinstance(other, Mapping):
            return dict(self.items()) == dict(other.items())
        return NotImplemented

    def __hash__(self) -> int:
        return hash(tuple(getattr(self, n) for n in _names(type(self))))

    def as_dict(self) -> dict[str, Any]:
        """The values by dotted key (lists as lists), as the schema check gives them."""
        return {key: self[key] for key in self}

    def with_keys(self: G, changes: Mapping[str, Any]) -> G:
        """A copy with the values of some dotted keys replaced (not checked again).

        Raises
        ------
        KeyError
            For a key the class does not have.
        """
        unknown = [key for key in changes if key not in _leaves(type(self))]
        if unknown:
            raise KeyError(unknown[0])
        return from_flat(type(self), {**self.as_dict(), **changes})


class Values(Group):
    """The checked values of one node's section (its keys and the shared ones)."""


def attribute(key_part: str) -> str:
    """The attribute of one part of a dotted key (a Python keyword gets a ``_``)."""
    return f"{key_part}_" if keyword.iskeyword(key_part) else key_part


def leaf_type(param: Param) -> Any:
    """The attribute type of a key: bool, int, float, str, or a tuple of one of them."""
    default = param.default
    if isinstance(default, list):
        elem = default[0] if default else 0.0
        return tuple[type(elem), ...]  # type: ignore[misc]
    return type(default)


def _frozen(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


@cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _group_of(cls: type, name: str) -> type[Group] | None:
    hint = _hints(cls)[name]
    return hint if isinstance(hint, type) and issubclass(hint, Group) else None


@cache
def _fields(cls: type) -> tuple[tuple[str, str, type[Group] | None], ...]:
    """``(attribute, key part, group class or None)`` of each field of ``cls``."""
    return tuple(
        (f.name, f.metadata.get("key", f.name), _group_of(cls, f.name))
        for f in dataclasses.fields(cls)
    )


@cache
def _names(cls: type) -> tuple[str, ...]:
    return tuple(name for name, _, _ in _fields(cls))


@cache
def _leaves(cls: type) -> dict[str, tuple[str, ...]]:
    """Each dotted key of ``cls`` (relative to it) and its attribute path."""
    out: dict[str, tuple[str, ...]] = {}
    for name, part, group in _fields(cls):
        if group is None:
            out[part] = (name,)
        else:
            for key, path in _leaves(group).items():
                out[f"{part}.{key}"] = (name, *path)
    return out


def keys_of(cls: type[Group]) -> tuple[str, ...]:
    """The dotted keys of a value class, in field order."""
    return tuple(_leaves(cls))


def from_flat(cls: type[G], flat: Mapping[str, Any], prefix: str = "") -> G:
    """An instance of ``cls`` from values by dotted key (checked already: not checked here).

    Raises
    ------
    KeyError
        For a key of ``cls`` that ``flat`` does not have.
    """
    kwargs: dict[str, Any] = {}
    for name, part, group in _fields(cls):
        key = prefix + part
        kwargs[name] = (
            from_flat(group, flat, key + ".") if group is not None else _frozen(flat[key])
        )
    return cls(**kwargs)


#: A schema as a tree: each part of a dotted key -> its Param, or the tree of its group.
Tree = dict[str, Any]


def nest(schema: Mapping[str, Param]) -> Tree:
    """``{"dob.cutoff_hz": p}`` as ``{"dob": {"cutoff_hz": p}}`` (key order kept).

    Raises
    ------
    ValueError
        When a key is both a value and a group (``a`` and ``a.b``), or a part
        of a key is not a name an attribute can have.
    """
    tree: Tree = {}
    for key, param in schema.items():
        *groups, last = key.split(".")
        node = tree
        for part in [*groups, last]:
            if not part.isidentifier() or part in RESERVED or part.startswith("_"):
                raise ValueError(f"key {key!r}: {part!r} cannot name an attribute")
        for part in groups:
            child = node.setdefault(part, {})
            if isinstance(child, Param):
                raise ValueError(f"key {key!r}: {part!r} is a key of its own")
            node = child
        if last in node:
            raise ValueError(f"key {key!r}: {last!r} is a group of keys")
        node[last] = param
    return tree


def camel(text: str) -> str:
    """``ball_screw`` -> ``BallScrew``."""
    return "".join(part[:1].upper() + part[1:] for part in text.replace(".", "_").split("_"))


def derive(name: str, bases: tuple[type[Group], ...], schema: Mapping[str, Param]) -> type[Values]:
    """The value class of ``bases`` with the keys of ``schema`` added, made at run time.

    What :mod:`servo_axis.params.typed_source` writes for a schema, as a
    class: a key of a group the bases have extends that group (a subclass of
    its class), any other key is a field; several bases are merged (a field
    two of them give the same group class once, two different group classes
    merged into one).

    Raises
    ------
    ValueError
        For a key that is a value in one and a group in the other, two
        different types of one key, or a key no attribute can name.
    """
    return _derive(name, bases, nest(schema))  # type: ignore[return-value]


@cache
def _minimal(types: tuple[type, ...]) -> tuple[type, ...]:
    """``types`` without those another of them derives from."""
    return tuple(t for t in types if not any(o is not t and issubclass(o, t) for o in types))


def _derive(name: str, bases: tuple[type[Group], ...], tree: Tree) -> type[Group]:
    inherited: dict[str, list[Any]] = {}
    parts: dict[str, str] = {}
    for base in bases:
        if not dataclasses.is_dataclass(base):
            continue
        for attr, part, _ in _fields(base):
            types = inherited.setdefault(attr, [])
            hint = _hints(base)[attr]
            if hint not in types:
                types.append(hint)
            parts[attr] = part
    declared: list[tuple[str, Any, Any]] = []
    for attr, types in inherited.items():
        sub = tree.pop(parts[attr], None)
        groups = [t for t in types if isinstance(t, type) and issubclass(t, Group)]
        if sub is None and len(types) == 1:
            continue
        if isinstance(sub, Param) or len(groups) != len(types):
            raise ValueError(f"key {parts[attr]!r}: given twice, or as a key and as a group")
        merged = _derive(name + camel(parts[attr]), _minimal(tuple(groups)), sub or {})
        declared.append((attr, merged, _field(parts[attr], attr)))
    for part, sub in tree.items():
        attr = attribute(part)
        if isinstance(sub, Param):
            declared.append((attr, leaf_type(sub), _field(part, attr, sub)))
        else:
            group = _derive(name + camel(part), (Group,), sub)
            declared.append((attr, group, _field(part, attr)))
    return dataclasses.make_dataclass(
        name, declared, bases=bases, frozen=True, kw_only=True, eq=False
    )


def _field(part: str, attr: str, param: Param | None = None) -> Any:
    metadata: dict[str, str] = {}
    if param is not None:
        metadata = {"unit": param.unit, "range": range_text(param)}
    if part != attr:
        metadata["key"] = part
    return dataclasses.field(metadata=metadata)


def range_text(param: Param) -> str:
    """The allowed values of a key in words (``> 0``, ``one of 'a', 'b'``; ``""``: any)."""
    if param.choices is not None:
        return "one of " + ", ".join(repr(c) for c in param.choices)
    default = param.default
    if isinstance(default, bool) or isinstance(default, str):
        return ""
    if isinstance(default, list) and default and isinstance(default[0], str):
        return ""
    return param.range_text()


def tree_of(cls: type) -> dict[str, Any]:
    """The fields of a value class as a tree of types (to compare a generated class with
    :func:`derive`'s): ``{attribute: type or subtree}``."""
    out: dict[str, Any] = {}
    for attr, part, group in _fields(cls):
        key = attr if part == attr else f"{attr}[{part}]"
        out[key] = tree_of(group) if group is not None else _hints(cls)[attr]
    return out
