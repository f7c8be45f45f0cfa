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

An installed extension that cannot be used (its module is missing or fails
to import, its object is not an entry of its kind or is refused by the
checks of its kind, two distributions give the same name) is *broken*: it is
left out of its registry and kept in :attr:`Registry.broken` with its error
(:class:`BrokenPlugin`), so that it stops only what selects it. Selecting
it (``plant.model: <name>``, a key ``<name>.*`` of a feedforward term) is a
:class:`~servo_axis.core.errors.BrokenPluginError` naming the plugin, its
entry point and the error; :func:`report_broken` writes each other broken
one once, as a warning line, to stderr (the command line does at the end of
its checks).

Nothing here imports rclpy.
"""

from __future__ import annotations

import re
import sys
import traceback
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from importlib import metadata
from typing import IO, Any, Generic, TypeVar

import numpy as np

from servo_axis.core.errors import (
    BrokenPluginError,
    ParameterFileError,
    did_you_mean,
)
from servo_axis.core.feedforward.terms import FeedforwardTerm
from servo_axis.core.identification.online.base import OnlineIdentifier
from servo_axis.core.learning.base import LearningLaw
from servo_axis.core.models.base import Plant
from servo_axis.params import schemas
from servo_axis.params.param import Param
from servo_axis.params.typed import Values as Values
from servo_axis.params.typed import camel, derive, keys_of
from servo_axis.params.values import (
    FeedforwardValues,
    IdentifierValues,
    LearningValues,
    PlantValues,
)

Scenario = dict[str, Any]

#: The values an extension's functions receive: its node's class with its keys added.
V = TypeVar("V", bound=Values)

#: The entry-point group of each kind of extension.
GROUPS = {
    "plant model": "servo_axis.plant_models",
    "feedforward term": "servo_axis.feedforward_terms",
    "learning law": "servo_axis.learning_laws",
    "identification method": "servo_axis.identification_methods",
}


def _no_warnings(values: Any) -> list[str]:
    return []


def _no_check(values: Any) -> None:
    return None


def _no_overrides(resolved: Any, given: Mapping[str, Any]) -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class PlantModelEntry(Generic[V]):
    """A plant model, selected by ``plant.model``.

    Attributes
    ----------
    schema : mapping of str to Param
        The model's keys in the ``plant`` section (beside the node's own,
        :data:`servo_axis.params.schemas.PLANT`); must have
        ``torque_constant_Nm_per_A`` (N m/A), with which the plant, as a
        drive, turns the torque reference of ``command`` into its current.
    build : callable
        ``build(values, rng) -> Plant`` from the checked plant values (an
        instance of :attr:`values`); what it rejects is reported as
        ``parameter '<key>': ...`` (:func:`servo_axis.params.param.build`).
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
    check : callable or None
        ``check(values)``: what depends on several keys, raising
        ParameterFileError naming a key; the runner refuses it before any
        process starts, without building the plant. None: the runner builds
        the plant once to check it (and drops it).
    values : type or None
        The class of the plant section's values with this model
        (:class:`~servo_axis.params.values.PlantValues` with its keys added,
        generated: :mod:`servo_axis.plugins.values`); None: made from
        :attr:`schema` at run time (:func:`~servo_axis.params.typed.derive`).
    """

    schema: Mapping[str, Param]
    build: Callable[[V, np.random.Generator], Plant]
    warnings: Callable[[V], list[str]] = _no_warnings
    rotary: bool = False
    description: str = ""
    fingerprint_if_set: frozenset[str] = frozenset()
    check: Callable[[V], object] | None = None
    values: type[V] | None = None


@dataclass(frozen=True)
class FeedforwardTermEntry(Generic[V]):
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
        ``check(values)``: what depends on several keys, checked without
        reading a file and without building the term (the runner refuses it
        before any process starts), raising ParameterFileError naming a key.
    files : tuple of str
        Its keys that name a file: a relative path is relative to the scenario file.
    order : float
        Terms are summed in increasing ``order`` (then name): a sum of floats
        depends on its order, a run's numbers on the sum.
    overrides : callable
        ``overrides(resolved, given) -> dict``: values it takes from other
        sections of the scenario (one source each; e.g. the plant a file
        must have been identified on), given the scenario read once
        (:class:`servo_axis.params.resolve.Resolved`: ``resolved.plant``, the
        plant's checked values; ``resolved.given(role)``, a section's given
        keys) and the feedforward section's given keys.
    description : str
        One line for ``list`` and the parameter reference.
    values : type or None
        The class of the feedforward section's values with this term and every other term installed
        (:class:`~servo_axis.params.values.FeedforwardValues` with its keys added,
        generated: :mod:`servo_axis.plugins.values`); None: made from
        :attr:`schema` at run time (:func:`~servo_axis.params.typed.derive`).
    """

    schema: Mapping[str, Param]
    build: Callable[[V], FeedforwardTerm | None]
    check: Callable[[V], object] = _no_check
    files: tuple[str, ...] = ()
    order: float = 100.0
    overrides: Callable[[Any, Mapping[str, Any]], dict[str, Any]] = _no_overrides
    description: str = ""
    values: type[V] | None = None


