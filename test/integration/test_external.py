"""Outside nodes play roles of a run, through ``python -m servo_axis run --external`` (issue 17).

The outside nodes are the examples a user copies (``examples/``: plain rclpy,
default QoS, their own node names, nothing imported from servo_axis) or a node
of the suite started by hand under another name with the run's parameter
file. Each run goes through the user's entry point; what is recorded is
checked against an independent computation (the PD law on the recorded
samples, the analytic sine) or against the same scenario run by the suite
alone.
"""

from __future__ import annotations

import hashlib
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from servo_axis.analysis.signals import StreamRules, read_streams
from servo_axis.params.scenario import load_scenario
from servo_axis.recording.deserialize import read_messages

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config"
EXAMPLES = REPO / "examples"
NS = "/x"
RUN_TIMEOUT_S = 90.0


def short(name: str, dst: Path, **shared: Any) -> Path:
    """Shipped scenario ``name`` with ``/**`` values changed and its file paths absolute."""
    data = load_scenario(CONFIG / f"{name}.yaml")
    data["/**"]["ros__parameters"].update(shared)
    ff = data.get("feedforward", {}).get("ros__parameters", {})
    for key in ("friction_table", "gms"):
        entry = ff.get(key, {})
        if entry.get("file") and not Path(entry["file"]).is_absolute():
            entry["file"] = str(CONFIG / entry["file"])
    path = dst / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def start_run(scenario: Path, out: Path, *extra: str) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "servo_axis", "run", str(scenario), "--out", str(out)]
    cmd += ["--domain-id", os.environ["ROS_DOMAIN_ID"], "--namespace", NS, "--no-plots", *extra]
    log = (out.parent / f"{out.name}.out").open("wb")
    return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


def start_outside(
    args: list[str], log: Path, *, run_profile: bool = False
) -> subprocess.Popen[bytes]:
    """An outside node in the run's domain, with localhost discovery (what the docs ask
    of a user) and Fast DDS's own defaults, or with ``run_profile`` the run's profile too."""
    env = dict(os.environ)
    if not run_profile:
        env.pop("FASTRTPS_DEFAULT_PROFILES_FILE", None)
        env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)
    return subprocess.Popen(
        [sys.executable, *args],
        stdout=log.open("wb"),
        stderr=subprocess.STDOUT,
        start_new_session=True,
        env=env,
    )


def finish(proc: subprocess.Popen[bytes], timeout_s: float) -> int | None:
    """The exit code; None if it had to be stopped (SIGINT, then SIGKILL)."""
    try:
        return proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        stop(proc)
        return None


