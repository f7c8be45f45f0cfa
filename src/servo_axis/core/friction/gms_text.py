"""The text of a GMS parameter file: written by :func:`gms_to_text`, read by :func:`gms_from_text`.

One ``key = value`` line per field of
:class:`~servo_axis.core.friction.gms_params.GmsParams` (a tuple as its
values separated by commas), after a header line and the two lines that name
the plant the fit was made on (``plant_model``, ``plant_fingerprint``).
Floats are written with ``repr``, so that a round trip is exact. Nothing
here reads or writes a file (``storage.py`` does).
"""

from __future__ import annotations

import math
from dataclasses import fields

from servo_axis.core.errors import ConfigError, TableError
from servo_axis.core.friction.gms_params import GmsParams

#: First line of a GMS parameter file.
HEADER_LINE = "# servo_axis GMS parameters v1"


def gms_to_text(params: GmsParams, *, plant_model: str, plant_fingerprint: str) -> str:
    """The parameters as the line-based text :func:`gms_from_text` reads.

    Parameters
    ----------
    params : GmsParams
        The model.
    plant_model, plant_fingerprint : str
        The plant the fit was made on: its model's name and
        ``params.resolve.plant_fingerprint`` (one line each, not empty).

    Returns
    -------
    str
        The file's text; floats written with ``repr``, so that a round trip
        is exact.

    Raises
    ------
    ConfigError
        For an empty or multi-line ``plant_model`` or ``plant_fingerprint``.
    """
    for name, value in (("plant_model", plant_model), ("plant_fingerprint", plant_fingerprint)):
        if not isinstance(value, str) or not value.strip() or value != value.strip():
            raise ConfigError(f"{name}: expected a non-empty string, got {value!r}")
        if "\n" in value or "\r" in value:
            raise ConfigError(f"{name}: expected one line, got {value!r}")
    lines = [
        HEADER_LINE,
        f"plant_model = {plant_model}",
        f"plant_fingerprint = {plant_fingerprint}",
    ]
    for f in fields(params):
        value = getattr(params, f.name)
        text = ", ".join(repr(v) for v in value) if isinstance(value, tuple) else repr(value)
        lines.append(f"{f.name} = {text}")
    return "\n".join(lines) + "\n"


_TUPLE_KEYS = ("stiffness_Nm_per_m", "weights")
_FLOAT_KEYS = (
    "coulomb_Nm",
    "static_Nm",
    "stribeck_velocity_m_s",
    "stribeck_exponent",
    "attraction_per_s",
    "viscous_Nms_per_m",
)
_TEXT_KEYS = ("plant_model", "plant_fingerprint", *_TUPLE_KEYS, *_FLOAT_KEYS)


def _number(source: str, number: int, key: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise TableError(
            f"{source}: line {number}: {key}: expected a number, got {text.strip()!r}"
        ) from None
    if not math.isfinite(value):
        raise TableError(f"{source}: line {number}: {key}: expected a finite number, got {value!r}")
    return value


def gms_from_text(text: str, *, source: str) -> tuple[GmsParams, str, str]:
    """Read the text :func:`gms_to_text` writes.

    Parameters
    ----------
    text : str
        The file's content.
    source : str
        What the text came from (a file name), for the messages.

    Returns
    -------
    tuple
        ``(params, plant_model, plant_fingerprint)``.

    Raises
    ------
    TableError
        Naming ``source`` and what is wrong: a wrong header, a line that is
        not ``key = value``, an unknown, repeated or missing key, a bad or
        non-finite number, lists of unequal lengths or any other value the
        parameters refuse (the field named).
    """
    raw = _key_lines(text, source=source)
    tuples = {
        key: tuple(_number(source, raw[key][0], key, part) for part in raw[key][1].split(","))
        for key in _TUPLE_KEYS
    }
    floats = {key: _number(source, raw[key][0], key, raw[key][1]) for key in _FLOAT_KEYS}
    k, w = tuples["stiffness_Nm_per_m"], tuples["weights"]
    if len(k) != len(w):
        raise TableError(
            f"{source}: unequal lengths: stiffness_Nm_per_m has {len(k)} values, weights {len(w)}"
        )
    try:
        params = GmsParams(
            stiffness_Nm_per_m=k,
            weights=w,
            coulomb_Nm=floats["coulomb_Nm"],
            static_Nm=floats["static_Nm"],
            stribeck_velocity_m_s=floats["stribeck_velocity_m_s"],
            stribeck_exponent=floats["stribeck_exponent"],
            attraction_per_s=floats["attraction_per_s"],
            viscous_Nms_per_m=floats["viscous_Nms_per_m"],
        )
    except ConfigError as err:
        raise TableError(f"{source}: {err}") from err
    return params, raw["plant_model"][1], raw["plant_fingerprint"][1]


def _key_lines(text: str, *, source: str) -> dict[str, tuple[int, str]]:
    """Each key of the text with its line number and its value (stripped, not empty for a name).

    Raises the :class:`TableError` of :func:`gms_from_text` for the header
    and for a line or key at fault.
    """
    lines = text.splitlines()
    if not lines or lines[0].strip() != HEADER_LINE:
        got = lines[0].strip() if lines else ""
        raise TableError(f"{source}: line 1: expected header {HEADER_LINE!r}, got {got!r}")
    raw: dict[str, tuple[int, str]] = {}
    for number, line in enumerate(lines[1:], start=2):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        key, sep, value = stripped.partition("=")
        key = key.strip()
        if not sep or not key:
            raise TableError(f"{source}: line {number}: expected 'key = value', got {stripped!r}")
        if key not in _TEXT_KEYS:
            raise TableError(f"{source}: line {number}: unknown key {key!r}")
        if key in raw:
            raise TableError(f"{source}: line {number}: key {key!r} given twice")
        raw[key] = (number, value.strip())
    missing = [k for k in _TEXT_KEYS if k not in raw]
    if missing:
        raise TableError(f"{source}: missing key(s) {', '.join(missing)}")
    for key in ("plant_model", "plant_fingerprint"):
        if not raw[key][1]:
            raise TableError(f"{source}: line {raw[key][0]}: {key}: expected a non-empty value")
    return raw
