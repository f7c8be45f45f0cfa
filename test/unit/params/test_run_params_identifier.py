"""The run's parameter file with an online identifier (paper 003): counts, memory, schedule."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from servo_axis.params import schemas
from servo_axis.params.factories import IDENTIFIERS
from servo_axis.params.run_params import handshake_overrides
from servo_axis.params.run_topics import recorder_topics
from servo_axis.params.scenario import flatten, load_scenario, roles_of
from servo_axis.plugins.dlpid import DLPID_FRICTION
from servo_axis.wire.topics import FLOAT64_MULTI_ARRAY, TOPICS

CONFIG = Path(__file__).resolve().parents[3] / "config"
BAG = Path("/tmp/run/bag")
ESTIMATES = "identifier/estimates"


def scenario(name: str) -> dict[str, Any]:
    data: dict[str, Any] = load_scenario(CONFIG / f"{name}.yaml")
    return data


def identifier_section(data: dict[str, Any]) -> dict[str, Any]:
    section: dict[str, Any] = flatten(data["identifier"]["ros__parameters"])
    return section


def overrides_of(data: dict[str, Any], roles: list[str] | None = None) -> dict[str, Any]:
    out: dict[str, Any] = handshake_overrides(
        data, roles_of(data) if roles is None else roles, BAG, CONFIG
    )
    return out


IDENTIFIED = ["dlpid_tilt_lpf2", "dlpid_tilt_lpf100", "dlpid_tilt_marc"]


def test_the_identifier_is_a_role_of_the_paper_003_scenarios_only() -> None:
    for name in IDENTIFIED:
        assert "identifier" in roles_of(scenario(name))
    roles = roles_of(scenario("dlpid_tilt_pid"))
    assert "identifier" not in roles and "learning" not in roles


# Counted by hand from the node graph (wire.topics):
#   identifier/estimates: feedforward, recorder
#   state:                feedback, identifier, recorder (no learning unit here)
#   command:              plant, identifier, recorder
@pytest.mark.parametrize(
    ("name", "estimates", "state", "command"),
    [
        ("dlpid_tilt_lpf2", 2, 3, 3),
        ("dlpid_tilt_lpf100", 2, 3, 3),
        ("dlpid_tilt_marc", 2, 3, 3),
        ("dlpid_tilt_pid", None, 2, 2),  # no identifier: feedback/plant + recorder
    ],
)
def test_subscriber_counts_with_and_without_an_identifier(
    name: str, estimates: int | None, state: int, command: int
) -> None:
    data = scenario(name)
    overrides = overrides_of(data)
    if estimates is None:
        assert "identifier" not in overrides
    else:
        assert overrides["identifier"]["wait_for_estimate_subscribers"] == estimates
    assert overrides["plant"]["wait_for_state_subscribers"] == state
    assert overrides["feedback"]["wait_for_command_subscribers"] == command
    # The table says the same: the identifier consumes both streams.
    by_name = {t.name: t for t in TOPICS}
    assert "identifier" in by_name["state"].consumers
    assert "identifier" in by_name["command"].consumers
    assert by_name[ESTIMATES].consumers == ("feedforward",)


def test_counts_without_a_recorder_are_the_control_nodes_only() -> None:
    data = scenario("dlpid_tilt_lpf2")
    roles = [r for r in roles_of(data) if r != "recorder"]
    overrides = overrides_of(data, roles)
    assert overrides["identifier"]["wait_for_estimate_subscribers"] == 1  # the feedforward
    assert overrides["plant"]["wait_for_state_subscribers"] == 2  # feedback, identifier
    assert overrides["feedback"]["wait_for_command_subscribers"] == 2  # plant, identifier
    # Without the identifier running, neither stream counts it.
    roles = [r for r in roles if r != "identifier"]
    overrides = overrides_of(data, roles)
    assert "identifier" not in overrides
    assert overrides["plant"]["wait_for_state_subscribers"] == 1
    assert overrides["feedback"]["wait_for_command_subscribers"] == 1
    assert not any(k.startswith(("adaptive.", "mnc.")) for k in overrides["feedforward"])


@pytest.mark.parametrize("name", IDENTIFIED)
def test_identifier_memory_goes_next_to_the_bag_unless_the_scenario_names_one(name: str) -> None:
    data = scenario(name)
    ident = overrides_of(data)["identifier"]
    assert ident["memory.file"] == str(BAG.parent / "identifier_memory.json")
    assert ident["report_dir"] == str(BAG.parent / "logs")
    # The learning unit's memory is another file.
    assert ident["memory.file"] != str(BAG.parent / "learning_memory.json")
    named = copy.deepcopy(data)
    named["identifier"]["ros__parameters"]["memory"] = {"file": "/elsewhere/id.json"}
    assert "memory.file" not in overrides_of(named)["identifier"]


@pytest.mark.parametrize("name", IDENTIFIED)
def test_feedforward_copies_the_identifiers_schedule_and_initial_estimates(name: str) -> None:
    data = scenario(name)
    ident = identifier_section(data)
    method = ident["method"]
    friction = IDENTIFIERS[method].estimates_friction
    assert friction == (method == "dlpid")
    ff = overrides_of(data)["feedforward"]
    assert ff["adaptive.enabled"] is True
    assert ff["adaptive.rls_period_s"] == ident["rls_period_s"]
    assert ff["adaptive.latency_s"] == ident["latency_s"]
    assert ff["mnc.unbalance_Nm"] == ident["initial.unbalance_Nm"]
    assert ff["mnc.friction"] is friction
    if friction:
        assert ff["mnc.coulomb_Nm"] == ident["initial.coulomb_Nm"]
    else:
        # MARC estimates no C: the feedforward keeps its own (unused) default.
        assert "mnc.coulomb_Nm" not in ff
        assert "initial.coulomb_Nm" not in ident


def test_mnc_friction_follows_the_method() -> None:
    assert overrides_of(scenario("dlpid_tilt_lpf2"))["feedforward"]["mnc.friction"] is True
    assert overrides_of(scenario("dlpid_tilt_marc"))["feedforward"]["mnc.friction"] is False


def test_values_the_section_leaves_out_are_the_identifiers_defaults() -> None:
    data = scenario("dlpid_tilt_lpf2")
    section = data["identifier"]["ros__parameters"]
    for key in ("rls_period_s", "latency_s", "initial", "method"):
        section.pop(key)
    ff = overrides_of(data)["feedforward"]
    assert ff["adaptive.rls_period_s"] == schemas.IDENTIFIER["rls_period_s"].default
    assert ff["adaptive.latency_s"] == schemas.IDENTIFIER["latency_s"].default
    assert ff["mnc.unbalance_Nm"] == schemas.IDENTIFIER["initial.unbalance_Nm"].default
    assert ff["mnc.coulomb_Nm"] == DLPID_FRICTION["initial.coulomb_Nm"].default
    assert (
        ff["mnc.friction"] is IDENTIFIERS[schemas.IDENTIFIER["method"].default].estimates_friction
    )


def test_a_changed_schedule_reaches_the_feedforward() -> None:
    data = scenario("dlpid_tilt_marc")
    section = data["identifier"]["ros__parameters"]
    section["rls_period_s"] = 2.0 * section["rls_period_s"]
    section["latency_s"] = 3.0 * section["latency_s"]
    section["initial"]["unbalance_Nm"] = 0.25
    ff = overrides_of(data)["feedforward"]
    assert ff["adaptive.rls_period_s"] == section["rls_period_s"]
    assert ff["adaptive.latency_s"] == section["latency_s"]
    assert ff["mnc.unbalance_Nm"] == 0.25


@pytest.mark.parametrize("name", [*IDENTIFIED, "dlpid_tilt_pid"])
def test_recorder_records_the_estimates_only_with_an_identifier(name: str) -> None:
    data = scenario(name)
    topics, types = recorder_topics(data, roles_of(data))
    rec = overrides_of(data)["recorder"]
    assert (rec["topics"], rec["types"]) == (topics, types)
    has_identifier = "identifier" in data
    assert (ESTIMATES in topics) is has_identifier
    if has_identifier:
        assert types[topics.index(ESTIMATES)] == FLOAT64_MULTI_ARRAY
        # In the order of the table of topics.
        table = [t.name for t in TOPICS]
        assert topics == sorted(topics, key=table.index)
    # Dropping the identifier from the run drops its topic.
    without = [r for r in roles_of(data) if r != "identifier"]
    assert ESTIMATES not in recorder_topics(data, without)[0]


def test_a_recorder_that_leaves_the_estimates_out_is_not_counted() -> None:
    data = scenario("dlpid_tilt_lpf2")
    data["recorder"]["ros__parameters"]["topics"] = ["state", "command"]
    data["recorder"]["ros__parameters"]["types"] = ["sensor_msgs/msg/JointState"] * 2
    overrides = overrides_of(data)
    assert overrides["identifier"]["wait_for_estimate_subscribers"] == 1
    assert overrides["plant"]["wait_for_state_subscribers"] == 3
