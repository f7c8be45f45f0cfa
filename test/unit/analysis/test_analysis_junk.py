"""Junk a recorder wrote into a bag changes no figure: the analysis keeps validated samples only.

A clean lockstep bag of an axis ``x`` (state, reference, command, learning
corrections and stats, plant status, clock, a fault) and the same bag with
junk interleaved on every topic (NaN, inf, short and empty arrays, an empty
payload, wrong names and labels, past, ahead and off-grid stamps, and a
wrong-named copy of the next sample arriving before the real one) give the
same validated streams, byte for byte, and the same signals and summary.
CDR payloads are made with rosbags (no rclpy).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.analysis.signals import (
    FaultRecord,
    StreamRules,
    load_signals,
    read_streams,
    table_name,
)
from servo_axis.analysis.summary import summarise
from servo_axis.core.errors import SignalError
from servo_axis.params.scenario import load_scenario
from servo_axis.recording.writer import BagWriter
from servo_axis.wire import layouts

JOINT_STATE = "sensor_msgs/msg/JointState"
MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
CLOCK = "rosgraph_msgs/msg/Clock"

PERIOD_S = 0.002
PERIOD_NS = 2_000_000
LEAD = 0.002
N = 200  # 4 cycles of 50 steps (0.1 s at 2 ms)
CYCLE = 50
RATIO = 2
TOPICS = {
    "/x/state": JOINT_STATE,
    "/x/reference": JOINT_STATE,
    "/x/command": JOINT_STATE,
    "/x/learning/correction": JOINT_STATE,
    "/x/learning/cycle_stats": MULTI_ARRAY,
    "/x/plant/status": MULTI_ARRAY,
    "/x/fault": MULTI_ARRAY,
    "/x/clock": CLOCK,
}
RULES = StreamRules(period_ns=PERIOD_NS, axis="x", steps=N, cycle_steps=CYCLE)


class Cdr:
    """CDR payloads made with rosbags' typestore; any stamp (ns), names and arrays."""

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ts = get_typestore(Stores.ROS2_JAZZY)
        self.t = self.ts.types

    def _stamp(self, ns: int) -> Any:
        return self.t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)

    def joint_state(self, ns: int, names: list[str], **fields: list[float]) -> bytes:
        header = self.t["std_msgs/msg/Header"](stamp=self._stamp(ns), frame_id="")
        msg = self.t[JOINT_STATE](
            header=header,
            name=names,
            **{
                f: np.array(fields.get(f, []), dtype=np.float64)
                for f in ("position", "velocity", "effort")
            },
        )
        return bytes(self.ts.serialize_cdr(msg, JOINT_STATE))

    def multi_array(self, labels: tuple[str, ...] | str, data: list[float]) -> bytes:
        """One dimension per field of size 1 (the project's layout); a str: one dimension."""
        if isinstance(labels, str):
            fields = [(labels, len(data))]
        else:
            fields = [(label, 1) for label in labels]
        dims = [
            self.t["std_msgs/msg/MultiArrayDimension"](label=label, size=size, stride=size)
            for label, size in fields
        ]
        layout = self.t["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
        msg = self.t[MULTI_ARRAY](layout=layout, data=np.array(data, dtype=np.float64))
        return bytes(self.ts.serialize_cdr(msg, MULTI_ARRAY))

    def clock(self, ns: int) -> bytes:
        return bytes(self.ts.serialize_cdr(self.t[CLOCK](clock=self._stamp(ns)), CLOCK))


CDR = Cdr()
MOTOR = ["x_motor"]
BOTH = ["x_motor", "x_table"]


def value(k: int, i: int = 0) -> float:
    return math.sin(0.05 * k + i) * 10 ** (-i)


def state(k: int, ns: int | None = None, names: list[str] = BOTH, **over: Any) -> bytes:
    fields = {
        "position": [value(k), LEAD * value(k) + 1e-6 * value(k, 1)],
        "velocity": [value(k, 2), value(k, 3)],
        "effort": [value(k, 4), value(k, 5)],
    }
    fields.update(over)
    return CDR.joint_state(k * PERIOD_NS if ns is None else ns, names, **fields)


def reference(k: int, ns: int | None = None, names: list[str] = MOTOR, **over: Any) -> bytes:
    fields = {"position": [value(k + 1)], "velocity": [value(k, 1)], "effort": [0.1 * value(k)]}
    fields.update(over)
    return CDR.joint_state(k * PERIOD_NS if ns is None else ns, names, **fields)


def command(k: int, ns: int | None = None, names: list[str] = MOTOR, **over: Any) -> bytes:
    fields = {"effort": [-0.2 * value(k)]}
    fields.update(over)
    return CDR.joint_state(k * PERIOD_NS if ns is None else ns, names, **fields)


def correction(k: int, ns: int | None = None, names: list[str] = MOTOR, **over: Any) -> bytes:
    fields = {"position": [1e-4 * value(k)], "velocity": [1e-3 * value(k)]}
    fields.update(over)
    return CDR.joint_state(k * PERIOD_NS if ns is None else ns, names, **fields)


def clean_messages() -> list[tuple[str, bytes]]:
    """The messages of a clean run, in recording order."""
    out: list[tuple[str, bytes]] = []
    for k in range(N):
        if k % 10 == 0:
            out.append(("/x/clock", CDR.clock(k * PERIOD_NS)))
        out.append(("/x/reference", reference(k)))
        out.append(("/x/state", state(k)))
        if k % 50 == 0:
            status = [float(k), 0.0, 0.0, 0.0]
            out.append(("/x/plant/status", CDR.multi_array(layouts.STATUS.labels, status)))
        out.append(("/x/command", command(k)))
        if k == 120:
            out.append(("/x/fault", CDR.multi_array(layouts.FAULT.labels, [120.0, 1.0, 2.5e-3])))
        if k % CYCLE == CYCLE - 1 and k + 1 < N:  # end of a cycle: the next one's corrections
            cycle = k // CYCLE + 1
            for j in range(k + 1, k + 1 + CYCLE, RATIO):
                out.append(("/x/learning/correction", correction(j)))
            stats = [float(cycle), 1e-6 * cycle, 3e-6 * cycle, float(cycle - 1)]
            out.append(
                ("/x/learning/cycle_stats", CDR.multi_array(layouts.CYCLE_STATS.labels, stats))
            )
    return out


def junk_for(topic: str, k: int) -> list[bytes]:
    """Every kind of junk for ``topic`` around step ``k`` (a real step of the run)."""
    nan, inf = math.nan, math.inf
    if topic in ("/x/state", "/x/reference", "/x/command", "/x/learning/correction"):
        make = {
            "/x/state": state,
            "/x/reference": reference,
            "/x/command": command,
            "/x/learning/correction": correction,
        }[topic]
        nxt = k + (RATIO if topic == "/x/learning/correction" else 1)
        names = BOTH if topic == "/x/state" else MOTOR
        wide = [0.0] * (len(names) + 1)
        used = {
            "/x/state": "position",
            "/x/reference": "effort",
            "/x/command": "effort",
            "/x/learning/correction": "velocity",
        }[topic]
        return [
            make(nxt, **{used: [nan] * len(names)}),  # NaN at the next step
            make(nxt, **{used: [inf] + [0.0] * (len(names) - 1)}),  # inf
            make(nxt, **{used: [-inf] * len(names)}),
            make(nxt, **{used: []}),  # short: no value
            make(nxt, **{used: wide}),  # long
            CDR.joint_state(nxt * PERIOD_NS, []),  # empty message
            make(nxt, names=[n.replace("x_", "y_") for n in names]),  # wrong names
            make(nxt, names=names[::-1] if len(names) > 1 else ["x_table"]),
            make(0, position=[5.0] * len(names)),  # past: step 0 again
            make(max(k - 5, 0), position=[5.0] * len(names)),  # past: k - 5
            make(k),  # the same step again
            make(k + 1000),  # ahead
            make(0, ns=10**18),  # 1e9 s ahead
            make(0, ns=nxt * PERIOD_NS + PERIOD_NS // 2),  # off the grid
            make(0, ns=-PERIOD_NS),  # negative
            b"\x00\x01\x00\x00\x01\x00",  # truncated payload
            b"",
        ]
    if topic == "/x/clock":
        return [
            CDR.clock((k - 10) * PERIOD_NS),  # past (negative before the first)
            CDR.clock((k + 1) * PERIOD_NS),  # off the clock's stride
            CDR.clock((k + 1000) * PERIOD_NS),
            CDR.clock(10**18),
            CDR.clock(k * PERIOD_NS + 7),
            b"\x00\x01",
        ]
    labels, good = {
        "/x/plant/status": (layouts.STATUS.labels, [float(k + 2), 0.0, 0.0, 0.0]),  # off the stride
        "/x/learning/cycle_stats": (
            layouts.CYCLE_STATS.labels,
            [1.0, 1e-6, 1e-6, 5.0],
        ),  # learned > cycle
        "/x/fault": (layouts.FAULT.labels, [float(k), 9.0, 1.0]),
    }[topic]
    wrong = ",".join(labels).replace("_", "-")
    return [
        CDR.multi_array(labels, [nan, *good[1:]]),
        CDR.multi_array(labels, [*good[:-1], inf]),
        CDR.multi_array(labels, good[:-1]),  # short
        CDR.multi_array(labels, []),  # empty
        CDR.multi_array(wrong, good),  # wrong labels
        CDR.multi_array("", good),
        CDR.multi_array(labels, [-5.0, *good[1:]]),  # negative (past)
        CDR.multi_array(labels, [1e9, *good[1:]]),  # future
        CDR.multi_array(labels, [good[0] + 0.5, *good[1:]]),  # not a whole number
        CDR.multi_array(labels, good),  # a plausible value at a wrong place / code
        b"\x00\x01\x00\x00",
    ]


def junk_messages(clean: list[tuple[str, bytes]]) -> tuple[list[tuple[str, bytes]], dict[str, int]]:
    """``clean`` with junk of every kind before and after some of its messages.

    Junk that comes first is built around the step before the real one, so
    that its "next step" kinds race the real message.
    """
    out: list[tuple[str, bytes]] = []
    junk: dict[str, int] = {}
    seen: dict[str, int] = {}
    for topic, data in clean:
        n = seen[topic] = seen.get(topic, 0) + 1
        step = read_step(topic, data)
        before = step - (RATIO if topic == "/x/learning/correction" else 1)
        if n % 7 == 3:  # junk first, then the real message
            for item in junk_for(topic, step if topic == "/x/clock" else before):
                out.append((topic, item))
                junk[topic] = junk.get(topic, 0) + 1
        out.append((topic, data))
        if n % 5 == 1:
            for item in junk_for(topic, step):
                out.append((topic, item))
                junk[topic] = junk.get(topic, 0) + 1
    return out, junk


def read_step(topic: str, data: bytes) -> int:
    """The step (cycle) a clean message carries."""
    from servo_axis.wire import cdr

    if TOPICS[topic] == JOINT_STATE:
        return cdr.decode_joint_state(data).stamp_ns // PERIOD_NS
    if TOPICS[topic] == CLOCK:
        return cdr.decode_clock(data).stamp_ns // PERIOD_NS
    return int(cdr.decode_float64_multi_array(data).data[0])


def sim_log_time(topic: str, data: bytes, now: list[int]) -> int:
    """The log time the recorder gives a message: its stamp (simulation time).

    As the recorder's timeline does: a JointState or Clock is logged at its
    stamp if that is in ``[0, now + 2.5 s]``, anything else at ``now``, the
    latest stamp of ``state``, ``command`` or ``/clock`` (moved by at most 1 s).
    So a junk message stamped in the past is logged before the real message
    it was recorded after: the log times are not the recording order.
    """
    from servo_axis.wire import cdr

    try:
        if TOPICS[topic] == JOINT_STATE:
            stamp = cdr.decode_joint_state(data).stamp_ns
        elif TOPICS[topic] == CLOCK:
            stamp = cdr.decode_clock(data).stamp_ns
        else:
            return now[0]
    except SignalError:
        return now[0]
    if topic in ("/x/state", "/x/command", "/x/clock") and now[0] < stamp <= now[0] + 10**9:
        now[0] = stamp
    return stamp if 0 <= stamp <= now[0] + 2_500_000_000 else now[0]


def write(bag_dir: Path, messages: list[tuple[str, bytes]]) -> None:
    now = [0]
    with BagWriter(bag_dir) as bag:
        for topic, type_name in TOPICS.items():
            bag.add_topic(topic, type_name)
        for topic, data in messages:
            bag.write(topic, data, log_time_ns=sim_log_time(topic, data, now))


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, int]]:
    root = tmp_path_factory.mktemp("junk")
    clean = clean_messages()
    junky, junk = junk_messages(clean)
    write(root / "clean" / "bag", clean)
    write(root / "junk" / "bag", junky)
    return root / "clean", root / "junk", junk


