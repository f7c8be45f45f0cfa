"""The live view (``run ... --live``): a Foxglove WebSocket client sees the run, the bag is unchanged.

The client speaks the Foxglove WebSocket protocol as Foxglove and Lichtblick
do (the ``websockets`` package; foxglove-sdk 0.30 names the subprotocol
``foxglove.sdk.v1``, the same protocol as ``foxglove.websocket.v1``): the
server sends ``serverInfo`` and ``advertise`` as JSON, the client subscribes
to every channel, and each message comes as a binary frame: opcode 0x01,
subscription id (u32 LE), log time (u64 LE, ns), payload (JSON here).
"""

from __future__ import annotations

import hashlib
import json
import math
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from run_support import cpu_hogs
from sensor_msgs.msg import JointState

from servo_axis.params.factories import run_steps
from servo_axis.params.resolve import node_values
from servo_axis.params.scenario import find_scenario, load_scenario
from servo_axis.wire.cdr import decode_joint_state
from servo_axis.wire.messages import StateSample

pytestmark = pytest.mark.integration

SCENARIO = "ptc_nominal"
CHANNELS = ("/x/state", "/x/reference", "/x/command", "/x/tracking_error", "/diagnostics")
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@dataclass
class Viewer:
    """What a Foxglove WebSocket client received during the run."""

    port: int
    server_info: dict[str, Any] = field(default_factory=dict)
    channels: dict[int, dict[str, Any]] = field(default_factory=dict)
    # topic -> [(log time ns, payload)]
    messages: dict[str, list[tuple[int, dict[str, Any]]]] = field(default_factory=dict)
    statuses: list[dict[str, Any]] = field(default_factory=list)
    subprotocol: str | None = None
    error: BaseException | None = None

    def watch(self, give_up: threading.Event) -> None:
        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        try:
            while True:  # until the server listens (the runner starts it first)
                try:
                    ws = connect(
                        f"ws://127.0.0.1:{self.port}", subprotocols=SUBPROTOCOLS, open_timeout=2
                    )
                    break
                except OSError:
                    if give_up.is_set():
                        return
                    time.sleep(0.02)
            with ws:
                self.subprotocol = ws.subprotocol
                subscribed: dict[int, str] = {}
                while True:
                    try:
                        frame = ws.recv(timeout=60)
                    except (ConnectionClosed, TimeoutError):
                        return
                    if isinstance(frame, str):
                        op = json.loads(frame)
                        if op["op"] == "serverInfo":
                            self.server_info = op
                        elif op["op"] == "advertise":
                            subs = []
                            for ch in op["channels"]:
                                self.channels[ch["id"]] = ch
                                sub_id = len(subscribed) + 1
                                subscribed[sub_id] = ch["topic"]
                                subs.append({"id": sub_id, "channelId": ch["id"]})
                            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                        elif op["op"] == "status":
                            self.statuses.append(op)
                    elif frame[0] == 0x01:
                        sub_id, log_time = struct.unpack_from("<IQ", frame, 1)
                        payload = json.loads(frame[13:])
                        self.messages.setdefault(subscribed[sub_id], []).append((log_time, payload))
        except BaseException as err:  # reported by the test
            self.error = err


def run(out: Path, domain: int, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "servo_axis", "run", SCENARIO, "--out", str(out), "--no-plots",
         "--domain-id", str(domain), *extra],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


def missing_ranges(steps: int, got: list[int]) -> str:
    """The steps of ``range(steps)`` not in ``got``, as ranges ("5-9, 1990-1999")."""
    missing = sorted(set(range(steps)) - set(got))
    ranges: list[list[int]] = []
    for k in missing:
        if ranges and ranges[-1][1] == k - 1:
            ranges[-1][1] = k
        else:
            ranges.append([k, k])
    return ", ".join(f"{a}-{b}" if a != b else str(a) for a, b in ranges) or "none"


def payload_hashes(payloads: dict[str, list[bytes]]) -> dict[str, tuple[int, str]]:
    """Message count and SHA-256 of the CDR payloads, per topic."""
    return {
        topic: (len(data), hashlib.sha256(b"".join(data)).hexdigest())
        for topic, data in payloads.items()
    }