@dataclass(frozen=True)
class LearningLawEntry(Generic[V]):
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
    check : callable or None
        ``check(values)``: what depends on several keys, raising
        ParameterFileError naming a key, without building the law; None:
        the runner builds the law once to check it (and drops it).
    values : type or None
        The class of the learning section's values with this law
        (:class:`~servo_axis.params.values.LearningValues` with its keys added,
        generated: :mod:`servo_axis.plugins.values`); None: made from
        :attr:`schema` at run time (:func:`~servo_axis.params.typed.derive`).
    """

    schema: Mapping[str, Param]
    period: str
    side: str
    build: Callable[[V], LearningLaw]
    identifies: tuple[str, ...] = ()
    convergence: Callable[[V, PlantValues], dict[str, float]] | None = None
    description: str = ""
    check: Callable[[V], object] | None = None
    values: type[V] | None = None
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
class IdentifierEntry(Generic[V]):
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
    check : callable or None
        ``check(values)``: what depends on several keys, raising
        ParameterFileError naming a key, without building the identifier;
        None: the runner builds it once to check it (and drops it).
    values : type or None
        The class of the identifier section's values with this method
        (:class:`~servo_axis.params.values.IdentifierValues` with its keys added,
        generated: :mod:`servo_axis.plugins.values`); None: made from
        :attr:`schema` at run time (:func:`~servo_axis.params.typed.derive`).
    """

    schema: Mapping[str, Param]
    build: Callable[[V], OnlineIdentifier]
    estimates_friction: bool = False
    description: str = ""
    check: Callable[[V], object] | None = None
    values: type[V] | None = None


#: The distribution of the suite itself (its extensions are "shipped").
SHIPPED_DISTRIBUTION = "servo-axis"


