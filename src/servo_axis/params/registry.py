"""The extension points: plant models, feedforward terms, learning laws, identification methods.

Each extension is one object declared in one module (its parameter schema,
its builder, its cross-key checks, the files it reads and its metadata) and
registered, like the plugins of ros2_control's pluginlib, as an entry point of
its distribution::

    [project.entry-points."servo_axis.plant_models"]
    rigid_axis = "my_package.rigid_axis:PLANT_MODEL"

The groups are :data:`GROUPS`; the entry point's name is the name a
scenario selects (``plant.model: rigid_axis``), its object one of
:class:`PlantModelEntry`, :class:`FeedforwardTermEntry`,
:class:`LearningLawEntry` or :class:`IdentifierEntry`. The suite's own
extensions (``servo_axis.plugins``) are registered the same way in its
``pyproject.toml``. The registries (:data:`PLANT_MODELS`, ...) read the
installed entry points the first time they are asked (a node process, the
runner and ``simulate`` each see what is installed in their environment);
:meth:`Registry.register` adds one in-process (tests, a script).

Nothing here imports rclpy.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Generic, TypeVar

import numpy as np

from servo_axis.core.errors import ConfigError, ParameterFileError, did_you_mean
from servo_axis.core.feedforward.terms import FeedforwardTerm
from servo_axis.core.identification.base import OnlineIdentifier
from servo_axis.core.learning.base import LearningLaw
from servo_axis.core.models.base import Plant
from servo_axis.params import schemas
from servo_axis.params.param import Param

Values = Mapping[str, Any]
Scenario = dict[str, Any]

#: The entry-point group of each kind of extension.
GROUPS = {
    "plant model": "servo_axis.plant_models",
    "feedforward term": "servo_axis.feedforward_terms",
    "learning law": "servo_axis.learning_laws",
    "identification method": "servo_axis.identification_methods",
}


def _no_warnings(values: Values) -> list[str]:
    return []


def _no_check(values: Values) -> None:
    return None


def _no_overrides(scenario: Scenario, given: Values) -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class PlantModelEntry:
    """A plant model, selected by ``plant.model``.

    Attributes
    ----------
    schema : mapping of str to Param
        The model's keys in the ``plant`` section (beside the node's own,
        :data:`servo_axis.params.schemas.PLANT`); must have
        ``torque_constant_Nm_per_A`` (N m/A), with which the plant, as a
        drive, turns the torque reference of ``command`` into its current.
    build : callable
        ``build(values, rng) -> Plant`` from the checked plant values; what
        it rejects is reported as ``parameter '<key>': ...``
        (:func:`servo_axis.params.param.build`).
    warnings : callable
        ``warnings(values) -> list of str``: what is allowed but unusual
        (the plant node logs each at start).
    rotary : bool
        Whether the table turns: its position is an angle (rad) and the
        summary's tracking error is ``r - y`` in rad; else it moves along a
        line, ``x = R theta``, and the error ``R (r - y)`` is in m.
    description : str
        One line for ``list`` and the parameter reference.
    fingerprint_if_set : frozenset of str
        Keys added after files were identified on the model (a GMS fit):
        in the plant's fingerprint only when set away from their default,
        so that a file fitted before names the same plant.
    """

    schema: Mapping[str, Param]
    build: Callable[[Values, np.random.Generator], Plant]
    warnings: Callable[[Values], list[str]] = _no_warnings
    rotary: bool = False
    description: str = ""
    fingerprint_if_set: frozenset[str] = frozenset()


@dataclass(frozen=True)
class FeedforwardTermEntry:
    """A feedforward term, switched on by its own keys of the ``feedforward`` section.

    Attributes
    ----------
    schema : mapping of str to Param
        The term's keys (``<term>.enabled``, ...), added to the feedforward
        section's.
    build : callable
        ``build(values) -> FeedforwardTerm or None`` (None when its keys
        leave it off); may read its files.
    check : callable
        ``check(values)``: what :func:`~servo_axis.params.factories.check_consistency`
        checks without reading a file (the runner refuses it before any process starts).
    files : tuple of str
        Its keys that name a file: a relative path is relative to the scenario file.
    order : float
        Terms are summed in increasing ``order`` (then name): a sum of floats
        depends on its order, a run's numbers on the sum.
    overrides : callable
        ``overrides(scenario, given) -> dict``: values it takes from other
        sections of the scenario (one source each; e.g. the plant a file
        must have been identified on).
    description : str
        One line for ``list`` and the parameter reference.
    """

    schema: Mapping[str, Param]
    build: Callable[[Values], FeedforwardTerm | None]
    check: Callable[[Values], None] = _no_check
    files: tuple[str, ...] = ()
    order: float = 100.0
    overrides: Callable[[Scenario, Values], dict[str, Any]] = _no_overrides
    description: str = ""


@dataclass(frozen=True)
class LearningLawEntry:
    """A learning law, selected by ``learning.law``.

    Attributes
    ----------
    schema : mapping of str to Param
        The law's own keys in the ``learning`` section.
    period, side : str
        ``cycle``/``trial`` and ``target``/``input`` (:mod:`servo_axis.core.learning.base`).
    build : callable
        ``build(values) -> LearningLaw`` from checked learning values.
    identifies : tuple of str
        What else it publishes besides its correction and the per-period
        stats: ``learning/parameters`` and / or ``learning/friction_table``.
    convergence : callable or None
        ``convergence(values, plant_values) -> dict``: the summary's
        ``ilc_convergence`` block of a run with this law (None: none).
    description : str
        One line for ``list`` and the parameter reference.
    """

    schema: Mapping[str, Param]
    period: str
    side: str
    build: Callable[[Values], LearningLaw]
    identifies: tuple[str, ...] = ()
    convergence: Callable[[Values, Values], dict[str, float]] | None = None
    description: str = ""
    outputs: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        if self.period not in ("cycle", "trial") or self.side not in ("target", "input"):
            raise ValueError(
                f"period, side: expected cycle/trial and target/input, got {self.period!r}, "
                f"{self.side!r}"
            )
        correction = "learning/correction" if self.side == "target" else "learning/input_correction"
        object.__setattr__(self, "outputs", (correction, "learning/cycle_stats", *self.identifies))


@dataclass(frozen=True)
class IdentifierEntry:
    """An online identification method, selected by ``identifier.method``.

    Attributes
    ----------
    schema : mapping of str to Param
        The method's own keys in the ``identifier`` section (beside
        :data:`servo_axis.params.schemas.IDENTIFIER`).
    build : callable
        ``build(values) -> OnlineIdentifier`` from checked identifier values.
    estimates_friction : bool
        Whether its ``C`` is an estimate (the feedforward then compensates
        friction with it, ``mnc.friction``) or always 0.
    description : str
        One line for ``list`` and the parameter reference.
    """

    schema: Mapping[str, Param]
    build: Callable[[Values], OnlineIdentifier]
    estimates_friction: bool = False
    description: str = ""


E = TypeVar("E")


class Registry(Mapping[str, E], Generic[E]):
    """The installed extensions of one kind, by name, read from their entry points once.

    Parameters
    ----------
    kind : str
        ``"plant model"``, ...: a key of :data:`GROUPS`.
    entry_type : type
        The class of its entries.
    validate : callable
        ``validate(name, entry)`` raises ValueError on an entry the suite cannot use.
    """

    def __init__(
        self, kind: str, entry_type: type[E], validate: Callable[[str, E], None] | None = None
    ) -> None:
        self.kind = kind
        self.group = GROUPS[kind]
        self._type = entry_type
        self._validate = validate or (lambda name, entry: None)
        self._entries: dict[str, E] | None = None
        self._sources: dict[str, str] = {}

    def _loaded(self) -> dict[str, E]:
        if self._entries is None:
            entries: dict[str, E] = {}
            for point in sorted(metadata.entry_points(group=self.group), key=lambda p: p.name):
                where = f"entry point {point.name!r} = {point.value!r} of group {self.group!r}"
                if point.name in entries:
                    raise ConfigError(
                        f"{where}: a {self.kind} named {point.name!r} is installed twice "
                        f"({self._sources[point.name]})"
                    )
                try:
                    entry = point.load()
                except Exception as err:  # an outside package's import error, named
                    raise ConfigError(f"{where}: cannot be loaded: {err}") from err
                self._check(point.name, entry, where)
                entries[point.name] = entry
                self._sources[point.name] = point.value
            self._entries = entries
        return self._entries

    def _check(self, name: str, entry: object, where: str) -> None:
        if not isinstance(entry, self._type):
            raise ConfigError(
                f"{where}: expected a {self._type.__name__}, got {type(entry).__name__}"
            )
        try:
            self._validate(name, entry)
        except ValueError as err:
            raise ConfigError(f"{where}: {err}") from err

    def register(self, name: str, entry: E) -> None:
        """Add (or replace) ``name`` in this process, as if it were installed.

        Raises
        ------
        ValueError
            When the entry is not one the suite can use.
        """
        self._validate(name, entry)
        self._loaded()[name] = entry
        self._sources[name] = "registered in-process"

    def unregister(self, name: str) -> None:
        """Remove ``name`` if it was registered in-process (an installed entry stays)."""
        if self._sources.get(name) == "registered in-process":
            del self._loaded()[name]
            del self._sources[name]

    def source(self, name: str) -> str:
        """Where ``name`` comes from (its entry point's ``module:object``)."""
        self._loaded()
        return self._sources[name]

    def lookup(self, name: object, key: str) -> E:
        """The entry ``name``; a ParameterFileError naming ``key`` and the installed ones otherwise."""
        entries = self._loaded()
        if not isinstance(name, str) or name not in entries:
            hint = did_you_mean(name, entries)
            raise ParameterFileError(
                f"parameter '{key}': expected one of {sorted(entries)} (the installed "
                f"{self.kind}s, entry points {self.group}), got {name!r}"
                + (f"; {hint}" if hint else "")
            )
        return entries[name]

    def __getitem__(self, name: str) -> E:
        return self._loaded()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._loaded())

    def __len__(self) -> int:
        return len(self._loaded())


