"""``identifier/estimates`` (paper 003): exact round trips and refusal of bad messages by name."""

from __future__ import annotations

import itertools
import math
import re
from typing import Any

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64MultiArray

from servo_axis.core.errors import SignalError
from servo_axis.wire import messages as msgs
from servo_axis.wire.layouts import EstimateData, check_estimate_values
from servo_axis.wire.messages import ESTIMATE_LABELS

FLAG_LABELS = ESTIMATE_LABELS[7:]


def estimate(**change: Any) -> EstimateData:
    base: dict[str, Any] = {
        "step": 1239,
        "applies_from_step": 1250,
        "inertia_kgm2": 0.1 + 0.2,  # 0.30000000000000004: every bit must survive
        "damping_Nms_per_rad": 1.0 / 3.0,
        "unbalance_Nm": math.pi / 10.0,
        "coulomb_Nm": 5e-324,  # the smallest subnormal
        "kappa": 1.2345678901234567e-7,
        "updated": (True, False, True, False),
    }
    base.update(change)
    return EstimateData(**base)


def wire(data: EstimateData) -> Float64MultiArray:
    """Encode, serialise, deserialise: what a subscriber gets."""
    msg = msgs.estimate_to_msg(data)
    out: Float64MultiArray = deserialize_message(serialize_message(msg), Float64MultiArray)
    return out


def good_values() -> list[float]:
    values: list[float] = estimate().values()
    return values


@pytest.mark.parametrize("flags", list(itertools.product((False, True), repeat=4)))
def test_round_trip_through_cdr_is_exact_for_every_flag_combination(
    flags: tuple[bool, bool, bool, bool],
) -> None:
    sent = estimate(updated=flags)
    got = msgs.estimate_from_msg(wire(sent))
    assert got == sent
    # Bit for bit, not merely ==: the floats are the same objects' values.
    for name in ("inertia_kgm2", "damping_Nms_per_rad", "unbalance_Nm", "coulomb_Nm", "kappa"):
        assert getattr(got, name).hex() == getattr(sent, name).hex()
    assert got.updated == flags and all(type(f) is bool for f in got.updated)
    assert type(got.step) is int and type(got.applies_from_step) is int


def test_round_trip_of_large_steps_and_zero_parameters() -> None:
    sent = estimate(
        step=2**40 - 1,
        applies_from_step=2**40 + 10,
        damping_Nms_per_rad=0.0,
        unbalance_Nm=0.0,
        coulomb_Nm=0.0,
        kappa=0.0,
    )
    assert msgs.estimate_from_msg(wire(sent)) == sent


def test_the_message_carries_the_labels_in_order() -> None:
    msg = wire(estimate())
    assert [d.label for d in msg.layout.dim] == list(ESTIMATE_LABELS)
    assert [(d.size, d.stride) for d in msg.layout.dim] == [(1, 1)] * 11
    assert list(msg.data) == estimate().values()


def test_values_order_is_the_labels_order() -> None:
    e = estimate()
    by_label = dict(zip(ESTIMATE_LABELS, e.values(), strict=True))
    for label in ESTIMATE_LABELS[:7]:
        assert by_label[label] == float(getattr(e, label)), label
    for label, flag in zip(FLAG_LABELS, e.updated, strict=True):
        assert by_label[label] == (1.0 if flag else 0.0), label
    assert FLAG_LABELS == (
        "updated_inertia",
        "updated_damping",
        "updated_unbalance",
        "updated_coulomb",
    )
    # One flag at a time lands on its own label.
    for i, label in enumerate(FLAG_LABELS):
        flags = tuple(j == i for j in range(4))
        values = dict(zip(ESTIMATE_LABELS, estimate(updated=flags).values(), strict=True))
        assert [values[lb] for lb in FLAG_LABELS] == [float(f) for f in flags]
        assert values[label] == 1.0


# -- refusals on the message path ---------------------------------------------------


@pytest.mark.parametrize("index", range(len(ESTIMATE_LABELS)))
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_values_are_refused_on_the_message_path(index: int, bad: float) -> None:
    msg = wire(estimate())
    data = list(msg.data)
    data[index] = bad
    msg.data = data
    with pytest.raises(SignalError, match=rf"data\[{index}\]: expected a finite number"):
        msgs.estimate_from_msg(msg)


def test_the_encoder_refuses_to_put_nan_on_the_wire() -> None:
    with pytest.raises(SignalError, match=r"data\[6\]"):
        msgs.estimate_to_msg(estimate(kappa=math.nan))


@pytest.mark.parametrize("count", [0, 10, 12])
def test_wrong_count_is_refused_on_the_message_path(count: int) -> None:
    msg = wire(estimate())
    msg.data = (good_values() * 2)[:count]
    with pytest.raises(SignalError, match=r"data: expected 11 values"):
        msgs.estimate_from_msg(msg)


