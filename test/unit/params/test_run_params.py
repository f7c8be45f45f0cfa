"""The run's parameter file: handshake counts, recorder topics, what the learning unit copies."""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import pytest
import yaml

from servo_axis.nodes.lockstep import FlowControl
from servo_axis.params.run_params import (
    OUTSIDE_PUBLISHER_DEPTH,
    handshake_overrides,
    outside_flow_control,
    write_run_params,
)
from servo_axis.params.run_topics import recorder_topics
from servo_axis.params.scenario import axis_view, load_scenario, roles_of
from servo_axis.run.processes import discovery_settings, ros_environment
from servo_axis.run.progress import temporary_environ
from servo_axis.wire.topics import TOPICS

CONFIG = Path(__file__).resolve().parents[3] / "config"
BAG = Path("/tmp/run/bag")


def scenario(name: str, axis: str = "") -> dict[str, Any]:
    data = load_scenario(CONFIG / f"{name}.yaml")
    return axis_view(data, axis, CONFIG) if axis else data


def counts(overrides: dict[str, dict[str, Any]]) -> tuple[int, int, int, int]:
    """(state, /clock, plant/status, reference) subscribers the publishers wait for."""
    plant = overrides["plant"]
    return (
        plant["wait_for_state_subscribers"],
        plant["wait_for_clock_subscribers"],
        plant["wait_for_status_subscribers"],
        overrides["feedforward"]["wait_for_reference_subscribers"],
    )


# Counted by hand from the node graph (docs/reference/topics.md):
#   state:        feedback, learning, recorder
#   /clock:       feedback, feedforward, learning (use_sim_time), recorder
#   plant/status: feedforward, recorder
#   reference:    feedback, recorder
@pytest.mark.parametrize(
    ("name", "axis", "expected"),
    [
        ("ptc_nominal", "", (2, 3, 2, 2)),  # feedback + recorder; + feedforward on /clock
        ("rptc_detailed", "", (3, 4, 2, 2)),  # + the learning unit on state and /clock
        ("xy_circle", "y", (3, 4, 2, 2)),  # one axis of the circle: the same graph
    ],
)
def test_subscriber_counts_of_shipped_scenarios(
    name: str, axis: str, expected: tuple[int, int, int, int]
) -> None:
    data = scenario(name, axis)
    overrides = handshake_overrides(data, roles_of(data), BAG, CONFIG)
    assert counts(overrides) == expected
    assert overrides["plant"]["flow_control"] is True
    assert overrides["recorder"]["output_dir"] == str(BAG)


def test_subscriber_counts_follow_what_runs_and_what_is_recorded() -> None:
    data = scenario("ptc_nominal")
    # No recorder: only the control nodes, and no flow control.
    roles = ["feedforward", "feedback", "plant"]
    overrides = handshake_overrides(data, roles, BAG, CONFIG)
    assert counts(overrides) == (1, 2, 1, 1)
    assert "flow_control" not in overrides["plant"]
    # A recorder that records only state and command waits on neither
    # /clock, plant/status nor reference, and its list is left alone.
    data["recorder"]["ros__parameters"]["topics"] = ["state", "command"]
    data["recorder"]["ros__parameters"]["types"] = ["sensor_msgs/msg/JointState"] * 2
    overrides = handshake_overrides(data, roles_of(data), BAG, CONFIG)
    assert counts(overrides) == (2, 2, 1, 1)
    assert "topics" not in overrides["recorder"] and "types" not in overrides["recorder"]


