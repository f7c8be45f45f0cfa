"""The identifier's parameters (paper 003): every bad value refused by name, as the node checks."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from servo_axis.core.errors import ParameterFileError
from servo_axis.params import schemas
from servo_axis.params.factories import (
    IDENTIFIERS,
    build_generator,
    build_identifier,
    checked_values,
)
from servo_axis.params.scenario import load_scenario, node_params
from servo_axis.plugins.dlpid import DLPID_FRICTION

CONFIG = Path(__file__).resolve().parents[3] / "config"


def given(name: str, role: str) -> dict[str, Any]:
    """What a scenario's section gives node ``role`` (shared keys included), unchecked."""
    section: dict[str, Any] = node_params(load_scenario(CONFIG / f"{name}.yaml"), role)
    return section


DLPID = given("dlpid_tilt_lpf2", "identifier")
MARC = given("dlpid_tilt_marc", "identifier")
T_U = DLPID["control_period_s"]
T_R = 2.0 * T_U  # the reference period of the multirate grid


def refused(role: str, values: dict[str, Any], key: str) -> ParameterFileError:
    with pytest.raises(ParameterFileError, match=rf"parameter '{re.escape(key)}'") as info:
        checked_values(role, values)
    return info.value


def bound(section: dict[str, Any], key: str) -> tuple[float, float]:
    default = {**schemas.IDENTIFIER, **DLPID_FRICTION}[key].default
    lo, hi = section.get(key, default)
    return float(lo), float(hi)


# -- the shipped values -----------------------------------------------------------------


@pytest.mark.parametrize(("section", "mode"), [(DLPID, "double_layer"), (MARC, "single_layer")])
def test_the_scenario_values_build_the_identifier(section: dict[str, Any], mode: str) -> None:
    values = checked_values("identifier", section)
    ident = build_identifier(values)
    assert ident.ratio == round(section["rls_period_s"] / T_U)
    assert ident.state()["mode"] == mode
    assert ident.last_step is None


# -- identifier section -------------------------------------------------------------------


@pytest.mark.parametrize("position", [0, 1, 2])
@pytest.mark.parametrize(("bad", "match"), [(0.0, "> 0"), (-0.1, "> 0"), (1.01, "<= 1")])
def test_forgetting_outside_zero_one_is_refused(position: int, bad: float, match: str) -> None:
    forgetting = list(DLPID["forgetting"])
    forgetting[position] = bad
    err = refused("identifier", {**DLPID, "forgetting": forgetting}, "forgetting")
    assert match in str(err)


def test_forgetting_of_one_is_no_forgetting_and_accepted() -> None:
    values = checked_values("identifier", {**DLPID, "forgetting": [1.0, 1.0, 1.0]})
    assert values["forgetting"] == [1.0, 1.0, 1.0]


@pytest.mark.parametrize("forgetting", [[], [0.999], [0.999, 0.999], [0.999] * 4, 0.999])
def test_forgetting_not_three_values_is_refused(forgetting: Any) -> None:
    refused("identifier", {**DLPID, "forgetting": forgetting}, "forgetting")


@pytest.mark.parametrize(
    "key",
    [
        "bounds.inertia_kgm2",
        "bounds.damping_Nms_per_rad",
        "bounds.unbalance_Nm",
        "bounds.coulomb_Nm",
    ],
)
def test_bounds_with_min_not_below_max_are_refused(key: str) -> None:
    lo, hi = bound(DLPID, key)
    for pair in ([hi, lo], [hi, hi], [lo, lo], [lo], [lo, hi, hi]):
        err = refused("identifier", {**DLPID, key: pair}, key)
        assert "min < max" in str(err), pair


INITIAL = [
    ("nominal.inertia_kgm2", "bounds.inertia_kgm2"),
    ("nominal.damping_Nms_per_rad", "bounds.damping_Nms_per_rad"),
    ("initial.unbalance_Nm", "bounds.unbalance_Nm"),
    ("initial.coulomb_Nm", "bounds.coulomb_Nm"),
]


@pytest.mark.parametrize(("key", "bounds_key"), INITIAL)
def test_initial_estimate_above_its_bounds_is_refused(key: str, bounds_key: str) -> None:
    _, hi = bound(DLPID, bounds_key)
    refused("identifier", {**DLPID, key: 2.0 * hi}, key)


@pytest.mark.parametrize(("key", "bounds_key"), INITIAL)
def test_initial_estimate_below_its_bounds_is_refused(key: str, bounds_key: str) -> None:
    initial = float(DLPID[key])
    # Bounds that exclude the scenario's initial value from below.
    refused("identifier", {**DLPID, bounds_key: [2.0 * initial, 4.0 * initial]}, key)
    # Bounds that hold it exactly at an edge are fine.
    checked_values("identifier", {**DLPID, bounds_key: [initial, 4.0 * initial]})
    checked_values("identifier", {**DLPID, bounds_key: [0.5 * initial, initial]})


