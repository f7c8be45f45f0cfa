"""Every parameter of every node refuses a bad value with a ParameterFileError naming its key.

The cases are generated from the schemas (``params/schemas.py`` through the
node schemas of ``params/factories.py``, with every registered plant model's
and learning law's keys): for every key of every node, NaN, +-inf and values
just outside (and far outside) each bound of a number, wrong types, and a
string that is not one of the choices. Each goes through
:func:`~servo_axis.params.factories.checked_values`, the check the nodes and
the runner make, and must be refused naming the full dotted key.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest

from servo_axis.core.errors import ConfigError, ParameterFileError
from servo_axis.core.feedback.pid import PidGains
from servo_axis.params import factories
from servo_axis.params.factories import (
    IDENTIFIERS,
    LEARNING_LAWS,
    PLANT_MODELS,
    build_generator,
    build_loop,
    checked_values,
    node_schema,
)
from servo_axis.params.param import Param, build
from servo_axis.params.registry import parameter_sections
from servo_axis.params.scenario import ROLES, check_params_files


def bases(role: str) -> list[dict[str, Any]]:
    """The given keys that select each registered model (plant) or law (learning)."""
    if role == "plant":
        return [{"model": name} for name in PLANT_MODELS]
    if role == "learning":
        return [{"law": name} for name in LEARNING_LAWS]
    if role == "identifier":
        return [{"method": name} for name in IDENTIFIERS]
    return [{}]


def is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def outside(param: Param, integer: bool) -> list[tuple[str, object]]:
    """Values just outside and far outside each bound of a number."""
    out: list[tuple[str, object]] = []
    for bound, lower, inclusive in (
        (param.minimum, True, True),
        (param.above, True, False),
        (param.maximum, False, True),
        (param.below, False, False),
    ):
        if bound is None:
            continue
        step = -1 if lower else 1
        if integer:
            near: object = int(bound) + step if inclusive else int(bound)
        else:
            near = math.nextafter(bound, step * math.inf) if inclusive else float(bound)
        far: object = int(bound) + 1000 * step if integer else bound + 1e6 * step
        sign = (">=" if inclusive else ">") if lower else ("<=" if inclusive else "<")
        out += [(f"{sign}{bound:g}:near", near), (f"{sign}{bound:g}:far", far)]
    return out


def bad_values(param: Param) -> list[tuple[str, object]]:
    """(label, value) of every value ``param`` must refuse."""
    d = param.default
    if isinstance(d, bool):
        return [("int", 1), ("string", "true"), ("float", 1.0), ("list", [True])]
    if isinstance(d, int):
        return [
            ("nan", math.nan),
            ("inf", math.inf),
            ("-inf", -math.inf),
            ("float", 1.5),
            ("bool", True),
            ("string", "1"),
            ("list", [1]),
            *outside(param, integer=True),
        ]
    if isinstance(d, float):
        return [
            ("nan", math.nan),
            ("inf", math.inf),
            ("-inf", -math.inf),
            ("bool", True),
            ("string", "1.0"),
            ("list", [1.0]),
            *outside(param, integer=False),
        ]
    if isinstance(d, str):
        cases: list[tuple[str, object]] = [("int", 1), ("bool", True), ("list", ["a"])]
        if param.choices is not None:
            cases.append(("choice", "no-such-choice"))
        return cases
    assert isinstance(d, list), f"unexpected default {d!r}"
    if d and isinstance(d[0], str):
        return [("scalar", "a"), ("number element", ["a", 1]), ("bool element", [True])]
    return [
        ("nan element", [0.0, math.nan]),
        ("inf element", [math.inf]),
        ("-inf element", [-math.inf]),
        ("string element", [1.0, "a"]),
        ("bool element", [True]),
        ("scalar", 1.0),
        *((f"element {label}", [v]) for label, v in outside(param, integer=False)),
    ]


def cases() -> Iterator[Any]:
    for role in ROLES:
        for base in bases(role):
            selected = "".join(f"[{v}]" for v in base.values())
            for key, param in node_schema(role, base).items():
                for label, value in bad_values(param):
                    yield pytest.param(role, base, key, value, id=f"{role}{selected}:{key}:{label}")


CASES = list(cases())


def names(key: str) -> str:
    return re.escape(f"parameter '{key}'")


def test_the_cases_cover_every_key_of_every_schema() -> None:
    schemas: list[Mapping[str, Param]] = [
        *parameter_sections().values(),
        *(e.schema for e in PLANT_MODELS.values()),
        *(e.schema for e in LEARNING_LAWS.values()),
    ]
    covered = {values[2] for values in (c.values for c in CASES)}
    for schema in schemas:
        for key, param in schema.items():
            assert key in covered, key
            assert bad_values(param), key
    # Every number is tried with NaN and +-inf in every node that takes it.
    nan_cases = {(c.values[0], c.values[2]) for c in CASES if c.id.endswith(":nan")}
    for role in ROLES:
        for base in bases(role):
            for key, param in node_schema(role, base).items():
                if is_number(param.default):
                    assert (role, key) in nan_cases
    assert len(CASES) > 800


def test_the_defaults_of_every_node_are_accepted() -> None:
    for role in ROLES:
        for base in bases(role):
            values = checked_values(role, base)
            assert set(values) == set(node_schema(role, base))


@pytest.mark.parametrize(("role", "base", "key", "value"), CASES)
def test_a_bad_value_is_refused_naming_its_full_key(
    role: str, base: dict[str, Any], key: str, value: object
) -> None:
    with pytest.raises(ParameterFileError, match=names(key)) as info:
        checked_values(role, {**base, key: value})
    text = str(info.value)
    assert "\n" not in text
    assert "expected" in text


# ----------------------------------------------------------------- what depends on several keys


def values_of(role: str, **given: Any) -> dict[str, Any]:
    return checked_values(role, {k.replace("__", "."): v for k, v in given.items()})


@pytest.mark.parametrize(
    ("role", "given", "key"),
    [
        ("plant", {"sim_step_s": 0.0003}, "control_period_s"),
        ("plant", {"sim_step_s": 0.002}, "sim_step_s"),
        ("plant", {"dead_time_s": 7e-5}, "dead_time_s"),
        (
            "plant",
            {"modes.frequency_hz": [100.0, 0.0], "modes.zeta": [0.1, 0.1], "modes.a": [0.1, 0.1]},
            "modes.frequency_hz",
        ),
        (
            "plant",
            {"modes.frequency_hz": [1e4], "modes.zeta": [0.1], "modes.a": [0.1]},
            "modes.frequency_hz",
        ),
        ("plant", {"sim_step_s": 1e-9}, "control_period_s"),
        ("plant", {"dead_time_s": 10.0}, "dead_time_s"),
        ("feedback", {"bandwidth_hz": 1e300}, "bandwidth_hz"),
        ("feedforward", {"learning.enabled": True, "learning.cycle_s": 1e300}, "learning.cycle_s"),
        ("learning", {"cycle_s": 1e15}, "cycle_s"),
        ("plant", {"modes.frequency_hz": [100.0], "modes.a": [1.0, 2.0]}, "modes"),
        ("plant", {"modes.frequency_hz": [100.0], "modes.a": [0.1]}, "modes.zeta"),
        ("recorder", {"duration_s": 1e-4}, "duration_s"),
        ("feedback", {"duration_s": 1e-4}, "duration_s"),
        ("feedback", {"dob.enabled": True, "dob.cutoff_hz": 500.0}, "dob.cutoff_hz"),
        ("feedback", {"nominal.damping_Nms_per_rad": 100.0}, "bandwidth_hz"),
        ("feedforward", {"learning.enabled": True, "learning.cycle_s": 0.003}, "learning.cycle_s"),
        ("feedforward", {"learning.enabled": True, "learning.cycle_s": 0.006}, "learning.cycle_s"),
        ("feedforward", {"learning.enabled": True, "ptc.enabled": False}, "ptc.enabled"),
        ("feedforward", {"learning.enabled": True, "learning.law": "no-such"}, "learning.law"),
        ("feedforward", {"friction_table.enabled": True}, "friction_table.file"),
        (
            "feedforward",
            {"reference.kind": "point_to_point", "reference.distance_m": 0.0},
            "reference.distance_m",
        ),
        ("learning", {"cycle_s": 0.0015}, "cycle_s"),
        ("learning", {"cycle_s": 0.006}, "cycle_s"),
        ("learning", {"nq": 20, "n": 20}, "n, nq"),
        ("recorder", {"topics": ["state"]}, "types"),
        ("recorder", {"counted_topics": ["elsewhere"]}, "counted_topics"),
        ("recorder", {"latched_topics": ["elsewhere"]}, "latched_topics"),
    ],
)
def test_what_depends_on_several_keys_names_a_key_of_the_section(
    role: str, given: dict[str, Any], key: str
) -> None:
    with pytest.raises(ParameterFileError, match=names(key)):
        checked_values(role, given)


def test_the_builders_name_the_scenario_key_not_the_constructor_argument() -> None:
    # Values that bypassed the schema (a caller of the builders with its own
    # values): the error must still name the key of the scenario file.
    for builder, role in ((build_loop, "feedback"), (build_generator, "feedforward")):
        good = checked_values(role, {"dob.enabled": True} if role == "feedback" else {})
        for key, bad in (
            ("control_period_s", -1e-3),
            ("nominal.inertia_kgm2", 0.0),
            ("nominal.damping_Nms_per_rad", -1.0),
            ("nominal.torque_constant_Nm_per_A", math.nan),
        ):
            with pytest.raises(ParameterFileError, match=names(key)):
                builder({**good, key: bad})
    plant = checked_values("plant", {})
    with pytest.raises(ParameterFileError, match=names("control_period_s")):
        factories.build_plant({**plant, "control_period_s": -1e-3})
    learning = checked_values("learning", {})
    with pytest.raises(ParameterFileError, match=names("control_period_s")):
        factories.build_learning_law({**learning, "control_period_s": -1e-3})
    with pytest.raises(ParameterFileError, match=names("bandwidth_hz")):
        build_loop({**checked_values("feedback", {}), "bandwidth_hz": 1e300})


def test_build_maps_constructor_arguments_to_keys() -> None:
    gains = PidGains(
        kp_A_per_rad=1.0, ki_A_per_rad_s=1.0, kd_A_s_per_rad=0.1, derivative_tau_s=1e-3
    )
    from servo_axis.core.feedback.pid import DiscretePid

    with pytest.raises(ParameterFileError, match=names("control_period_s")):
        build("", DiscretePid, keys=factories.PERIOD_KEYS, gains=gains, period_s=-1.0)
    with pytest.raises(ParameterFileError, match=names("dob.period_s")):
        build("dob.", DiscretePid, gains=gains, period_s=-1.0)

    def refuses() -> None:
        raise ParameterFileError("parameter 'x.y': expected something")

    # An error that already names its parameter is passed on unchanged.
    with pytest.raises(ParameterFileError, match=r"^parameter 'x\.y': expected something$"):
        build("p.", refuses)


# ----------------------------------------------------------------- parameter files of a node


def test_a_missing_params_file_is_one_line_naming_it(tmp_path: Path) -> None:
    missing = tmp_path / "missing.yaml"
    with pytest.raises(ConfigError, match=re.escape(f"parameter file {missing}: cannot read")) as e:
        check_params_files(["--ros-args", "--params-file", str(missing)])
    assert "\n" not in str(e.value)


def test_a_broken_params_file_is_one_line_with_the_place(tmp_path: Path) -> None:
    good = tmp_path / "good.yaml"
    good.write_text("plant:\n  ros__parameters:\n    duration_s: 1.0\n")
    broken = tmp_path / "broken.yaml"
    broken.write_text("plant:\n  ros__parameters:\n    modes: {frequency_hz: [1.0, 2.0\n")
    check_params_files(["--ros-args", "--params-file", str(good)])
    with pytest.raises(
        ConfigError, match=re.escape(f"parameter file {broken}: not valid YAML")
    ) as e:
        check_params_files(["--ros-args", "--params-file", str(good), "--params-file", str(broken)])
    assert "\n" not in str(e.value)
    assert "line 4" in str(e.value)


def test_every_plant_model_has_the_drive_torque_constant() -> None:
    # The plant turns the torque reference of `command` into its current with it.
    for name, entry in PLANT_MODELS.items():
        assert "torque_constant_Nm_per_A" in entry.schema, name
    schema = {"inertia_kgm2": Param(0.01, unit="kg m^2", above=0.0, meaning="J")}
    with pytest.raises(ValueError, match="torque_constant_Nm_per_A"):
        factories.register_plant_model("no_drive_constant", schema=schema, build=lambda v, r: None)  # type: ignore[arg-type, return-value]
    assert "no_drive_constant" not in PLANT_MODELS