@pytest.mark.parametrize("mode", ["separate", "composed"])
def test_live_view_serves_the_run_on_the_simulation_timeline_and_changes_nothing(
    ros_env: int, tmp_path: Path, raw_payloads: Callable[[Path], dict[str, list[bytes]]], mode: str
) -> None:
    scenario = load_scenario(find_scenario(SCENARIO))
    plant = node_values(scenario, "plant")
    period_ns = round(plant["control_period_s"] * 1e9)
    steps = run_steps(plant)
    lead = node_values(scenario, "feedback")["lead_m_per_rad"]

    viewer = Viewer(free_port())
    give_up = threading.Event()
    client = threading.Thread(target=viewer.watch, args=(give_up,), daemon=True)
    client.start()
    composed = ["--composed"] if mode == "composed" else []
    live = run(tmp_path / "live", ros_env, "--live", "--live-port", str(viewer.port), *composed)
    give_up.set()
    client.join(timeout=90)
    assert live.returncode == 0, live.stdout + live.stderr
    assert f"live view: ws://127.0.0.1:{viewer.port}" in live.stdout
    assert viewer.error is None, repr(viewer.error)
    assert not client.is_alive()
    assert viewer.subprotocol in SUBPROTOCOLS
    assert viewer.server_info["op"] == "serverInfo"
    assert "time" in viewer.server_info["capabilities"]
    assert not viewer.statuses, viewer.statuses

    # Every channel advertised, JSON with a JSON schema.
    by_topic = {ch["topic"]: ch for ch in viewer.channels.values()}
    assert set(CHANNELS) <= set(by_topic), sorted(by_topic)
    for topic in CHANNELS:
        assert by_topic[topic]["encoding"] == "json"
        assert by_topic[topic]["schemaEncoding"] == "jsonschema"
        json.loads(by_topic[topic]["schema"])

    # Messages on the simulation timeline: log time = the header stamp = step * T_u,
    # increasing, within the run. Every step: the viewer subscribed while the
    # nodes started, the bridge reads the writers' history and forwards what
    # is still queued when it is stopped.
    for topic in CHANNELS[:4]:
        got = viewer.messages.get(topic, [])
        assert len(got) == steps, (
            f"{topic}: {len(got)} messages of {steps}, missing steps "
            f"{missing_ranges(steps, [m['step'] for _, m in got])}"
        )
        times = np.array([t for t, _ in got], dtype=np.int64)
        assert np.all(times % period_ns == 0), topic
        assert np.all(np.diff(times) > 0), topic
        assert times[-1] <= (steps - 1) * period_ns, topic
        for t, msg in got:
            assert msg["step"] * period_ns == t
            assert msg["timestamp"]["sec"] * 1_000_000_000 + msg["timestamp"]["nsec"] == t
    for t, _ in viewer.messages.get("/diagnostics", []):  # once the nodes publish them
        assert t % period_ns == 0 and t <= (steps - 1) * period_ns

    # A state message: every value named as the wire's sample fields, finite.
    states = {m["step"]: m for _, m in viewer.messages["/x/state"]}
    names = {f.name for f in fields(StateSample)}
    for msg in states.values():
        assert set(msg) == names | {"timestamp"}
        assert all(math.isfinite(msg[n]) for n in names - {"step"})
    assert "encoder_rad" in names

    # The values are the run's: the recorded state at the same steps.
    recorded = {}
    for data in raw_payloads(tmp_path / "live" / "bag")["/x/state"]:
        js = decode_joint_state(data)
        recorded[js.stamp_ns // period_ns] = js.position[0]
    live_steps = sorted(states)
    assert_allclose(
        [states[k]["encoder_rad"] for k in live_steps],
        [recorded[k] for k in live_steps],
        rtol=0,
        atol=0,
    )

    # The tracking error: reference position minus the encoder angle (semi-closed loop).
    refs = {m["step"]: m["position_rad"] for _, m in viewer.messages["/x/reference"]}
    errors = [m for _, m in viewer.messages["/x/tracking_error"]]
    both = [e for e in errors if e["step"] in refs and e["step"] in states]
    assert len(both) == steps
    for e in both:
        assert e["reference_rad"] == refs[e["step"]]
        assert e["output_rad"] == states[e["step"]]["encoder_rad"]
    assert_allclose(
        [e["error_rad"] for e in errors],
        [e["reference_rad"] - e["output_rad"] for e in errors],
        rtol=0,
        atol=0,
    )
    assert_allclose(
        [e["error_m"] for e in errors],
        [lead * e["error_rad"] for e in errors],
        rtol=1e-12,
        atol=1e-18,
    )

    # The live view changes nothing: the bag of a run without it is byte-identical.
    plain = run(tmp_path / "plain", ros_env, *composed)
    assert plain.returncode == 0, plain.stdout + plain.stderr
    assert "live view" not in plain.stdout
    with_live = payload_hashes(raw_payloads(tmp_path / "live" / "bag"))
    without = payload_hashes(raw_payloads(tmp_path / "plain" / "bag"))
    assert with_live == without
    assert with_live["/x/state"][0] == steps


def test_diagnostics_are_forwarded_at_the_simulation_time_the_bridge_has_seen(
    ros_env: int, tmp_path: Path
) -> None:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    from servo_axis.nodes.runtime import STREAM_QOS
    from servo_axis.run.live_channels import LiveAxis
    from servo_axis.run.live_view import module_args
    from servo_axis.wire.messages import state_to_msg

    axis = LiveAxis("/x", "x", 1e-3, "encoder", 0.00191, True)
    viewer = Viewer(free_port())
    give_up = threading.Event()
    client = threading.Thread(target=viewer.watch, args=(give_up,), daemon=True)
    client.start()
    log = (tmp_path / "live.log").open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "servo_axis.run.live", *module_args(viewer.port, [axis])],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    context = rclpy.context.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("diagnostics_source", context=context)
    try:
        # A state stamped at step 7 (1 ms steps), then diagnostics stamped in wall time.
        state = node.create_publisher(JointState, "/x/state", STREAM_QOS)
        state_msg = state_to_msg(
            StateSample(7, 0.5, 1e-3, 0.0, 0.0, 0.0, 0.0), axis="x", period_ns_=10**6
        )
        diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        msg = DiagnosticArray()
        msg.header.stamp.sec = 1_700_000_000
        msg.status = [
            DiagnosticStatus(
                level=DiagnosticStatus.WARN,
                name="x/plant",
                message="deadline misses",
                hardware_id="x",
                values=[KeyValue(key="deadline_misses", value="3")],
            )
        ]
        deadline = time.monotonic() + 30
        while "/diagnostics" not in viewer.messages and time.monotonic() < deadline:
            # Diagnostics only once the viewer has the state back: the bridge
            # matches the two topics in either order, and diagnostics ahead of
            # the first state are rightly at time 0.
            state.publish(state_msg)
            if "/x/state" in viewer.messages:
                diagnostics.publish(msg)
            time.sleep(0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=20)
        log.close()
        give_up.set()
        client.join(timeout=30)
    assert code == 0, (tmp_path / "live.log").read_text()
    assert viewer.error is None, repr(viewer.error)
    got = viewer.messages.get("/diagnostics", [])
    assert got, (tmp_path / "live.log").read_text()
    log_time, payload = got[0]
    assert log_time == 7 * 10**6  # the simulation time of the last state, not the stamp
    assert payload["header"]["stamp"] == {"sec": 1_700_000_000, "nsec": 0}
    assert payload["status"] == [
        {
            "level": 1,
            "name": "x/plant",
            "message": "deadline misses",
            "hardware_id": "x",
            "values": [{"key": "deadline_misses", "value": "3"}],
        }
    ]