@pytest.mark.parametrize("window", [2, 1, 0, -5])
def test_pe_window_below_three_is_refused(window: int) -> None:
    refused("identifier", {**DLPID, "pe_window": window}, "pe_window")
    assert checked_values("identifier", {**DLPID, "pe_window": 3})["pe_window"] == 3


def test_latency_shorter_than_the_rls_period_is_refused() -> None:
    period = 4.0 * T_R
    err = refused(
        "identifier", {**DLPID, "rls_period_s": period, "latency_s": period - T_R}, "latency_s"
    )
    assert "at least one estimate period" in str(err)
    # Exactly one period, or more, is fine.
    for latency in (period, period + T_R):
        checked_values("identifier", {**DLPID, "rls_period_s": period, "latency_s": latency})


@pytest.mark.parametrize("bad", [1.5, 0.5, 2.25])
def test_rls_period_not_whole_reference_periods_is_refused(bad: float) -> None:
    # latency_s large and whole, so that only rls_period_s is wrong.
    values = {**DLPID, "rls_period_s": bad * T_R, "latency_s": 10.0 * T_R}
    err = refused("identifier", values, "rls_period_s")
    assert "whole number" in str(err)


@pytest.mark.parametrize("bad", [5.5, 0.5, 1.25])
def test_latency_not_whole_reference_periods_is_refused(bad: float) -> None:
    err = refused("identifier", {**DLPID, "rls_period_s": T_R, "latency_s": bad * T_R}, "latency_s")
    assert "whole number" in str(err)


def test_a_control_period_as_rls_period_is_not_a_reference_period() -> None:
    # T_RLS = T_u is a whole number of control periods but not of T_r = 2 T_u.
    refused("identifier", {**DLPID, "rls_period_s": T_U, "latency_s": 10.0 * T_R}, "rls_period_s")


@pytest.mark.parametrize("method", ["lms", "DLPID", "", 3, None])
def test_unknown_method_names_the_registered_ones(method: Any) -> None:
    err = refused("identifier", {**MARC, "method": method}, "method")
    assert f"expected one of {sorted(IDENTIFIERS)}" in str(err)
    assert {"dlpid", "marc"} <= set(IDENTIFIERS)


@pytest.mark.parametrize("key", sorted(DLPID_FRICTION))
def test_marc_has_no_friction_keys(key: str) -> None:
    value = DLPID_FRICTION[key].default
    with pytest.raises(
        ParameterFileError, match=rf"unknown parameter '{re.escape(key)}' for node 'identifier'"
    ):
        checked_values("identifier", {**MARC, key: value})
    # The same key is dlpid's own.
    checked_values("identifier", {**MARC, "method": "dlpid", key: value})


def test_friction_cutoff_hz_given_to_marc_is_unknown() -> None:
    with pytest.raises(ParameterFileError, match=r"unknown parameter 'friction\.cutoff_hz'"):
        checked_values("identifier", {**MARC, "friction.cutoff_hz": 2.0})


# -- the feedforward's copy of the schedule --------------------------------------------------


FEEDFORWARD = {**given("dlpid_tilt_lpf2", "feedforward"), "adaptive.enabled": True}


def test_the_feedforward_schedule_in_control_samples() -> None:
    period, latency = 2.0 * T_R, 3.0 * T_R
    values = checked_values(
        "feedforward",
        {**FEEDFORWARD, "adaptive.rls_period_s": period, "adaptive.latency_s": latency},
    )
    gen = build_generator(values, terms=[])
    # The first estimate is computed from samples 0 .. R - 1, applies from R + L.
    assert gen.next_estimate_step == round((period + latency) / T_U)


@pytest.mark.parametrize("bad", [1.5, 0.5, 2.25])
def test_feedforward_rls_period_not_whole_reference_periods_is_refused(bad: float) -> None:
    values = {
        **FEEDFORWARD,
        "adaptive.rls_period_s": bad * T_R,
        "adaptive.latency_s": 10.0 * T_R,
    }
    err = refused("feedforward", values, "adaptive.rls_period_s")
    assert "whole number" in str(err)


@pytest.mark.parametrize("bad", [5.5, 0.5, 1.25])
def test_feedforward_latency_not_whole_reference_periods_is_refused(bad: float) -> None:
    values = {**FEEDFORWARD, "adaptive.rls_period_s": T_R, "adaptive.latency_s": bad * T_R}
    err = refused("feedforward", values, "adaptive.latency_s")
    assert "whole number" in str(err)


def test_feedforward_latency_shorter_than_its_period_is_refused() -> None:
    values = {
        **FEEDFORWARD,
        "adaptive.rls_period_s": 4.0 * T_R,
        "adaptive.latency_s": 3.0 * T_R,
    }
    err = refused("feedforward", values, "adaptive.latency_s")
    assert "at least one estimate period" in str(err)


@pytest.mark.parametrize("key", ["adaptive.rls_period_s", "adaptive.latency_s"])
@pytest.mark.parametrize("bad", [0.0, -4e-3])
def test_feedforward_schedule_not_positive_is_refused(key: str, bad: float) -> None:
    refused("feedforward", {**FEEDFORWARD, key: bad}, key)