def _normalized(name: str) -> str:
    """A distribution name as PEP 503 compares them (``servo_axis`` is ``servo-axis``)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _load_error(err: BaseException) -> str:
    """``<Type>: <message>``, and where in the plugin's own code it was raised.

    The innermost frame outside ``importlib`` is the line of the plugin that
    failed (an ``import`` of a missing dependency, a ``raise``); a module
    that is not there at all has none.
    """
    text = f"{type(err).__name__}: {_one_line(str(err))}"
    frames = [
        f
        for f in traceback.extract_tb(err.__traceback__)
        if "importlib" not in f.filename and not f.filename.startswith("<frozen")
    ]
    if len(frames) > 1:  # the first is load() itself
        last = frames[-1]
        text += f" (at {last.filename}:{last.lineno})"
    return text


@dataclass(frozen=True)
class BrokenPlugin:
    """An installed extension that cannot be used, and why.

    Attributes
    ----------
    kind : str
        ``"plant model"``, ...: a key of :data:`GROUPS`.
    name : str
        Its entry point's name (what a scenario would select).
    value : str
        Its entry point's ``module:object`` (each of them, for a name given twice).
    group : str
        Its entry point's group.
    distribution : str
        ``<name> <version>`` of the distribution that declares it (``""`` if unknown).
    error : str
        What went wrong, one line (the import error with its type, the type
        of a wrong object, what the checks of its kind refuse, ...).
    """

    kind: str
    name: str
    value: str
    group: str
    distribution: str
    error: str

    @property
    def where(self) -> str:
        """``entry point '<name>' = '<module:object>' of group '<group>' (distribution ...)``."""
        of = f" (distribution {self.distribution})" if self.distribution else ""
        return f"entry point {self.name!r} = {self.value!r} of group {self.group!r}{of}"

    def line(self) -> str:
        """The one line that names it: kind, name, entry point, error."""
        return f"{self.kind} {self.name!r} cannot be loaded: {self.where}: {self.error}"


#: The broken plugins already named on stderr or in an error (kind, name).
_reported: set[tuple[str, str]] = set()


E = TypeVar("E")


class Registry(Mapping[str, E], Generic[E]):
    """The installed extensions of one kind, by name, read from their entry points once.

    The mapping holds the extensions that load; those that do not are in
    :attr:`broken`.

    Parameters
    ----------
    kind : str
        ``"plant model"``, ...: a key of :data:`GROUPS`.
    entry_type : type
        The class of its entries.
    node_values : type
        The class of the node's values its entries add their keys to
        (:class:`~servo_axis.params.values.PlantValues`, ...).
    validate : callable
        ``validate(name, entry)`` raises ValueError on an entry the suite cannot use.
    """

    def __init__(
        self,
        kind: str,
        entry_type: type[E],
        node_values: type[Values],
        validate: Callable[[str, E], None] | None = None,
    ) -> None:
        self.kind = kind
        self.group = GROUPS[kind]
        self._type = entry_type
        self.node_values = node_values
        self._validate = validate or (lambda name, entry: None)
        self._entries: dict[str, E] | None = None
        self._sources: dict[str, str] = {}
        self._distributions: dict[str, str] = {}
        self._broken: dict[str, BrokenPlugin] = {}
        self._classes: dict[str, type[Values]] = {}

    @property
    def loaded(self) -> bool:
        """Whether the entry points have been read (by any question asked of it)."""
        return self._entries is not None

    def _loaded(self) -> dict[str, E]:
        if self._entries is None:
            entries: dict[str, E] = {}
            points = sorted(metadata.entry_points(group=self.group), key=lambda p: p.name)
            names = [p.name for p in points]
            for point in points:
                dist = getattr(point, "dist", None)
                distribution = f"{dist.name} {dist.version}" if dist is not None else ""
                if names.count(point.name) > 1:
                    self._broken[point.name] = self._twice(point.name, points)
                    continue
                try:
                    entry = point.load()
                    self._check(point.name, entry)
                except Exception as err:  # an outside package's failure, kept with its name
                    error = str(err) if isinstance(err, _RefusedError) else _load_error(err)
                    self._broken[point.name] = BrokenPlugin(
                        self.kind, point.name, point.value, self.group, distribution, error
                    )
                    continue
                entries[point.name] = entry
                self._sources[point.name] = point.value
                self._distributions[point.name] = distribution
            self._entries = entries
        return self._entries

    def _twice(self, name: str, points: list[metadata.EntryPoint]) -> BrokenPlugin:
        """The broken plugin of a name that several distributions give."""
        same = [p for p in points if p.name == name]
        dists = [
            f"{d.name} {d.version}" if (d := getattr(p, "dist", None)) is not None else "?"
            for p in same
        ]
        return BrokenPlugin(
            self.kind,
            name,
            " and ".join(p.value for p in same),
            self.group,
            "",
            f"installed {len(same)} times, by {' and '.join(dists)}; uninstall all but one",
        )

    def _check(self, name: str, entry: object) -> None:
        if not isinstance(entry, self._type):
            raise _RefusedError(f"expected a {self._type.__name__}, got {type(entry).__name__}")
        try:
            self._validate(name, entry)
            self._classes[name] = self._class_of(name, entry)
        except ValueError as err:
            raise _RefusedError(str(err)) from err

    def _class_of(self, name: str, entry: Any) -> type[Values]:
        """The class of a section's values with ``entry``: its ``values``, or one made now.

        Raises
        ------
        ValueError
            For a ``values`` that is not a class of the node's values with
            exactly the entry's keys added (a generated module not written
            again after its schema changed), or keys no class can have.
        """
        node = self.node_values
        cls = entry.values
        if cls is None:
            return derive(f"{camel(name)}Values", (node,), entry.schema) if entry.schema else node
        if not (isinstance(cls, type) and issubclass(cls, node)):
            raise ValueError(f"values: expected a subclass of {node.__name__}, got {cls!r}")
        given, own = set(keys_of(cls)) - set(keys_of(node)), set(entry.schema)
        if given != own:
            odd = sorted(given ^ own)[0]
            raise ValueError(
                f"values: {cls.__name__} and the schema differ in key {odd!r} (a generated "
                "class not written again after its schema changed: scripts/typed_values.py)"
            )
        return cls

    def values_class(self, name: str) -> type[Values]:
        """The class of a section's values with the installed extension ``name``."""
        self._loaded()
        return self._classes[name]

    @property
    def broken(self) -> Mapping[str, BrokenPlugin]:
        """The installed extensions of this kind that cannot be loaded, by name."""
        self._loaded()
        return dict(self._broken)

    def register(self, name: str, entry: E) -> None:
        """Add (or replace) ``name`` in this process, as if it were installed.

        Raises
        ------
        ValueError
            When the entry is not one the suite can use.
        """
        self._validate(name, entry)
        cls = self._class_of(name, entry)
        self._loaded()[name] = entry
        self._classes[name] = cls
        self._broken.pop(name, None)
        self._sources[name] = "registered in-process"
        self._distributions[name] = ""

    def unregister(self, name: str) -> None:
        """Remove ``name`` if it was registered in-process (an installed entry stays)."""
        if self._sources.get(name) == "registered in-process":
            del self._loaded()[name]
            del self._sources[name]
            del self._distributions[name]

    def source(self, name: str) -> str:
        """Where ``name`` comes from (its entry point's ``module:object``)."""
        self._loaded()
        return self._sources[name]

    def distribution(self, name: str) -> str:
        """``<name> <version>`` of the distribution that declares ``name`` (``""``: in-process)."""
        self._loaded()
        return self._distributions[name]

    def shipped(self, name: str) -> bool:
        """Whether ``name`` is one of the suite's own (declared by the ``servo_axis`` distribution)."""
        dist = self.distribution(name).rpartition(" ")[0]
        return _normalized(dist) == SHIPPED_DISTRIBUTION

    def refuse_broken(self, name: object, key: str) -> None:
        """A BrokenPluginError naming ``key`` if ``name`` is a broken extension of this kind."""
        if isinstance(name, str) and name in self.broken:
            plugin = self._broken[name]
            _reported.add((self.kind, name))
            raise BrokenPluginError(f"parameter '{key}': {plugin.line()}")

    def refuse_broken_keys(self, keys: Iterable[str]) -> None:
        """A BrokenPluginError for the first of ``keys`` of a broken extension (``<name>.*``).

        A feedforward term is switched on by its own keys, which start with
        its name: a scenario that sets one uses the term.
        """
        broken = self.broken
        for key in sorted(keys):
            name = key.partition(".")[0]
            if "." in key and name in broken:
                self.refuse_broken(name, key)

    def lookup(self, name: object, key: str) -> E:
        """The entry ``name``; a ParameterFileError naming ``key`` and the installed ones otherwise.

        Raises
        ------
        BrokenPluginError
            For an installed extension that cannot be loaded (its entry
            point and its error named).
        ParameterFileError
            For a name that is not installed (the installed ones listed).
        """
        entries = self._loaded()
        self.refuse_broken(name, key)
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