def test_junk_changes_no_validated_stream(bags: tuple[Path, Path, dict[str, int]]) -> None:
    clean_run, junk_run, junk = bags
    clean = read_streams(clean_run / "bag", RULES)
    dirty = read_streams(junk_run / "bag", RULES)
    assert set(junk) == set(TOPICS)  # every topic got junk
    assert clean.dropped == dict.fromkeys(clean.counts, 0), clean.first_reason
    for topic in TOPICS:
        got = [(k.step, k.data) for k in dirty.kept[topic]]
        want = [(k.step, k.data) for k in clean.kept[topic]]
        assert got == want, (topic, dirty.first_reason.get(topic))
        assert dirty.dropped[topic] == junk[topic], topic
        assert dirty.counts[topic] == clean.counts[topic] + junk[topic]
    # The clean streams are what the run published: one per step, all of them.
    assert [k.step for k in clean.kept["/x/state"]] == list(range(N))
    assert [k.step for k in clean.kept["/x/learning/correction"]] == list(range(CYCLE, N, RATIO))
    assert [k.step for k in clean.kept["/x/learning/cycle_stats"]] == [1, 2, 3]
    assert [k.step for k in clean.kept["/x/plant/status"]] == [0, 50, 100, 150]
    assert [k.step for k in clean.kept["/x/clock"]] == list(range(0, N, 10))