def test_recorder_records_the_table_topics_of_the_nodes_that_run_in_table_order() -> None:
    core = [
        ("state", "sensor_msgs/msg/JointState"),
        ("command", "sensor_msgs/msg/JointState"),
        ("reference", "sensor_msgs/msg/JointState"),
        ("/clock", "rosgraph_msgs/msg/Clock"),
        ("fault", "std_msgs/msg/Float64MultiArray"),
        ("plant/status", "std_msgs/msg/Float64MultiArray"),
    ]
    learning = [
        ("learning/correction", "sensor_msgs/msg/JointState"),
        ("learning/cycle_stats", "std_msgs/msg/Float64MultiArray"),
    ]
    for name, expected in (("ptc_nominal", core), ("rptc_detailed", core + learning)):
        data = scenario(name)
        topics, types = recorder_topics(data, roles_of(data))
        assert list(zip(topics, types, strict=True)) == expected
        rec = handshake_overrides(data, roles_of(data), BAG, CONFIG)["recorder"]
        assert (rec["topics"], rec["types"]) == (topics, types)
    # The runner's own flow-control topic is not recorded.
    assert "recorder/progress" in {t.name for t in TOPICS}
    assert "recorder/progress" not in recorder_topics(data, roles_of(data))[0]


def test_learning_unit_copies_target_cycle_and_sensor() -> None:
    data = scenario("rptc_detailed")
    ff = data["feedforward"]["ros__parameters"]
    learning = handshake_overrides(data, roles_of(data), BAG, CONFIG)["learning"]
    assert learning["cycle_s"] == ff["learning"]["cycle_s"]
    assert {k.removeprefix("reference."): v for k, v in learning.items() if "reference." in k} == (
        ff["reference"]
    )
    assert learning["memory.file"] == str(BAG.parent / "learning_memory.json")
    assert "sensor" not in learning  # the feedback section does not set it
    full_closed = copy.deepcopy(data)
    full_closed["feedback"]["ros__parameters"]["sensor"] = "scale"
    learning = handshake_overrides(full_closed, roles_of(full_closed), BAG, CONFIG)["learning"]
    assert learning["sensor"] == "scale"


def test_nodes_on_the_plant_clock_get_sim_time_and_the_plant_does_not() -> None:
    data = scenario("rptc_detailed")
    overrides = handshake_overrides(data, roles_of(data), BAG, CONFIG)
    for role in ("feedback", "feedforward", "learning"):
        assert overrides[role]["use_sim_time"] is True
    assert "use_sim_time" not in overrides["plant"]
    # The recorder stamps the bag with wall time; its /clock subscription is
    # the one counted in wait_for_clock_subscribers.
    assert "use_sim_time" not in overrides["recorder"]


def test_run_params_file_holds_the_scenario_and_the_overrides(tmp_path: Path) -> None:
    data = scenario("ptc_friction_table")
    overrides = handshake_overrides(data, roles_of(data), tmp_path / "bag", CONFIG)
    path = write_run_params(data, overrides, tmp_path / "params.yaml")
    written = yaml.safe_load(path.read_text())
    assert list(written) == [
        "/**",
        "/**/plant",
        "/**/feedback",
        "/**/feedforward",
        "/**/recorder",
    ]
    assert written["/**"] == data["/**"]
    ff = written["/**/feedforward"]["ros__parameters"]
    assert ff["friction_table.file"] == str(CONFIG / "friction_table_ball_screw_x.csv")
    assert ff["use_sim_time"] is True
    assert written["/**/plant"]["ros__parameters"]["wait_for_state_subscribers"] == 2
    assert written["/**/recorder"]["ros__parameters"]["output_dir"] == str(tmp_path / "bag")


def test_environment_helpers_leave_os_environ_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FASTDDS_BUILTIN_TRANSPORTS", "DEFAULT")
    monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE", raising=False)
    before = dict(os.environ)
    env = ros_environment(42, Path("/tmp/logs"))
    assert env["ROS_DOMAIN_ID"] == "42" and env["FASTDDS_BUILTIN_TRANSPORTS"] == "UDPv4"
    assert Path(env["FASTRTPS_DEFAULT_PROFILES_FILE"]).is_file()
    assert dict(os.environ) == before
    settings = discovery_settings(Path("/tmp/logs"))
    with temporary_environ(settings):
        assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
        assert os.environ["FASTDDS_BUILTIN_TRANSPORTS"] == "UDPv4"
    assert dict(os.environ) == before  # the unset one removed, the set one back
    with pytest.raises(RuntimeError), temporary_environ(settings):
        raise RuntimeError
    assert dict(os.environ) == before