def stop(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def tails(out: Path) -> str:
    text = (out.parent / f"{out.name}.out").read_text(errors="replace").splitlines()[-15:]
    for log in sorted((out / "logs").glob("[a-z]*.log")) if (out / "logs").is_dir() else []:
        text += [f"{log.stem}: {line}" for line in log.read_text().splitlines()[-4:]]
    return "\n".join(text)


def run_with_outside(
    scenario: Path, out: Path, roles: list[str], outside: list[list[str]]
) -> tuple[int | None, Any]:
    """Run ``scenario`` with ``roles`` played by the ``outside`` commands; the exit code."""
    extra = [a for r in roles for a in ("--external", r)]
    proc = start_run(scenario, out, *extra)
    nodes = [
        start_outside(args, out.parent / f"{out.name}.outside{i}.log")
        for i, args in enumerate(outside)
    ]
    try:
        code = finish(proc, RUN_TIMEOUT_S)
    finally:
        for node in nodes:
            stop(node)
    return code, nodes


def run_params(proc: subprocess.Popen[bytes], out: Path) -> dict[str, Any]:
    """The parameter file the run at ``out`` wrote for its nodes, once it is there."""
    deadline = time.monotonic() + 30
    while not (out / "params.yaml").is_file():
        assert time.monotonic() < deadline and proc.poll() is None, tails(out)
        time.sleep(0.05)
    return dict(yaml.safe_load((out / "params.yaml").read_text()))


def payload_hashes(bag: Path, raw_payloads: Any) -> dict[str, str]:
    return {
        topic: hashlib.sha256(b"".join(data)).hexdigest()
        for topic, data in raw_payloads(bag).items()
    }


def joint_series(bag: Path, topic: str) -> dict[int, Any]:
    """Messages of a JointState topic by stamp (ns)."""
    return {
        m.message.header.stamp.sec * 10**9 + m.message.header.stamp.nanosec: m.message
        for m in read_messages(bag, topics=[topic])
    }


def pd_controller(bandwidth_hz: float, inertia: float) -> list[str]:
    return [
        str(EXAMPLES / "pd_controller.py"),
        "--ros-args",
        "-r",
        f"__ns:={NS}",
        "-p",
        f"bandwidth_hz:={bandwidth_hz}",
        "-p",
        f"inertia_kgm2:={inertia}",
    ]


# -- an outside controller on each plant model ----------------------------------------


@pytest.mark.parametrize(
    ("scenario", "duration_s", "bandwidth_hz", "inertia", "runs"),
    [
        # 3 modes, dead time, friction; RPTC learning on: twice, the bags compared
        ("rptc_detailed", 1.0, 20.0, 0.01, 2),
        ("dlpid_tilt_pid", 0.4, 10.0, 0.005, 1),  # tilting table (003)
        ("slow_reversal_sigmoid", 0.5, 20.0, 0.0033, 1),  # elastic ball screw (004)
    ],
)
def test_the_example_controller_drives_each_plant_model(
    ros_env: int,
    tmp_path: Path,
    raw_payloads: Any,
    scenario: str,
    duration_s: float,
    bandwidth_hz: float,
    inertia: float,
    runs: int,
) -> None:
    """Through `run --external feedback` with examples/pd_controller.py: exit 0, on the
    most detailed axis twice with the bags identical (a property of the lockstep
    protocol, not of the model: once is enough for the others), and every recorded
    command is the PD law of the recorded state and reference of its sample (computed
    here, independently of the example). (Once, on ptc_friction, as the tutorial has
    it: test_docs_pages.py::test_tutorials_own_controller.)"""
    path = short(scenario, tmp_path, duration_s=duration_s)
    hashes = []
    for i in range(runs):
        out = tmp_path / f"run{i}"
        code, _ = run_with_outside(path, out, ["feedback"], [pd_controller(bandwidth_hz, inertia)])
        assert code == 0, tails(out)
        hashes.append(payload_hashes(out / "bag", raw_payloads))
    assert all(h == hashes[0] for h in hashes)
    bag = tmp_path / "run0" / "bag"
    state, ref, cmd = (joint_series(bag, f"{NS}/{t}") for t in ("state", "reference", "command"))
    steps = round(duration_s / load_scenario(path)["/**"]["ros__parameters"]["control_period_s"])
    assert len(state) == len(cmd) == steps
    w = 2 * math.pi * bandwidth_hz
    kp, kd = inertia * w * w, 2 * 0.7 * inertia * w
    stamps = sorted(cmd)
    want = [
        ref[t].effort[0]
        + kp * (ref[t].position[0] - state[t].position[0])
        + kd * (ref[t].velocity[0] - state[t].velocity[0])
        for t in stamps
    ]
    got = [cmd[t].effort[0] for t in stamps]
    assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    assert {cmd[t].name[0] for t in stamps} == {state[stamps[0]].name[0]}
    # It did control the axis: the motor follows the reference to within a tenth of its swing.
    y = np.array([state[t].position[0] for t in stamps])
    r = np.array([ref[t].position[0] for t in stamps])
    assert np.max(np.abs(r - y)) < 0.1 * max(np.ptp(r), 1e-3)


# -- an outside reference generator ----------------------------------------------------


def test_the_example_reference_generator_feeds_the_axis(
    ros_env: int, tmp_path: Path, raw_payloads: Any
) -> None:
    """`run ptc_nominal --external feedforward` with examples/sine_reference.py: exit 0, the
    bags of two runs identical, the recorded reference is the analytic sine of its stamp,
    and the suite's feedback made the axis follow it."""
    path = short("ptc_nominal", tmp_path, duration_s=0.5)
    gen = [str(EXAMPLES / "sine_reference.py"), "--ros-args", "-r", f"__ns:={NS}"]
    hashes = []
    for i in range(2):
        out = tmp_path / f"run{i}"
        code, _ = run_with_outside(path, out, ["feedforward"], [gen])
        assert code == 0, tails(out)
        hashes.append(payload_hashes(out / "bag", raw_payloads))
    assert hashes[0] == hashes[1]
    bag = tmp_path / "run0" / "bag"
    ref, state = joint_series(bag, f"{NS}/reference"), joint_series(bag, f"{NS}/state")
    assert len(ref) == 500
    t = np.array(sorted(ref)) * 1e-9
    a, w = 5.0, 2 * math.pi * 2.0
    assert_allclose([ref[k].position[0] for k in sorted(ref)], a * (1 - np.cos(w * t)), atol=1e-12)
    assert_allclose([ref[k].velocity[0] for k in sorted(ref)], a * w * np.sin(w * t), atol=1e-9)
    assert_allclose(
        [ref[k].effort[0] for k in sorted(ref)],
        0.01 * a * w * w * np.cos(w * t) + 0.1 * a * w * np.sin(w * t),
        atol=1e-9,
    )
    err = [ref[k].position[0] - state[k].position[0] for k in sorted(ref)]
    assert max(abs(e) for e in err[250:]) < 0.01 * 2 * a


#: A listener on `command` with the default profile, in plain rclpy.
COMMAND_LISTENER = """
import rclpy
from sensor_msgs.msg import JointState
rclpy.init()
node = rclpy.create_node("my_command_listener", namespace="{ns}")
node.create_subscription(JointState, "command", lambda m: None, 10)
rclpy.spin(node)
"""


def test_a_feedback_that_listens_last_still_gets_the_generators_first_reference(
    ros_env: int, tmp_path: Path, raw_payloads: Any
) -> None:
    """The sine example answers `state` too, so it cannot stand in for the feedback. The
    suite's feedback, started by hand as `my_feedback`, is made to subscribe only once a
    third listener on `command` comes, 3 s after everything else: the plant waits for it,
    and the bag equals that of the same run with the feedback started by the runner. (CI
    once hung at step 1: a slow feedback missed reference[0], sent before it listened.)"""
    path = short("ptc_nominal", tmp_path, duration_s=0.2)
    gen = [str(EXAMPLES / "sine_reference.py"), "--ros-args", "-r", f"__ns:={NS}"]
    runner_fed = tmp_path / "runner_fed"
    code, _ = run_with_outside(path, runner_fed, ["feedforward"], [gen])
    assert code == 0, tails(runner_fed)

    out = tmp_path / "late"
    proc = start_run(path, out, "--external", "feedforward", "--external", "feedback")
    nodes = [start_outside(gen, tmp_path / "late.generator.log")]
    try:
        params = run_params(proc, out)
        params["/**/my_feedback"] = params.pop("/**/feedback")
        section = params["/**/my_feedback"]["ros__parameters"]
        section["wait_for_command_subscribers"] += 1
        mine = tmp_path / "my_feedback.yaml"
        mine.write_text(yaml.safe_dump(params))
        feedback = ["-m", "servo_axis.nodes.feedback", "--ros-args", "--params-file", str(mine),
                    "-r", "__node:=my_feedback", "-r", f"__ns:={NS}"]  # fmt: skip
        nodes.append(start_outside(feedback, tmp_path / "late.feedback.log"))
        time.sleep(3.0)
        assert proc.poll() is None, tails(out)
        listener = ["-c", COMMAND_LISTENER.format(ns=NS)]
        nodes.append(start_outside(listener, tmp_path / "late.listener.log"))
        code = finish(proc, RUN_TIMEOUT_S)
    finally:
        for node in nodes:
            stop(node)
    assert code == 0, tails(out)
    assert payload_hashes(out / "bag", raw_payloads) == payload_hashes(
        runner_fed / "bag", raw_payloads
    )
    assert len(joint_series(out / "bag", f"{NS}/reference")) == 200


# -- the suite's own nodes as outside nodes ---------------------------------------------


def outside_suite_node_gives_the_suites_own_result(
    scenario: str, duration_s: float, role: str, name: str, tmp_path: Path, raw_payloads: Any
) -> None:
    """Run ``scenario`` by the suite alone, then with ``--external role`` played by the
    suite's own node of that role started by hand as ``name`` with the run's parameter file
    (its section renamed, as a user would); the two bags must be equal, byte for byte.
    The suite alone runs composed: the same bag as its separate processes
    (test_runs.py::test_lockstep_runs_are_identical_separate_composed_and_split), in
    less CPU time."""
    path = short(scenario, tmp_path, duration_s=duration_s)
    alone = tmp_path / "alone"
    assert finish(start_run(path, alone, "--composed"), RUN_TIMEOUT_S) == 0, tails(alone)

    out = tmp_path / "outside"
    proc = start_run(path, out, "--external", role)
    params = run_params(proc, out)
    params[f"/**/{name}"] = params.pop(f"/**/{role}")
    mine = tmp_path / f"{name}.yaml"
    mine.write_text(yaml.safe_dump(params))
    node = start_outside(
        ["-m", f"servo_axis.nodes.{role}", "--ros-args", "--params-file", str(mine),
         "-r", f"__node:={name}", "-r", f"__ns:={NS}"],
        tmp_path / f"{name}.log",
    )  # fmt: skip
    try:
        code = finish(proc, RUN_TIMEOUT_S)
    finally:
        stop(node)
    assert code == 0, tails(out)
    assert payload_hashes(out / "bag", raw_payloads) == payload_hashes(alone / "bag", raw_payloads)


def test_an_outside_learning_unit_gives_the_suites_own_result(
    ros_env: int, tmp_path: Path, raw_payloads: Any
) -> None:
    """The suite's learning node as `my_learner` plays `--external learning` (RPTC)."""
    outside_suite_node_gives_the_suites_own_result(
        "rptc_detailed", 1.5, "learning", "my_learner", tmp_path, raw_payloads
    )


def test_an_outside_plant_gives_the_suites_own_result(
    ros_env: int, tmp_path: Path, raw_payloads: Any
) -> None:
    """servo_axis as the controller stack of an axis simulated elsewhere: the suite's plant
    node as `my_axis_sim` plays `--external plant`; the run ends when the recorder has
    every step."""
    outside_suite_node_gives_the_suites_own_result(
        "ptc_friction", 0.5, "plant", "my_axis_sim", tmp_path, raw_payloads
    )


# -- junk and silence from outside ------------------------------------------------------


class OutsideNode:
    """A node of the user's (default QoS, its own name) in this process.

    It follows `state`; with ``answer`` it plays the feedback with the example's PD law
    (the same floating-point operations as ``examples/pd_controller.py``); with ``junk``
    it sends NaN, short, empty, misnamed, past, ahead and off-grid commands at 200 Hz,
    through its own command publisher if it answers, else through one it makes only
    once the run is under way (after the declared controller's).
    """

    def __init__(
        self,
        domain: int,
        *,
        junk: bool = True,
        answer: bool = False,
        bandwidth_hz: float = 20.0,
        inertia: float = 0.01,
        axis: str = "x",
        period_ns: int = 1_000_000,
    ) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import JointState

        self.rclpy, self.axis, self.period_ns, self.junk = rclpy, axis, period_ns, junk
        self.context = rclpy.context.Context()
        rclpy.init(args=[], context=self.context, domain_id=domain)
        self.node = rclpy.create_node("not_a_servo_node", namespace=NS, context=self.context)
        # Answers and junk share one publisher: at 200 Hz of junk a depth-10 queue may drop
        # an answer before a loaded plant reads it (keep-last), so this one keeps 1000.
        self.pub = self.node.create_publisher(JointState, "command", 1000) if answer else None
        w = 2 * math.pi * bandwidth_hz
        self.kp, self.kd = inertia * w * w, 2 * 0.7 * inertia * w
        self.states: dict[int, Any] = {}
        self.references: dict[int, Any] = {}
        self.answer = answer
        self.step = 0
        self.node.create_subscription(JointState, "state", self._on_state, 10)
        if answer:
            self.node.create_subscription(JointState, "reference", self._on_reference, 1000)
        self.kinds = ["nan", "short", "empty", "wrong_name", "past", "ahead", "off_grid"]
        self.sent: dict[str, int] = dict.fromkeys(self.kinds, 0)
        self._i = 0
        if junk:
            self.node.create_timer(0.005, self._tick)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def _ns(self, msg: Any) -> int:
        return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec

    def _on_state(self, msg: Any) -> None:
        self.step = self._ns(msg) // self.period_ns
        if self.answer:
            self.states[self._ns(msg)] = msg
            self._answer(self._ns(msg))

    def _on_reference(self, msg: Any) -> None:
        self.references[self._ns(msg)] = msg
        self._answer(self._ns(msg))

    def _answer(self, key: int) -> None:
        from sensor_msgs.msg import JointState

        if key not in self.states or key not in self.references:
            return
        state, ref = self.states.pop(key), self.references.pop(key)
        error = ref.position[0] - state.position[0]
        rate = ref.velocity[0] - state.velocity[0]
        command = JointState(header=state.header, name=[state.name[0]])
        command.effort = [ref.effort[0] + self.kp * error + self.kd * rate]
        assert self.pub is not None
        self.pub.publish(command)

    def _tick(self) -> None:
        from builtin_interfaces.msg import Time
        from sensor_msgs.msg import JointState

        if self.step < 20:
            return  # until the stream has begun, "past" is no past
        if self.pub is None:
            self.pub = self.node.create_publisher(JointState, "command", 10)
        kind = self.kinds[self._i % len(self.kinds)]
        self._i += 1
        ns = {"past": (self.step - 5) * self.period_ns, "ahead": (self.step + 1000) * self.period_ns,
              "off_grid": (self.step + 1) * self.period_ns + self.period_ns // 2}.get(
            kind, (self.step + 1) * self.period_ns)  # fmt: skip
        msg = JointState(name=[f"{self.axis}_motor"], effort=[0.0])
        msg.header.stamp = Time(sec=ns // 10**9, nanosec=ns % 10**9)
        if kind == "nan":
            msg.effort = [math.nan]
        elif kind == "short":
            msg.effort = []
        elif kind == "empty":
            msg = JointState(header=msg.header)
        elif kind == "wrong_name":
            msg.name = ["y_motor"]
        self.pub.publish(msg)
        self.sent[kind] += 1

    def spin_while(self, cond: Any, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while cond() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


@pytest.fixture(scope="module")
def clean_external_run(module_ros_env: tuple[int, Path]) -> tuple[Path, Path]:
    """``(scenario, run)``: ptc_nominal for 1 s with the example controller as the
    feedback and nothing else on the domain; the junk tests compare their runs with it."""
    _, folder = module_ros_env
    path = short("ptc_nominal", folder, duration_s=1.0)
    out = folder / "clean"
    code, _ = run_with_outside(path, out, ["feedback"], [pd_controller(20.0, 0.01)])
    assert code == 0, tails(out)
    return path, out


def same_streams(clean: Path, dirty: Path, path: Path) -> None:
    rules = StreamRules.from_scenario(load_scenario(path), 0.001)
    a, b = read_streams(clean / "bag", rules), read_streams(dirty / "bag", rules)
    for topic in (f"{NS}/state", f"{NS}/command", f"{NS}/reference"):
        got = [(k.step, k.data) for k in b.kept[topic]]
        assert got == [(k.step, k.data) for k in a.kept[topic]], topic
        assert len(got) == rules.steps, topic


def test_junk_from_the_outside_controller_itself_is_rejected_and_changes_nothing(
    ros_env: int, tmp_path: Path, clean_external_run: tuple[Path, Path]
) -> None:
    """The outside feedback node answers every state and, through the same publisher,
    sends junk commands: the plant rejects and counts them like an internal node's; no
    stranger, exit 0, and the bag's validated streams are those of the clean example run."""
    path, clean = clean_external_run
    dirty = tmp_path / "junk"
    node = OutsideNode(ros_env, answer=True)
    try:
        proc = start_run(path, dirty, "--external", "feedback")
        node.spin_while(lambda: proc.poll() is None, RUN_TIMEOUT_S)
        code = finish(proc, 10.0)
    finally:
        node.close()
    assert code == 0, tails(dirty)
    assert all(n > 0 for n in node.sent.values()), node.sent
    summary = yaml.safe_load((dirty / "summary.json").read_text())
    plant = summary["health"]["nodes"]["plant"]
    assert plant["rejected"]["command"] > 0 and not plant["strangers"]
    same_streams(clean, dirty, path)


def test_a_stranger_beside_the_outside_controller_is_reported_and_changes_nothing(
    ros_env: int, tmp_path: Path, clean_external_run: tuple[Path, Path]
) -> None:
    """While the example controller drives the axis, a second outside node (default QoS)
    starts publishing junk commands: it is a stranger (exit 3), its messages are counted and
    never applied, and the bag's validated streams are those of the clean run."""
    path, clean = clean_external_run
    dirty = tmp_path / "junk"
    junk = OutsideNode(ros_env)
    try:
        proc = start_run(path, dirty, "--external", "feedback")
        ctrl = start_outside(pd_controller(20.0, 0.01), tmp_path / "ctrl.log")
        try:
            junk.spin_while(lambda: proc.poll() is None, RUN_TIMEOUT_S)
            code = finish(proc, 10.0)
        finally:
            stop(ctrl)
    finally:
        junk.close()
    assert code == 3, tails(dirty)
    assert all(n > 0 for n in junk.sent.values()), junk.sent
    summary = yaml.safe_load((dirty / "summary.json").read_text())
    plant = summary["health"]["nodes"]["plant"]
    # Its messages are a stranger's: counted, never applied (nor validated).
    assert plant["stranger_messages"]["command"] > 0
    assert any("not_a_servo_node" in who for who in plant["strangers"]["command"])
    same_streams(clean, dirty, path)


@pytest.mark.shm
def test_an_outside_controller_that_stops_answering_is_a_reported_fallback(
    ros_env: int, tmp_path: Path
) -> None:
    """SIGKILL of the outside controller mid-run: once the graph shows it gone (its
    participant's lease) and `command_timeout_s` has passed, the plant applies zero
    current, the run ends with exit 3 or 4, the summary names the fallback, and every
    state sample is in the bag."""
    path = short("ptc_nominal", tmp_path, duration_s=1.5, mode="lockstep")
    out = tmp_path / "run"
    watcher = OutsideNode(ros_env, junk=False)
    try:
        proc = start_run(path, out, "--external", "feedback")
        # The run's profile: its 5 s participant lease is how soon a killed node is seen gone.
        ctrl = start_outside(pd_controller(20.0, 0.01), tmp_path / "ctrl.log", run_profile=True)
        try:
            watcher.spin_while(lambda: watcher.step < 300 and proc.poll() is None, 60.0)
            os.killpg(ctrl.pid, signal.SIGKILL)
            killed_at = watcher.step
            code = finish(proc, RUN_TIMEOUT_S)
        finally:
            stop(ctrl)
    finally:
        watcher.close()
    assert 300 <= killed_at < 1500
    assert code in (3, 4), tails(out)
    summary = yaml.safe_load((out / "summary.json").read_text())
    kinds = [f["kind"] for f in summary["health"]["nodes"]["plant"]["fallbacks"]]
    assert "command_timeout" in kinds
    assert summary["message_counts"][f"{NS}/state"] == 1500
    assert 0 < summary["message_counts"][f"{NS}/command"] < 1500


@pytest.mark.realtime
def test_in_realtime_an_outside_controller_that_stops_answering_ends_the_run_with_exit_5(
    ros_env: int, tmp_path: Path
) -> None:
    """Realtime, the example controller (plain rclpy, default QoS) SIGKILLed mid-run of
    a 30 s run: the plant's clock goes on holding the last current, and 2 s without a
    command end the run (``loop_open``) long before its 30 s: exit 5, the reason
    first, a readable bag (issue 30: such a run once ended "complete, exit 0")."""
    path = short("ptc_nominal", tmp_path, duration_s=30.0, mode="realtime")
    out = tmp_path / "run"
    watcher = OutsideNode(ros_env, junk=False)
    try:
        proc = start_run(path, out, "--external", "feedback")
        ctrl = start_outside(pd_controller(20.0, 0.01), tmp_path / "ctrl.log")
        try:
            watcher.spin_while(lambda: watcher.step < 300 and proc.poll() is None, 60.0)
            os.killpg(ctrl.pid, signal.SIGKILL)
            killed_at = time.monotonic()
            code = finish(proc, RUN_TIMEOUT_S)
            ended_s = time.monotonic() - killed_at
        finally:
            stop(ctrl)
    finally:
        watcher.close()
    summary = yaml.safe_load((out / "summary.json").read_text())
    reasons = summary["health"]["reasons"]
    # Either way the run ended by itself, long before its 30 s, and said why.
    assert code == 5 and reasons[0].startswith("the loop was not closed"), tails(out)
    assert ended_s < 15.0  # 2 s without a command or a tick, 1 s for the recorder, the stop
    if "(clock_stalled)" in reasons[0]:
        # The host did not give the plant's clock its periods (other load):
        # what the test is about, the loop opened by the gone controller,
        # cannot be seen then.
        pytest.skip(f"this host did not keep the realtime clock: {reasons[0]}")
    assert reasons[0].startswith("the loop was not closed: plant ended the run (loop_open)")
    (fallback,) = summary["health"]["nodes"]["plant"]["fallbacks"]
    assert fallback["kind"] == "loop_open" and 300 <= fallback["step"] < 30_000
    states = summary["message_counts"][f"{NS}/state"]
    assert fallback["step"] - 10 <= states <= fallback["step"] + 1
    assert summary["realtime"]["ticks"] == fallback["step"]


# -- the examples on Ctrl-C ----------------------------------------------------------------


def test_the_examples_end_quietly_on_a_signal_while_they_work(ros_env: int, tmp_path: Path) -> None:
    """The three examples close a loop among themselves, with no run of the suite (the
    plant on its own clock, so whatever order they start in), and each gets its signal
    while busy in its callbacks: SIGTERM to the controller, SIGINT (a terminal's Ctrl-C,
    to the process group) to the generator and the plant. Each exits 0 with no traceback.
    Before, rclpy's own handler shut the context down from a thread of its own while
    the main thread still used it: ``RCLError: ... the given context is not valid`` from
    the executor or a node's constructor, in 3 of 6 repetitions here."""
    ros = ["--ros-args", "-r", f"__ns:={NS}"]
    endless = ["-p", "realtime:=true", "-p", "steps:=100000000"]
    examples = {
        "rigid_axis": [str(EXAMPLES / "rigid_axis.py"), *ros, *endless],
        "sine_reference": [str(EXAMPLES / "sine_reference.py"), *ros],
        "pd_controller": [str(EXAMPLES / "pd_controller.py"), *ros],
    }
    watcher = OutsideNode(ros_env, junk=False)
    procs = {name: start_outside(args, tmp_path / f"{name}.log") for name, args in examples.items()}
    try:
        alive = lambda: all(p.poll() is None for p in procs.values())  # noqa: E731
        watcher.spin_while(lambda: watcher.step == 0 and alive(), 120.0)
        first = watcher.step  # the plant's clock (ms), once its states come
        # 300 ms of states at 1 kHz, each taken by the generator and the controller.
        watcher.spin_while(lambda: watcher.step < first + 300 and alive(), 60.0)
        assert first > 0 and watcher.step >= first + 300, {n: p.poll() for n, p in procs.items()}
        for name, number in (("pd_controller", signal.SIGTERM), ("sine_reference", signal.SIGINT),
                             ("rigid_axis", signal.SIGINT)):  # fmt: skip
            os.killpg(procs[name].pid, number)
            code = finish(procs[name], 20.0)
            text = (tmp_path / f"{name}.log").read_text(errors="replace")
            assert code == 0 and "Traceback" not in text, (name, code, text[-3000:])
    finally:
        for proc in procs.values():
            stop(proc)
        watcher.close()


# -- the runner's own checks -------------------------------------------------------------


def test_an_outside_node_that_never_comes_ends_the_run_with_a_readable_bag(
    ros_env: int, tmp_path: Path
) -> None:
    """``--external-timeout`` counts from when the run's own nodes are up (each has reported
    on /diagnostics, the recorder once its bag is open): a timeout far shorter than any
    host's start-up (1 s; the recorder opened its bag 2.9-3.6 s after the run's start on a
    third of a core) still ends the run with its bag, readable. Before, it counted from
    the runner's start and the run ended before the recorder had made its bag."""
    path = short("ptc_nominal", tmp_path, duration_s=0.2)
    out = tmp_path / "run"
    proc = start_run(path, out, "--external", "feedback", "--external-timeout", "1")
    code = finish(proc, 120)
    text = (tmp_path / "run.out").read_text()
    assert code == 1, text
    assert "outside node did not come within --external-timeout 1 s" in text
    assert "publishes   /x/command" in text and "subscribes  /x/state" in text
    assert (out / "bag" / "metadata.yaml").is_file(), text
    from rosbags.rosbag2 import Reader

    with Reader(out / "bag") as reader:
        assert reader.message_count == sum(1 for _ in reader.messages())
    # Every node the run started was up and reported before the wait ended.
    for role in ("plant", "feedforward", "recorder"):
        assert (out / "logs" / f"{role}.health.json").is_file(), role


@pytest.mark.parametrize(
    ("role", "message"),
    [
        ("controller", "--external controller: expected one of plant, feedback"),
        ("identifier", "--external identifier: the scenario has no identifier section"),
    ],
)
def test_an_external_role_the_run_cannot_have_is_refused(
    ros_env: int, tmp_path: Path, role: str, message: str
) -> None:
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "servo_axis", "run", "ptc_nominal", "--out", str(out),
         "--external", role],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr
    assert not out.exists()