def refused(port: int, give_up: threading.Event, out: list[object]) -> None:
    """A client offering only the older subprotocol: what the server answered."""
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    while not give_up.is_set():
        try:
            with connect(
                f"ws://127.0.0.1:{port}", subprotocols=["foxglove.websocket.v1"], open_timeout=5
            ) as ws:
                out.append(ws.subprotocol)
            return
        except InvalidStatus as err:
            out.append(err.response.status_code)
            return
        except OSError:
            time.sleep(0.02)


def test_under_load_two_viewers_get_the_last_step_and_a_refused_one_is_told(
    ros_env: int, tmp_path: Path
) -> None:
    """CPU hogs beside the run (two, one beside another pytest-xdist worker): the live
    view drains until the run's last step (it once stopped 3 s after the nodes, two
    viewers at step 1,982 of 3,000, silently), and the runner's terminal says why a
    viewer offering only foxglove.websocket.v1 was refused (the SDK answers HTTP 400
    and logged only "handshake failed")."""
    steps = run_steps(node_values(load_scenario(find_scenario(SCENARIO)), "plant"))
    port = free_port()
    viewers = [Viewer(port), Viewer(port)]
    give_up = threading.Event()
    clients = [threading.Thread(target=v.watch, args=(give_up,), daemon=True) for v in viewers]
    answer: list[object] = []
    clients.append(threading.Thread(target=refused, args=(port, give_up, answer), daemon=True))
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(cpu_hogs())]
    try:
        for c in clients:
            c.start()
        live = run(tmp_path / "live", ros_env, "--live", "--live-port", str(port))
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
        give_up.set()
        for c in clients:
            c.join(timeout=90)
    assert live.returncode == 0, live.stdout + live.stderr
    assert answer == [400], answer
    assert "live view: a viewer could not connect (Dropping client 127.0.0.1:" in live.stderr
    assert "offers only the older foxglove.websocket.v1 is refused with HTTP 400" in live.stderr
    for viewer in viewers:
        assert viewer.error is None, repr(viewer.error)
        got = [m["step"] for _, m in viewer.messages.get("/x/state", [])]
        assert got == list(range(steps)), (
            f"{len(got)} states of {steps}, missing {missing_ranges(steps, got)}; "
            f"the terminal said: {live.stderr[-1500:]}"
        )
    assert "/x/state: forwarded" not in live.stderr  # nothing to report
