"""The cross-key checks of a role's topics and sources (plant, feedback, recorder).

Split from :mod:`servo_axis.params.factories`, whose ``check_consistency``
calls them with a role's typed values: what a key must satisfy with the
mode or with the other topic lists of its role, named by key
(:class:`~servo_axis.core.errors.ParameterFileError`), before anything moves.
"""

from __future__ import annotations

from servo_axis.core.errors import ParameterFileError
from servo_axis.params.names import namespace_problem
from servo_axis.params.values import FeedbackValues, PlantValues, RecorderValues


def check_command_source(values: PlantValues) -> None:
    """``command_source: drive_setpoint`` only in realtime (a set-point has no step to wait for).

    Raises
    ------
    ParameterFileError
        Naming ``command_source`` and ``mode``.
    """
    if values.command_source == "drive_setpoint" and values.mode == "lockstep":
        raise ParameterFileError(
            "parameter 'command_source': drive_setpoint needs mode: realtime (a drive's "
            "set-point carries no step of the k T_u grid, which lockstep waits for; "
            "got mode: lockstep)"
        )


def check_forward_topic(values: FeedbackValues) -> None:
    """``forward_commands_topic``: empty, or a ROS topic name (absolute or relative).

    Raises
    ------
    ParameterFileError
        Naming ``forward_commands_topic`` and what rcl would refuse.
    """
    topic = values.forward_commands_topic
    if not topic:
        return
    problem = namespace_problem(topic if topic.startswith("/") else f"/{topic}")
    if problem is not None or topic in ("/", "~"):
        raise ParameterFileError(
            f"parameter 'forward_commands_topic': {topic!r} is not a ROS topic name: "
            f"{problem or 'no name'}"
        )


def check_recorder_topics(values: RecorderValues) -> None:
    """One type per topic; the latched and counted topics among them; a period per
    final topic; a split size of 0 or at least the MCAP minimum."""
    topics, types = values.topics, values.types
    if len(topics) != len(types) or not topics:
        raise ParameterFileError(
            f"parameter 'types': expected one type per topic ({len(topics)} topics), "
            f"got {len(types)}"
        )
    for key, listed in (
        ("latched_topics", values.latched_topics),
        ("counted_topics", values.counted_topics),
    ):
        extra = set(listed) - set(topics)
        if extra:
            raise ParameterFileError(f"parameter '{key}': {sorted(extra)} not in 'topics'")
    from servo_axis.recording.reader import MIN_SPLIT_SIZE_BYTES

    if 0 < values.max_bag_size_bytes < MIN_SPLIT_SIZE_BYTES:
        raise ParameterFileError(
            f"parameter 'max_bag_size_bytes': expected 0 (no split) or >= "
            f"{MIN_SPLIT_SIZE_BYTES} (bytes), got {values.max_bag_size_bytes}"
        )
    finals, every = values.final_topics, values.final_every_steps
    if len(finals) != len(every):
        raise ParameterFileError(
            f"parameter 'final_every_steps': expected one period per final topic "
            f"({len(finals)} topics), got {len(every)}"
        )