def learning_scenario(path: Path, **shared: Any) -> Path:
    data = {
        "/**": {
            "ros__parameters": {
                "scenario": {"name": "junk", "description": "junk in the bag"},
                "control_period_s": PERIOD_S,
                "lead_m_per_rad": LEAD,
                "duration_s": N * PERIOD_S,
                **shared,
            }
        },
        "plant": {"ros__parameters": {}},
        "feedback": {"ros__parameters": {"sensor": "scale"}},
        "feedforward": {
            "ros__parameters": {
                "reference": {"kind": "sine", "frequency_hz": 10.0, "amplitude_m": 0.001},
                "learning": {"enabled": True, "cycle_s": CYCLE * PERIOD_S},
            }
        },
    }
    path.write_text(yaml.safe_dump(data))
    return path


def test_rules_of_a_scenario(tmp_path: Path) -> None:
    scenario = load_scenario(learning_scenario(tmp_path / "s.yaml"))
    assert StreamRules.from_scenario(scenario, PERIOD_S) == RULES
    realtime = load_scenario(learning_scenario(tmp_path / "r.yaml", mode="realtime", axis="y"))
    rules = StreamRules.from_scenario(realtime, PERIOD_S)
    assert (rules.mode, rules.axis, rules.window) == ("realtime", "y", 100)


