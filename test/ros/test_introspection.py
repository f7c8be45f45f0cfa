"""ROS introspection of a node: parameters described and read-only, its /diagnostics levels."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import pytest
import rclpy
from numpy.testing import assert_allclose
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from servo_axis.nodes.plant import PlantNode
from servo_axis.params.scenario import load_scenario, node_params

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parents[2] / "config"


def call(
    ctx: Context, nodes: list[Node], client: Any, request: Any, timeout_s: float = 20.0
) -> Any:
    """Call a service once it is there, spinning ``nodes``; the response."""
    ex = SingleThreadedExecutor(context=ctx)
    for n in nodes:
        ex.add_node(n)
    deadline = time.monotonic() + timeout_s
    try:
        while not client.service_is_ready():
            assert time.monotonic() < deadline, "service not found"
            ex.spin_once(timeout_sec=0.05)
        future = client.call_async(request)
        while not future.done():
            assert time.monotonic() < deadline, "no response"
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.shutdown()
    return future.result()


def test_parameters_are_described_and_refuse_a_set_while_running(context: Context) -> None:
    """describe_parameters from a second node gives meaning, unit and range; a set is refused."""
    given = node_params(load_scenario(CONFIG / "ptc_nominal.yaml"), "plant")
    given["duration_s"] = 1  # an integer for a number: declared as the number 1.0
    plant = PlantNode(
        context=context,
        namespace="/x",
        parameter_overrides=[Parameter(k, value=v) for k, v in given.items()],
    )
    probe = rclpy.create_node("probe", context=context)
    try:
        assert plant.get_fully_qualified_name() == "/x/plant"
        names = [
            "duration_s",
            "control_period_s",
            "friction.elements",
            "mode",
            "modes.frequency_hz",
            "clock_every_steps",
        ]
        describe = probe.create_client(DescribeParameters, "/x/plant/describe_parameters")
        got = call(context, [plant, probe], describe, DescribeParameters.Request(names=names))
        by_name = {d.name: d for d in got.descriptors}
        assert sorted(by_name) == sorted(names)
        assert all(d.read_only for d in got.descriptors)

        duration = by_name["duration_s"]
        assert duration.type == ParameterType.PARAMETER_DOUBLE
        assert "length of the run" in duration.description and "[s]" in duration.description
        assert "the bound 0 itself is refused" in duration.description  # exclusive: > 0
        (fp,) = duration.floating_point_range
        assert fp.from_value == 0.0 and math.isinf(fp.to_value) and fp.step == 0.0

        (fp,) = by_name["control_period_s"].floating_point_range
        assert_allclose([fp.from_value, fp.to_value], [1e-6, 1.0], rtol=0, atol=0)
        assert "refused" not in by_name["control_period_s"].description  # inclusive bounds

        elements = by_name["friction.elements"]
        assert elements.type == ParameterType.PARAMETER_INTEGER
        (ir,) = elements.integer_range
        assert (ir.from_value, ir.to_value, ir.step) == (1, 200, 0)
        (ir,) = by_name["clock_every_steps"].integer_range
        assert (ir.from_value, ir.to_value) == (1, 2**63 - 1)

        mode = by_name["mode"]
        assert mode.type == ParameterType.PARAMETER_STRING
        assert "one of 'lockstep', 'realtime'" in mode.additional_constraints
        assert not mode.floating_point_range and not mode.integer_range
        assert by_name["modes.frequency_hz"].type == ParameterType.PARAMETER_DOUBLE_ARRAY

        # The declared values are the checked ones (the integer 1 is the number 1.0).
        get = probe.create_client(GetParameters, "/x/plant/get_parameters")
        values = call(context, [plant, probe], get, GetParameters.Request(names=["duration_s"]))
        (value,) = values.values
        assert value.type == ParameterType.PARAMETER_DOUBLE and value.double_value == 1.0

        # A set while running is refused with a reason, and the value stays.
        setter = probe.create_client(SetParameters, "/x/plant/set_parameters")
        request = SetParameters.Request(
            parameters=[
                ParameterMsg(
                    name="duration_s",
                    value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=5.0),
                )
            ]
        )
        (result,) = call(context, [plant, probe], setter, request).results
        assert not result.successful
        assert result.reason == "Trying to set a read-only parameter: duration_s."
        assert plant.get_parameter("duration_s").value == 1.0
        # An undeclared name is refused too (it is not created).
        request.parameters[0].name = "no_such_key"
        (result,) = call(context, [plant, probe], setter, request).results
        assert not result.successful  # rclpy 7.1: "Invalid access to undeclared parameter(s)"
        assert not plant.has_parameter("no_such_key")
    finally:
        probe.destroy_node()
        plant.destroy_node()


def every_schema() -> list[tuple[str, Any]]:
    """``(role/choice, schema)`` for every role and every plant model, law and method."""
    from servo_axis.params.factories import (
        IDENTIFIERS,
        LEARNING_LAWS,
        NODE_SCHEMAS,
        PLANT_MODELS,
        node_schema,
    )

    out = [(role, node_schema(role, {})) for role in NODE_SCHEMAS]
    out += [(f"plant/{m}", node_schema("plant", {"model": m})) for m in PLANT_MODELS]
    out += [(f"learning/{law}", node_schema("learning", {"law": law})) for law in LEARNING_LAWS]
    out += [(f"identifier/{m}", node_schema("identifier", {"method": m})) for m in IDENTIFIERS]
    return out


@pytest.mark.parametrize(
    ("where", "schema"), every_schema(), ids=lambda x: x if isinstance(x, str) else ""
)
def test_every_key_gets_a_descriptor_whose_range_holds_its_default(where: str, schema: Any) -> None:
    from servo_axis.nodes.parameters import descriptor

    for name, param in schema.items():
        d = descriptor(name, param)
        assert d.read_only and d.name == name and d.description, (where, name)
        assert param.meaning in d.description, (where, name)
        assert not param.unit or f"[{param.unit}]" in d.description, (where, name)
        default = param.default if isinstance(param.default, list) else [param.default]
        for x in default:
            for r in [*d.floating_point_range, *d.integer_range]:
                assert r.from_value <= x <= r.to_value, (where, name, x, r)
        if param.above is not None and not d.integer_range and param.minimum is None:
            assert "itself is refused" in d.description, (where, name)


def test_diagnostics_levels_of_a_node_seen_by_a_default_qos_subscriber(context: Context) -> None:
    """OK, then WARN after a rejected message, then ERROR after a trip, on /diagnostics."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    from servo_axis.core.feedback.loop import Fault
    from servo_axis.nodes.feedback import FeedbackNode

    feedback = FeedbackNode(context=context, namespace="/y")
    probe = rclpy.create_node("probe", context=context)
    got: list[DiagnosticStatus] = []
    sub = probe.create_subscription(
        DiagnosticArray, "/diagnostics", lambda m: got.extend(m.status), 10
    )
    ex = SingleThreadedExecutor(context=context)
    ex.add_node(feedback)
    ex.add_node(probe)

    def publish_and_read() -> DiagnosticStatus:
        got.clear()
        feedback.publish_diagnostics()
        deadline = time.monotonic() + 10
        while not any(s.name == "/y/feedback" for s in got):
            assert time.monotonic() < deadline, "no status"
            ex.spin_once(timeout_sec=0.02)
        return [s for s in got if s.name == "/y/feedback"][-1]

    try:
        deadline = time.monotonic() + 10
        while sub.get_publisher_count() < 1:
            assert time.monotonic() < deadline, "not matched"
            ex.spin_once(timeout_sec=0.02)
        ok = publish_and_read()
        assert ok.level == DiagnosticStatus.OK and ok.hardware_id == "x"
        feedback.report.reject("state", "state rejected: junk")
        warn = publish_and_read()
        assert warn.level == DiagnosticStatus.WARN
        assert warn.message == "1 messages rejected (1 state)"
        feedback.loop.trip(Fault.FOLLOWING_ERROR)
        error = publish_and_read()
        assert error.level == DiagnosticStatus.ERROR
        assert error.message.startswith("tripped: following_error")
        values = {kv.key: kv.value for kv in error.values}
        assert values["tripped"] == "true" and values["fault"] == "following_error"
        assert values["rejected state"] == "1"
    finally:
        ex.shutdown()
        probe.destroy_node()
        feedback.destroy_node()
