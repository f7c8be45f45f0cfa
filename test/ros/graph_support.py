"""The node graph of a scenario in one process, as the runner would start it (ROS tests)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from servo_axis.nodes.feedback import FeedbackNode
from servo_axis.nodes.feedforward import FeedforwardNode
from servo_axis.nodes.identifier import IdentifierNode
from servo_axis.nodes.learning import LearningNode
from servo_axis.nodes.plant import PlantNode
from servo_axis.nodes.recorder import RecorderNode
from servo_axis.params.run_params import handshake_overrides
from servo_axis.params.scenario import node_params, roles_of

NODE_CLASSES: dict[str, Callable[..., Node]] = {
    "plant": PlantNode,
    "feedback": FeedbackNode,
    "feedforward": FeedforwardNode,
    "recorder": RecorderNode,
    "learning": LearningNode,
    "identifier": IdentifierNode,
}


def graph_nodes(
    context: Context, data: dict[str, Any], bag: Path, scenario_dir: Path
) -> list[Node]:
    """The nodes of a scenario in this process, with the run plan's parameters (recorder first)."""
    roles = [r for r in roles_of(data) if r in NODE_CLASSES]
    extra = handshake_overrides(data, roles, bag, scenario_dir)
    return [
        NODE_CLASSES[role](
            context=context,
            parameter_overrides=[
                Parameter(k, value=v)
                for k, v in {**node_params(data, role), **extra.get(role, {})}.items()
            ],
        )
        for role in roles
    ]


def spin_until(
    ctx: Context, nodes: list[Node], cond: Callable[[], bool], timeout_s: float = 20.0
) -> None:
    """Spin ``nodes`` on one executor until ``cond()``; fails after ``timeout_s``."""
    ex = SingleThreadedExecutor(context=ctx)
    for n in nodes:
        ex.add_node(n)
    deadline = time.monotonic() + timeout_s
    try:
        while not cond():
            assert time.monotonic() < deadline, "timed out"
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.shutdown()