def test_signals_and_summary_are_those_of_the_clean_bag(
    bags: tuple[Path, Path, dict[str, int]], tmp_path: Path
) -> None:
    clean_run, junk_run, junk = bags
    path = learning_scenario(tmp_path / "s.yaml")
    scenario = load_scenario(path)
    clean = load_signals(clean_run / "bag", PERIOD_S, scenario=scenario)
    dirty = load_signals(junk_run / "bag", PERIOD_S, scenario=scenario)
    assert clean.step.tolist() == list(range(N))
    for name in ("step", "encoder_rad", "scale_m", "reference_rad", "feedforward_Nm", "command_Nm"):
        assert_array_equal(getattr(dirty, name), getattr(clean, name), err_msg=name)
    assert not np.isnan(clean.command_Nm).any()
    assert clean.faults == dirty.faults == [FaultRecord(120, 1, "following_error", 2.5e-3)]
    assert dirty.dropped == junk and sum(clean.dropped.values()) == 0
    # summary.json (no scenario passed to load_signals there: the rules are
    # the run's params.yaml beside the bag, here the scenario's own lines).
    for run in (clean_run, junk_run):
        (run / "params.yaml").write_text(path.read_text())
    a = summarise(clean_run, scenario=scenario, scenario_path=path, wall_time_s=1.0, mode="p")
    b = summarise(junk_run, scenario=scenario, scenario_path=path, wall_time_s=1.0, mode="p")
    assert a.steps == b.steps == N
    assert len(a.tracking_error.cycles) == 4
    assert_allclose(
        [(c.rms_m, c.max_m) for c in b.tracking_error.cycles],
        [(c.rms_m, c.max_m) for c in a.tracking_error.cycles],
        rtol=0,
        atol=0,
    )
    assert b.tracking_error == a.tracking_error
    assert b.faults == a.faults