class _RefusedError(ValueError):
    """An entry object that loaded but is not one the suite can use (its message is the reason)."""


def _validate_plant_model(name: str, entry: PlantModelEntry[Any]) -> None:
    clash = set(entry.schema) & (set(schemas.PLANT) | set(schemas.SHARED))
    if clash:
        raise ValueError(f"schema: keys {sorted(clash)} are the plant node's own")
    if "torque_constant_Nm_per_A" not in entry.schema:
        raise ValueError(
            "schema: expected a key 'torque_constant_Nm_per_A' (N m/A), with which the "
            "plant turns the torque reference of `command` into its current"
        )


def _validate_term(name: str, entry: FeedforwardTermEntry[Any]) -> None:
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


PLANT_MODELS: Registry[PlantModelEntry[Any]] = Registry(
    "plant model", PlantModelEntry, PlantValues, _validate_plant_model
)
FEEDFORWARD_TERMS: Registry[FeedforwardTermEntry[Any]] = Registry(
    "feedforward term", FeedforwardTermEntry, FeedforwardValues, _validate_term
)
LEARNING_LAWS: Registry[LearningLawEntry[Any]] = Registry(
    "learning law", LearningLawEntry, LearningValues, _validate_own_keys("learning")
)
IDENTIFIERS: Registry[IdentifierEntry[Any]] = Registry(
    "identification method", IdentifierEntry, IdentifierValues, _validate_own_keys("identifier")
)