def test_wrong_labels_are_refused() -> None:
    swapped = list(ESTIMATE_LABELS)
    swapped[2], swapped[3] = swapped[3], swapped[2]  # J and D swapped
    for labels in (swapped, [*ESTIMATE_LABELS[:-1], "updated_friction"]):
        msg = msgs.labelled_array(labels, good_values())
        with pytest.raises(SignalError, match=r"layout\.dim: expected one dimension per field"):
            msgs.estimate_from_msg(msg)
    # The labels of before (one dimension listing the fields) are no estimate either.
    msg = wire(estimate())
    msg.layout.dim = [msg.layout.dim[0]]
    msg.layout.dim[0].label = ",".join(ESTIMATE_LABELS)
    msg.layout.dim[0].size = msg.layout.dim[0].stride = 11
    with pytest.raises(SignalError, match=r"layout\.dim"):
        msgs.estimate_from_msg(msg)


def test_a_dimension_size_that_disagrees_with_the_data_is_refused() -> None:
    msg = wire(estimate())
    msg.layout.dim[0].size = 10
    with pytest.raises(SignalError, match=r"layout.dim 'step': expected size 1, got 10"):
        msgs.estimate_from_msg(msg)
    msg = wire(estimate())
    msg.data = list(msg.data)[:10]
    with pytest.raises(SignalError, match=r"data: expected 11 values"):
        msgs.estimate_from_msg(msg)


# -- refusals of check_estimate_values -----------------------------------------------


@pytest.mark.parametrize("count", [0, 7, 10, 12, 22])
def test_check_refuses_too_short_or_too_long(count: int) -> None:
    values = (good_values() * 2)[:count]
    with pytest.raises(SignalError, match=rf"data: expected 11 values, got {count}"):
        check_estimate_values(values)


@pytest.mark.parametrize(
    ("index", "value", "match"),
    [
        (0, 1239.5, r"^step: expected a whole number >= 0"),
        (0, -10.0, r"^step: expected a whole number >= 0"),
        (0, -1.0, r"^step: expected a whole number >= 0"),
        (1, 1250.25, r"^applies_from_step: expected a whole number after step 1239"),
        (1, 1239.0, r"^applies_from_step: expected a whole number after step 1239"),  # ==
        (1, 1238.0, r"^applies_from_step: expected a whole number after step 1239"),  # <
        (1, 0.0, r"^applies_from_step: expected a whole number after step 1239"),
        (2, 0.0, r"^inertia_kgm2: expected a value > 0"),
        (2, -1e-4, r"^inertia_kgm2: expected a value > 0"),
        (2, -5e-324, r"^inertia_kgm2: expected a value > 0"),
        (3, -1e-12, r"^damping_Nms_per_rad: expected a value >= 0"),
        (4, -0.3, r"^unbalance_Nm: expected a value >= 0"),
        (5, -5e-324, r"^coulomb_Nm: expected a value >= 0"),
        (7, 0.5, r"^updated_inertia: expected 0 or 1, got 0.5"),
        (8, 2.0, r"^updated_damping: expected 0 or 1, got 2.0"),
        (9, -1.0, r"^updated_unbalance: expected 0 or 1"),
        (10, 0.5, r"^updated_coulomb: expected 0 or 1, got 0.5"),
        (10, 2.0, r"^updated_coulomb: expected 0 or 1, got 2.0"),
    ],
)
def test_check_refuses_each_bad_field_by_name(index: int, value: float, match: str) -> None:
    values = good_values()
    values[index] = value
    with pytest.raises(SignalError, match=match):
        check_estimate_values(values)
    # The same values refused the same way when they arrive as a message.
    msg = wire(estimate())
    msg.data = values
    with pytest.raises(SignalError, match=match):
        msgs.estimate_from_msg(msg)


def test_check_accepts_the_edges() -> None:
    values = good_values()
    values[0], values[1] = 0.0, 1.0  # step 0, applies from the very next step
    values[3] = values[4] = values[5] = 0.0
    values[7:] = [0.0, 1.0, 0.0, 1.0]
    got = check_estimate_values(values)
    assert (got.step, got.applies_from_step) == (0, 1)
    assert (got.damping_Nms_per_rad, got.unbalance_Nm, got.coulomb_Nm) == (0.0, 0.0, 0.0)
    assert got.updated == (False, True, False, True)
    assert got.values() == values


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("index", [0, 1, 4, 6])
def test_check_refuses_non_finite_values_by_name(bad: float, index: int) -> None:
    """A memory file's last estimate goes through the check without a message:
    a NaN step must be a SignalError, not a crash converting it to int."""
    values = [9.0, 20.0, 5e-3, 1.3e-2, 0.3, 0.02, 1e-3, 1.0, 1.0, 1.0, 1.0]
    values[index] = bad
    with pytest.raises(SignalError, match=re.escape(f"data[{index}]")):
        check_estimate_values(values)