def test_short_and_empty_joint_states_are_dropped_not_raised(tmp_path: Path) -> None:
    """The tester's IndexError: a short or empty recorded JointState."""
    msgs = [
        ("/x/state", CDR.joint_state(0, [])),
        ("/x/state", CDR.joint_state(0, ["x_motor"], position=[1.0])),
        ("/x/state", CDR.joint_state(0, BOTH, position=[1.0], velocity=[0, 0], effort=[0, 0])),
        ("/x/reference", CDR.joint_state(0, [])),
        ("/x/reference", CDR.joint_state(0, MOTOR, position=[1.0])),
        ("/x/command", CDR.joint_state(0, MOTOR)),
        ("/x/fault", CDR.multi_array(layouts.FAULT.labels, [])),
        ("/x/fault", CDR.multi_array(layouts.FAULT.labels, [3.0])),
        ("/x/state", b""),
    ]
    write(tmp_path / "bag", msgs)
    sig = load_signals(tmp_path / "bag", PERIOD_S)
    assert sig.step.size == 0 and sig.command_Nm.size == 0 and sig.faults == []
    assert sig.dropped == {"/x/state": 4, "/x/reference": 2, "/x/command": 1, "/x/fault": 2}


def test_a_past_stamped_sample_does_not_replace_the_real_one(tmp_path: Path) -> None:
    """The tester's 6,909.8 um: a junk state stamped in the past, recorded after the real one."""
    msgs: list[tuple[str, bytes]] = []
    for k in range(20):
        msgs += [("/x/reference", reference(k)), ("/x/state", state(k))]
        if k == 10:
            msgs.append(("/x/state", state(3, position=[3.6, 0.007])))
    write(tmp_path / "bag", msgs)
    sig = load_signals(tmp_path / "bag", PERIOD_S)
    assert sig.step.tolist() == list(range(20))
    assert_allclose(sig.encoder_rad, [value(k) for k in range(20)], rtol=0, atol=0)
    assert sig.dropped == {"/x/reference": 0, "/x/state": 1}


def test_lockstep_takes_exactly_the_next_step_realtime_a_window(tmp_path: Path) -> None:
    msgs = [(t, f(k)) for k in range(30) if k != 7 for t, f in (("/x/state", state),)]
    msgs += [("/x/reference", reference(k)) for k in range(30)]
    write(tmp_path / "run" / "bag", msgs)
    lockstep = load_signals(tmp_path / "run" / "bag", PERIOD_S)
    assert lockstep.step.tolist() == list(range(7))  # a lockstep stream cannot skip step 7
    assert lockstep.dropped["/x/state"] == 22
    shared = {"mode": "realtime", "control_period_s": PERIOD_S}
    (tmp_path / "run" / "params.yaml").write_text(
        yaml.safe_dump({"/**": {"ros__parameters": shared}})
    )
    realtime = load_signals(tmp_path / "run" / "bag", PERIOD_S)
    assert realtime.step.tolist() == [k for k in range(30) if k != 7]
    assert realtime.dropped == {"/x/state": 0, "/x/reference": 0}


def test_the_axis_comes_from_the_run_parameters(tmp_path: Path) -> None:
    """An axis ``y`` (a multi-axis run's directory): its names are the valid ones."""
    y = ["y_motor", "y_table"]
    msgs = [("/y/state", state(k, names=y if k < 5 else BOTH)) for k in range(10)]
    msgs += [("/y/reference", reference(k, names=["y_motor"])) for k in range(10)]
    write_topics = {"/y/state": JOINT_STATE, "/y/reference": JOINT_STATE}
    with BagWriter(tmp_path / "run" / "bag") as bag:
        for topic, type_name in write_topics.items():
            bag.add_topic(topic, type_name)
        for t, (topic, data) in enumerate(msgs):
            bag.write(topic, data, log_time_ns=t + 1)
    assert load_signals(tmp_path / "run" / "bag", PERIOD_S).step.size == 0  # default axis x
    params = {"/**": {"ros__parameters": {"axis": "y"}}, "/**/plant": {"ros__parameters": {}}}
    (tmp_path / "run" / "params.yaml").write_text(yaml.safe_dump(params))
    sig = load_signals(tmp_path / "run" / "bag", PERIOD_S)
    assert sig.step.tolist() == [0, 1, 2, 3, 4]
    assert sig.dropped == {"/y/state": 5, "/y/reference": 0}


