"""All nodes of one axis in one process on one executor (composed mode).

``python -m servo_axis.nodes.composed plant feedback feedforward recorder --ros-args --params-file <scenario>.yaml``

The container is the one module that imports the node modules. The node
classes are the same as in separate processes, so the recorded
payloads are identical. The process ends when the plant has finished the run
(and, with flow control, the recorder has everything).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from rclpy.node import Node

from servo_axis.nodes.feedback import FeedbackNode
from servo_axis.nodes.feedforward import FeedforwardNode
from servo_axis.nodes.identifier import IdentifierNode
from servo_axis.nodes.learning import LearningNode
from servo_axis.nodes.plant import PlantNode
from servo_axis.nodes.recorder import RecorderNode
from servo_axis.nodes.runtime import run_main

ROLES = ("plant", "feedback", "feedforward", "learning", "identifier", "recorder")


def factories(roles: list[str]) -> list[Callable[[], Node]]:
    """Node constructors for ``roles``, in a fixed order (recorder first, plant last)."""
    table: dict[str, Callable[[], Node]] = {
        "recorder": RecorderNode,
        "learning": LearningNode,
        "identifier": IdentifierNode,
        "feedforward": FeedforwardNode,
        "feedback": FeedbackNode,
        "plant": PlantNode,
    }
    unknown = [r for r in roles if r not in table]
    if unknown:
        raise SystemExit(
            f"composed: unknown node role(s) {unknown}; expected some of {list(ROLES)}"
        )
    return [table[r] for r in table if r in roles]


def main(argv: list[str] | None = None) -> int:
    """Entry point: role names, then ROS arguments."""
    argv = list(sys.argv if argv is None else argv)
    split = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    roles = argv[1:split]
    ros_args = [argv[0], *argv[split:]]

    def plant_done(nodes: list[Node]) -> bool:
        return any(getattr(n, "done", False) for n in nodes)

    return run_main("composed", factories(roles), ros_args, done=plant_done)


if __name__ == "__main__":
    raise SystemExit(main())