@pytest.mark.parametrize(
    ("external", "capped"),
    [
        (("feedback",), True),  # command: counted, from a default-profile publisher
        (("feedforward",), True),  # reference
        (("learning",), False),  # its streams are not counted by the flow control
        ((), False),
    ],
)
def test_an_outside_publisher_of_a_counted_stream_caps_the_plants_lead(
    external: tuple[str, ...], capped: bool
) -> None:
    data = scenario("rptc_detailed")
    overrides = handshake_overrides(data, roles_of(data), BAG, CONFIG, external=external)
    if capped:
        assert overrides["plant"]["max_recorder_lag_steps"] == OUTSIDE_PUBLISHER_DEPTH - 2
        assert overrides["recorder"]["ack_every_steps"] == OUTSIDE_PUBLISHER_DEPTH - 2
    else:
        assert "max_recorder_lag_steps" not in overrides["plant"]
        assert "ack_every_steps" not in overrides["recorder"]
    # A scenario's smaller lead stays.
    data["plant"]["ros__parameters"]["max_recorder_lag_steps"] = 3
    assert outside_flow_control(data) == {"max_recorder_lag_steps": 3}


def test_an_outside_plant_needs_only_state_and_command() -> None:
    """Issue 31: the feedback makes `command` (the plant's start sign) once every reader of
    `state` is in and holds its answers for the recorder; the feedforward tops up on
    `state`; the recorder's progress does not wait for `/clock` or `plant/status`."""
    data = scenario("ptc_nominal")
    ours = handshake_overrides(data, roles_of(data), BAG, CONFIG)
    theirs = handshake_overrides(data, roles_of(data), BAG, CONFIG, external=("plant",))
    readers = ours["plant"]["wait_for_state_subscribers"]
    assert readers == 2  # the feedback, the recorder
    assert theirs["feedback"]["wait_for_state_readers"] == readers + 1  # + the feedforward
    assert theirs["feedforward"]["progress_from_state"] is True
    # plant/status: the recorder's only (a suite's plant started by hand waits for it)
    assert ours["plant"]["wait_for_status_subscribers"] == 2
    assert theirs["plant"]["wait_for_status_subscribers"] == 1
    assert theirs["feedback"]["recorder_lag_steps"] == OUTSIDE_PUBLISHER_DEPTH - 2
    assert theirs["recorder"]["ack_every_steps"] == OUTSIDE_PUBLISHER_DEPTH - 2
    assert "final_topics" not in theirs["recorder"]
    assert ours["recorder"]["final_topics"] == ["/clock", "plant/status"]
    for key in ("wait_for_state_readers", "recorder_lag_steps"):
        assert key not in ours["feedback"]
    assert "progress_from_state" not in ours["feedforward"]
    realtime = scenario("ptc_nominal")
    realtime["plant"]["ros__parameters"]["mode"] = "realtime"
    rt = handshake_overrides(realtime, roles_of(realtime), BAG, CONFIG, external=("plant",))
    assert "recorder_lag_steps" not in rt["feedback"]  # lockstep only


def lost_by_a_keep_last_writer(lag: int, ack_every: int, depth: int = 10) -> int:
    """Samples an outside keep-last ``depth`` writer overwrote before the recorder took them.

    The plant publishes ``state[k]`` once the recorder's last acknowledgement
    is at least ``k - lag`` (:class:`FlowControl`); the outside node answers
    each state at once; the recorder takes nothing for as long as the plant
    can go on, then everything (the worst case), acknowledging every
    ``ack_every`` steps.
    """
    steps = 2000
    flow = FlowControl(enabled=True, max_lag_steps=lag, steps=steps)
    flow.acknowledge(0)
    history: list[int] = []  # the writer's last `depth` samples
    taken = lost = 0
    k = 0
    while taken < steps:
        while k < steps and flow.may_step_to(k):
            history = [*history, k][-depth:]  # the answer to state[k]
            k += 1
        lost += sum(1 for s in range(taken, k) if s not in history)
        taken = k
        flow.acknowledge(taken - taken % ack_every)
        if k == steps:
            break
    return lost