#: Every registry, by kind.
REGISTRIES: dict[str, Registry[Any]] = {
    "plant model": PLANT_MODELS,
    "feedforward term": FEEDFORWARD_TERMS,
    "learning law": LEARNING_LAWS,
    "identification method": IDENTIFIERS,
}


def feedforward_terms() -> list[tuple[str, FeedforwardTermEntry[Any]]]:
    """The installed feedforward terms in the order they are summed (``order``, then name)."""
    return sorted(FEEDFORWARD_TERMS.items(), key=lambda item: (item[1].order, item[0]))


#: The feedforward section's class of each set of installed terms' classes.
_TERM_CLASSES: dict[tuple[type[Values], ...], type[Values]] = {}


def feedforward_class() -> type[Values]:
    """The class of the feedforward section's values: the node's and every installed term's keys.

    One class derived from every term's (each a
    :class:`~servo_axis.params.values.FeedforwardValues` with its keys
    added), so that a term's functions get an instance of its own class.
    """
    classes = tuple(FEEDFORWARD_TERMS.values_class(name) for name, _ in feedforward_terms())
    if not classes:
        return FeedforwardValues
    made = _TERM_CLASSES.get(classes)
    if made is None:
        made = _TERM_CLASSES[classes] = derive("FeedforwardTermsValues", classes, {})
    return made


def term_files() -> tuple[str, ...]:
    """Every feedforward key that names a file (relative to the scenario file)."""
    return tuple(key for _, entry in feedforward_terms() for key in entry.files)


def broken_plugins(*, loaded_only: bool = False) -> list[BrokenPlugin]:
    """Every installed extension that cannot be loaded, of every kind.

    ``loaded_only``: of the registries read so far only (no plugin is
    imported for the question).
    """
    return [
        plugin
        for registry in REGISTRIES.values()
        if registry.loaded or not loaded_only
        for plugin in registry.broken.values()
    ]


def report_broken(file: IO[str] | None = None) -> list[BrokenPlugin]:
    """Write a warning line for each broken plugin not named yet (of the registries read so far).

    Each is named once per process: here, or in the error of a scenario
    that selects it (:meth:`Registry.refuse_broken`). Returns those written.
    """
    out = sys.stderr if file is None else file
    fresh = [p for p in broken_plugins(loaded_only=True) if (p.kind, p.name) not in _reported]
    for plugin in fresh:
        _reported.add((plugin.kind, plugin.name))
        print(
            f"warning: {plugin.line()}; it is left out (only a scenario that uses it is refused)",
            file=out,
        )
    if fresh:
        out.flush()
    return fresh


def parameter_sections(*, shipped_only: bool = False) -> dict[str, Mapping[str, Param]]:
    """Every section of the parameter reference, by title: each node's keys, then its extensions'.

    An extension without keys of its own has no section; extensions with
    the same keys share one (``learning (laws pilc_bf, pilc_bfft)``).
    ``shipped_only``: the suite's own extensions only (those of the
    ``servo_axis`` distribution; docs/parameters.md), not the plugins
    installed beside it.
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
        if shipped_only:
            items = [(name, entry) for name, entry in items if registry.shipped(name)]
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