def _validate_plant_model(name: str, entry: PlantModelEntry) -> None:
    clash = set(entry.schema) & (set(schemas.PLANT) | set(schemas.SHARED))
    if clash:
        raise ValueError(f"schema: keys {sorted(clash)} are the plant node's own")
    if "torque_constant_Nm_per_A" not in entry.schema:
        raise ValueError(
            "schema: expected a key 'torque_constant_Nm_per_A' (N m/A), with which the "
            "plant turns the torque reference of `command` into its current"
        )


def _validate_term(name: str, entry: FeedforwardTermEntry) -> None:
    clash = set(entry.schema) & (set(schemas.FEEDFORWARD) | set(schemas.SHARED))
    if clash:
        raise ValueError(f"schema: keys {sorted(clash)} are the feedforward node's own")
    missing = [k for k in entry.files if k not in entry.schema]
    if missing:
        raise ValueError(f"files: {missing} are not keys of its schema")


def _validate_own_keys(section: str) -> Callable[[str, Any], None]:
    def validate(name: str, entry: Any) -> None:
        own = {"learning": schemas.LEARNING, "identifier": schemas.IDENTIFIER}[section]
        clash = set(entry.schema) & (set(own) | set(schemas.SHARED))
        if clash:
            raise ValueError(f"schema: keys {sorted(clash)} are the {section} node's own")

    return validate