def test_the_capped_lead_loses_nothing_of_a_default_depth_writer() -> None:
    data = scenario("rptc_detailed")
    capped = outside_flow_control(data)["max_recorder_lag_steps"]
    assert lost_by_a_keep_last_writer(capped, capped) == 0
    assert lost_by_a_keep_last_writer(capped, 1) == 0
    # The shipped lead (200, acknowledged every 50) lost all but the newest
    # 10 of each burst: what a slow recorder met with an example controller.
    assert lost_by_a_keep_last_writer(200, 50) > 1000


def test_a_drive_set_point_is_recorded_not_counted_and_only_in_realtime(tmp_path: Path) -> None:
    """``command_source: drive_setpoint``: ros2_control's commands carry no step, so the
    recorder records `command` without counting it, and lockstep (which waits for the
    command of each step) refuses the option naming both keys."""
    data = scenario("ptc_nominal")
    data["/**"]["ros__parameters"]["mode"] = "realtime"
    data["plant"]["ros__parameters"]["command_source"] = "drive_setpoint"
    external = ("feedback",)
    rec = handshake_overrides(data, roles_of(data), BAG, CONFIG, external)["recorder"]
    assert "command" in rec["topics"] and "command" not in rec["counted_topics"]
    assert "state" in rec["counted_topics"]
    stamped = scenario("ptc_nominal")
    stamped["/**"]["ros__parameters"]["mode"] = "realtime"
    rec = handshake_overrides(stamped, roles_of(stamped), BAG, CONFIG, external)["recorder"]
    assert "command" in rec["counted_topics"]
    from servo_axis.core.errors import ParameterFileError
    from servo_axis.params.factories import checked_values

    with pytest.raises(ParameterFileError, match=r"'command_source': drive_setpoint needs mode"):
        checked_values("plant", {"command_source": "drive_setpoint", "mode": "lockstep"})
    values = checked_values("plant", {"command_source": "drive_setpoint", "mode": "realtime"})
    assert values["setpoint_period_s"] == 0.0 and values["setpoint_threshold_Nm"] == -1.0
    # The identifier pairs commands with states by stamp: refused before anything starts.
    from servo_axis.core.errors import ConfigError
    from servo_axis.params.run_plan import plan_run

    path = CONFIG / "dlpid_tilt_lpf2.yaml"
    identified = load_scenario(path)
    identified["/**"]["ros__parameters"]["mode"] = "realtime"
    identified["plant"]["ros__parameters"]["command_source"] = "drive_setpoint"
    with pytest.raises(ConfigError, match="drive_setpoint: the identifier pairs each command"):
        plan_run(identified, path, out_dir=tmp_path / "run")


@pytest.mark.parametrize("topic", ["/effort_controller/commands", "effort_controller/commands"])
def test_a_forward_commands_topic_is_a_ros_topic_name(topic: str) -> None:
    from servo_axis.core.errors import ParameterFileError
    from servo_axis.params.factories import checked_values

    assert checked_values("feedback", {"forward_commands_topic": topic})["forward_commands_topic"]
    with pytest.raises(ParameterFileError, match=r"'forward_commands_topic': .* segment '2x'"):
        checked_values("feedback", {"forward_commands_topic": topic.replace("commands", "2x")})


def test_the_run_tells_an_outside_feedback_that_its_command_is_a_set_point(
    tmp_path: Path,
) -> None:
    from servo_axis.params.run_plan import plan_run
    from servo_axis.run.prepare import describe_external

    path = CONFIG / "ptc_nominal.yaml"
    data = load_scenario(path)
    data["/**"]["ros__parameters"]["mode"] = "realtime"
    stamped = plan_run(data, path, out_dir=tmp_path / "a", external=["feedback"]).axes[0]
    assert "the answer to state[k]" in describe_external(stamped, "feedback")
    data["plant"]["ros__parameters"]["command_source"] = "drive_setpoint"
    driven = plan_run(data, path, out_dir=tmp_path / "b", external=["feedback"]).axes[0]
    text = describe_external(driven, "feedback")
    assert "a drive's set-point: effort of the motor joint (N m), any stamp" in text
    assert "the answer to state[k]" not in text
