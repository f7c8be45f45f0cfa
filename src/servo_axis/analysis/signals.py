"""Recorded signals of a run, per control step, read from its bag without ROS.

The bag is read as raw CDR payloads (:func:`servo_axis.recording.reader.read_raw`)
and the four topics the analysis needs are decoded with
:mod:`servo_axis.wire.cdr`, by their leaf name (so ``/x/state`` of a
namespaced axis is ``state``):

* ``state`` (JointState): ``position`` = [encoder angle (rad), scale (m)];
* ``reference`` (JointState): ``position[0]`` = feedback reference (rad),
  ``effort[0]`` = feedforward current (A);
* ``command`` (JointState): ``effort[0]`` = current reference (A);
* ``fault`` (Float64MultiArray): ``data`` = [step, code, value].

The step of a JointState is its ``header.stamp`` divided by the control
period. Every other topic is only counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from servo_axis.analysis.metrics import to_plain
from servo_axis.core.feedback.loop import Fault
from servo_axis.core.feedback.output import controlled_output
from servo_axis.params.factories import build_generator, feedforward_values, node_values
from servo_axis.recording.reader import read_raw
from servo_axis.wire.cdr import decode_float64_multi_array, decode_joint_state

#: Name of each fault code of the ``fault`` topic (``following_error``, ...).
FAULT_NAMES: dict[int, str] = {int(f): f.name.lower() for f in Fault}


@dataclass(frozen=True)
class FaultRecord:
    """One message of the ``fault`` topic.

    Attributes
    ----------
    step : int
        Control sample at which the loop tripped.
    code : int
        :class:`~servo_axis.core.feedback.loop.Fault` code.
    name : str
        The code's name (``following_error``, ...), ``"?"`` for an unknown code.
    value : float
        The value that tripped (m, A or s, by code).
    """

    step: int
    code: int
    name: str
    value: float

    def to_dict(self) -> dict[str, Any]:
        """The record as in ``summary.json`` (keys step, code, name, value)."""
        plain: dict[str, Any] = to_plain(self)
        return plain

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FaultRecord:
        """Inverse of :meth:`to_dict`."""
        return cls(step=data["step"], code=data["code"], name=data["name"], value=data["value"])


@dataclass(frozen=True, eq=False)
class Signals:
    """Signals of a run per recorded control step.

    Attributes
    ----------
    step : ndarray of int
        Control samples that have both a ``state`` and a ``reference``
        message, ascending.
    encoder_rad, scale_m : ndarray of float
        Sensor readings at those steps (rad, m).
    reference_rad, feedforward_A : ndarray of float
        Feedback reference (rad) and feedforward current (A).
    command_A : ndarray of float
        Current reference (A); NaN at a step without a ``command`` message.
    faults : list of FaultRecord
        The ``fault`` messages, in log-time order.
    counts : dict
        Messages per topic (every topic of the bag, in order of first message).
    """

    step: NDArray[np.int_]
    encoder_rad: NDArray[np.float64]
    scale_m: NDArray[np.float64]
    reference_rad: NDArray[np.float64]
    feedforward_A: NDArray[np.float64]
    command_A: NDArray[np.float64]
    faults: list[FaultRecord] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)


def load_signals(bag_dir: Path, period_s: float) -> Signals:
    """Arrays per step from a bag: state, reference and command, plus faults and counts.

    Parameters
    ----------
    bag_dir : Path
        The bag directory.
    period_s : float
        Control period ``T_u``, s: a message stamped ``t`` is step ``t // T_u``.

    Returns
    -------
    Signals
        The steps common to ``state`` and ``reference``, sorted, with the
        signals at those steps.
    """
    period_ns = round(period_s * 1e9)
    state: dict[int, tuple[float, float]] = {}
    ref: dict[int, tuple[float, float]] = {}
    cmd: dict[int, float] = {}
    faults: list[FaultRecord] = []
    counts: dict[str, int] = {}
    for m in read_raw(Path(bag_dir)):
        counts[m.topic] = counts.get(m.topic, 0) + 1
        leaf = m.topic.rsplit("/", 1)[-1]
        if leaf == "state":
            js = decode_joint_state(m.data)
            state[js.stamp_ns // period_ns] = (js.position[0], js.position[1])
        elif leaf == "reference":
            js = decode_joint_state(m.data)
            ref[js.stamp_ns // period_ns] = (js.position[0], js.effort[0])
        elif leaf == "command":
            js = decode_joint_state(m.data)
            cmd[js.stamp_ns // period_ns] = js.effort[0]
        elif leaf == "fault":
            step, code, value = decode_float64_multi_array(m.data).data
            faults.append(
                FaultRecord(
                    step=int(step),
                    code=int(code),
                    name=FAULT_NAMES.get(int(code), "?"),
                    value=value,
                )
            )
    steps = sorted(set(state) & set(ref))
    return Signals(
        step=np.array(steps, dtype=int),
        encoder_rad=np.array([state[s][0] for s in steps]),
        scale_m=np.array([state[s][1] for s in steps]),
        reference_rad=np.array([ref[s][0] for s in steps]),
        feedforward_A=np.array([ref[s][1] for s in steps]),
        command_A=np.array([cmd.get(s, math.nan) for s in steps]),
        faults=faults,
        counts=counts,
    )


def learning_enabled(scenario: dict[str, Any]) -> bool:
    """True when the scenario's feedforward generator applies learning corrections."""
    return "feedforward" in scenario and bool(
        node_values(scenario, "feedforward")["learning.enabled"]
    )


def tracking(
    scenario: dict[str, Any], scenario_path: Path, sig: Signals
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Target (rad) and controlled output ``y`` (rad) per recorded step.

    ``y`` is the feedback's sensor reading in rad of motor angle
    (:func:`~servo_axis.core.feedback.output.controlled_output`). The target
    is the reference the feedback got, except with learning: then it is the
    original target without the learned correction (the ``r`` of 000 eq. (9)),
    recomputed with the same generator.
    """
    fb = node_values(scenario, "feedback")
    y = controlled_output(
        fb["sensor"],
        encoder_rad=sig.encoder_rad,
        scale_m=sig.scale_m,
        lead_m_per_rad=fb["lead_m_per_rad"],
    )
    target = sig.reference_rad
    if learning_enabled(scenario) and sig.step.size:
        values = feedforward_values(scenario, scenario_path)
        values["learning.enabled"] = False
        rows = build_generator(values).samples(0, int(sig.step.max()) + 1)
        target = np.array([rows[k][0] for k in sig.step])
    return target, y