PLANT_MODELS: Registry[PlantModelEntry] = Registry(
    "plant model", PlantModelEntry, _validate_plant_model
)
FEEDFORWARD_TERMS: Registry[FeedforwardTermEntry] = Registry(
    "feedforward term", FeedforwardTermEntry, _validate_term
)
LEARNING_LAWS: Registry[LearningLawEntry] = Registry(
    "learning law", LearningLawEntry, _validate_own_keys("learning")
)
IDENTIFIERS: Registry[IdentifierEntry] = Registry(
    "identification method", IdentifierEntry, _validate_own_keys("identifier")
)

#: Every registry, by kind.
REGISTRIES: dict[str, Registry[Any]] = {
    "plant model": PLANT_MODELS,
    "feedforward term": FEEDFORWARD_TERMS,
    "learning law": LEARNING_LAWS,
    "identification method": IDENTIFIERS,
}


def feedforward_terms() -> list[tuple[str, FeedforwardTermEntry]]:
    """The installed feedforward terms in the order they are summed (``order``, then name)."""
    return sorted(FEEDFORWARD_TERMS.items(), key=lambda item: (item[1].order, item[0]))


def term_files() -> tuple[str, ...]:
    """Every feedforward key that names a file (relative to the scenario file)."""
    return tuple(key for _, entry in feedforward_terms() for key in entry.files)


def parameter_sections() -> dict[str, Mapping[str, Param]]:
    """Every section of the parameter reference, by title: each node's keys, then its extensions'.

    An extension without keys of its own has no section; extensions with
    the same keys share one (``learning (laws pilc_bf, pilc_bfft)``).
    """
    kinds: dict[str, tuple[str, Registry[Any]]] = {
        "plant": ("model", PLANT_MODELS),
        "feedforward": ("term", FEEDFORWARD_TERMS),
        "learning": ("law", LEARNING_LAWS),
        "identifier": ("method", IDENTIFIERS),
    }
    nodes: dict[str, Mapping[str, Param]] = {
        "/**": schemas.SHARED,
        "plant": schemas.PLANT,
        "feedback": schemas.FEEDBACK,
        "feedforward": schemas.FEEDFORWARD,
        "learning": schemas.LEARNING,
        "identifier": schemas.IDENTIFIER,
        "recorder": schemas.RECORDER,
    }
    out: dict[str, Mapping[str, Param]] = {}
    for node, schema in nodes.items():
        out[node] = schema
        if node not in kinds:
            continue
        word, registry = kinds[node]
        items: list[tuple[str, Any]] = (
            list(feedforward_terms()) if node == "feedforward" else sorted(registry.items())
        )
        groups: list[tuple[list[str], Mapping[str, Param]]] = []
        for name, entry in items:
            if not entry.schema:
                continue
            same = [g for g in groups if dict(g[1]) == dict(entry.schema)]
            if same:
                same[0][0].append(name)
            else:
                groups.append(([name], entry.schema))
        for names, keys in groups:
            label = f"{word}s {', '.join(names)}" if len(names) > 1 else f"{word} {names[0]}"
            out[f"{node} ({label})"] = keys
    return out
