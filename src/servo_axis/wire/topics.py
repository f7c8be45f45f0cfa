"""The one table of topics: name, type, QoS, producer, consumers, recorded, counted.

The nodes take their QoS from it, the recorder its default topic list, and
the runner its handshakes (how many subscribers each publisher waits for)
and the flow-control topics. Names are relative to the axis namespace except
``/clock``. Nothing here imports rclpy: QoS is named (``stream``,
``latched``) and :mod:`servo_axis.nodes.base` makes the profiles.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

JOINT_STATE = "sensor_msgs/msg/JointState"
FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
CLOCK = "rosgraph_msgs/msg/Clock"

#: QoS names: reliable, transient-local, keep-last 2000 (per-sample streams, deep
#: enough for the preview window and the recorder's lag); reliable,
#: transient-local, depth 1 (a late subscriber gets the last message).
QOS_NAMES = ("stream", "latched")


@dataclass(frozen=True)
class Topic:
    """One topic of an axis.

    Attributes
    ----------
    name : str
        Relative to the axis namespace (``/clock`` is absolute).
    type_name : str
        ``pkg/msg/Type``.
    qos : str
        ``stream`` or ``latched`` (:data:`QOS_NAMES`).
    producer : str
        The role that publishes it.
    consumers : tuple of str
        The roles that subscribe to it (the recorder aside).
    recorded : bool
        Recorded by default (when its producer runs).
    counted : bool
        Counted by the recorder's flow-control acknowledgement: the plant
        never runs more than ``max_recorder_lag_steps`` ahead of the
        smallest count of these.
    meaning : str
        One line for the topic table (docs/reference/topics.md).
    enabled_by : str
        The producer's bool parameter that switches the topic on ("" when
        it always runs): a switched-off topic is neither recorded nor counted.
    """

    name: str
    type_name: str
    qos: str
    producer: str
    consumers: tuple[str, ...]
    recorded: bool
    counted: bool
    meaning: str
    enabled_by: str = ""


TOPICS: tuple[Topic, ...] = (
    Topic("state", JOINT_STATE, "stream", "plant", ("feedback", "learning", "identifier"), True,
          True,
          "sensor readings and true motion at every sample"),
    Topic("command", JOINT_STATE, "stream", "feedback", ("plant", "identifier"), True, True,
          "motor torque reference K_T i (N m), the answer to state[k]"),
    Topic("reference", JOINT_STATE, "stream", "feedforward", ("feedback",), True, True,
          "feedback reference and feedforward torque (N m), published ahead"),
    Topic("/clock", CLOCK, "stream", "plant", ("feedback", "feedforward", "learning"), True, False,
          "simulation time every clock_every_steps samples"),
    Topic("fault", FLOAT64_MULTI_ARRAY, "latched", "feedback", (), True, False,
          "the trip of the feedback loop"),
    Topic("plant/status", FLOAT64_MULTI_ARRAY, "stream", "plant", ("feedforward",), True, False,
          "progress and counters of the plant"),
    Topic("learning/correction", JOINT_STATE, "stream", "learning", ("feedforward",), True, False,
          "the learned correction of the next cycle"),
    Topic("learning/input_correction", JOINT_STATE, "stream", "learning", ("feedforward",), True,
          False, "the learned feedforward torque (N m) of the next trial (input-side laws)"),
    Topic("learning/cycle_stats", FLOAT64_MULTI_ARRAY, "stream", "learning", (), True, False,
          "tracking error statistics per learning cycle or trial"),
    Topic("learning/parameters", FLOAT64_MULTI_ARRAY, "stream", "learning", (), True, False,
          "plant parameters a projection-based law identified, per trial"),
    Topic("learning/friction_table", FLOAT64_MULTI_ARRAY, "stream", "learning", (), True, False,
          "the data-based friction table a law built, per trial"),
    Topic("identifier/estimates", FLOAT64_MULTI_ARRAY, "stream", "identifier", ("feedforward",),
          True, False, "online estimates J, D, U, C, the PE index and the updates, per RLS period"),
    Topic("deformation", FLOAT64_MULTI_ARRAY, "stream", "feedback", (), True, True,
          "deformation ratio d_r of 004 eqs. (5)-(7) and its increments, every sample",
          enabled_by="deformation.enabled"),
    Topic("recorder/progress", FLOAT64_MULTI_ARRAY, "latched", "recorder", ("plant",), False, False,
          "steps fully recorded (flow control)"),
)  # fmt: skip

BY_NAME: dict[str, Topic] = {t.name: t for t in TOPICS}


def topic(name: str) -> Topic:
    """The table's entry of ``name`` (KeyError naming it if there is none)."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"topic {name!r} is not in the topic table") from None


def recorded_topics(roles: Iterable[str], enabled: Iterable[str] = ()) -> list[Topic]:
    """The topics recorded by default in a run of ``roles``, in table order.

    A topic with an ``enabled_by`` switch is among them only when its name is
    in ``enabled`` (the switch is on in its producer's section).
    """
    present = set(roles)
    on = set(enabled)
    return [
        t
        for t in TOPICS
        if t.recorded and t.producer in present and (not t.enabled_by or t.name in on)
    ]


def subscriber_count(name: str, roles: Iterable[str], recorded: Iterable[str] = ()) -> int:
    """How many subscribers the run of ``roles`` has on ``name`` (the recorder's included)."""
    present = set(roles)
    entry = topic(name)
    count = sum(1 for role in entry.consumers if role in present)
    return count + int("recorder" in present and name in set(recorded))