def test_table_names_of_recorded_topics() -> None:
    assert table_name("/x/state") == table_name("/state") == table_name("state") == "state"
    assert table_name("/x/clock") == table_name("/clock") == "/clock"
    assert table_name("/x/plant/status") == "plant/status"
    assert table_name("/x/learning/cycle_stats") == "learning/cycle_stats"
    assert table_name("/x/status") is None and table_name("/x/trace") is None


def test_the_recording_order_is_the_sequence_not_the_log_time(tmp_path: Path) -> None:
    """A junk sample logged before the real one it came after (e.g. a tie of stamps)."""
    with BagWriter(tmp_path / "bag") as bag:
        bag.add_topic("/x/state", JOINT_STATE)
        bag.add_topic("/x/reference", JOINT_STATE)
        for k in range(10):
            bag.write("/x/reference", reference(k), log_time_ns=10 * k + 5)
            bag.write("/x/state", state(k), log_time_ns=10 * k + 5)
            # Valid in every field but its values, recorded after the real
            # one and logged before it.
            bag.write("/x/state", state(k, position=[9.0, 9.0]), log_time_ns=10 * k + 4)
    sig = load_signals(tmp_path / "bag", PERIOD_S)
    assert sig.step.tolist() == list(range(10))
    assert_allclose(sig.encoder_rad, [value(k) for k in range(10)], rtol=0, atol=0)
    assert sig.dropped == {"/x/reference": 0, "/x/state": 10}


def test_a_strangers_well_formed_next_sample_is_left_out_and_counted(tmp_path: Path) -> None:
    """A stranger's sample of the next step, valid in every field and recorded before the
    producer's, is on the stranger's channel: not in the stream, counted apart; a reader
    that merges a topic's channels (rosbags) still has every message of the wire."""
    from rosbags.rosbag2 import Reader

    who = "/x/mimic 010f78fd316f8cfd0000000000002303"
    with BagWriter(tmp_path / "bag") as bag:
        bag.add_topic("/x/state", JOINT_STATE)
        bag.add_topic("/x/reference", JOINT_STATE)
        for k in range(10):
            bag.write("/x/reference", reference(k), log_time_ns=10 * k + 1)
            bag.write("/x/state", state(k, position=[9.0, 9.0]), log_time_ns=10 * k + 4,
                      stranger=who)  # fmt: skip
            bag.write("/x/state", state(k), log_time_ns=10 * k + 5)
    streams = read_streams(tmp_path / "bag", RULES)
    assert [k.step for k in streams.kept["/x/state"]] == list(range(10))
    assert [k.data for k in streams.kept["/x/state"]] == [state(k) for k in range(10)]
    assert streams.strangers == {"/x/state": 10}
    assert streams.dropped == {"/x/state": 0, "/x/reference": 0}
    assert streams.counts == {"/x/reference": 10, "/x/state": 20}
    sig = load_signals(tmp_path / "bag", PERIOD_S)
    assert_allclose(sig.encoder_rad, [value(k) for k in range(10)], rtol=0, atol=0)
    with Reader(tmp_path / "bag") as reader:
        states = [c for c in reader.connections if c.topic == "/x/state"]
        assert [c.msgcount for c in states] == [20]
        assert sum(1 for c, _, _ in reader.messages(connections=states)) == 20
    from mcap.reader import make_reader

    (path,) = (tmp_path / "bag").glob("*.mcap")
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    channels = [c for c in summary.channels.values() if c.topic == "/x/state"]
    assert sorted(c.metadata.get("stranger_publisher", "") for c in channels) == ["", who]
    assert len({c.metadata["offered_qos_profiles"] for c in channels}) == 1
