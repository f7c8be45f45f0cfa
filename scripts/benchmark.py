#!/usr/bin/env python3
"""Benchmark: steps/s of a scenario in lockstep, against a ping-pong baseline.

Measures, in one run on this machine:

* baseline: two processes that bounce a JointState back and forth in
  lockstep (each round trip is what one plant <-> feedback step costs in
  transport and executor alone);
* the scenario with plant, feedback, feedforward and recorder as separate
  processes;
* the same composed in one process;
* the same loop as plain function calls (core only, no ROS).

Figures are printed as steps/s, as a ratio to real time at the control
period (1.0x = as fast as the real axis) and as a ratio to the baseline
measured in the same run. Each measurement is appended, dated, to
docs/history/benchmarks.md; ``--all`` and ``--quick`` also update the rows of
the scenarios they measured in the table of today's numbers at the top of
docs/benchmarks.md (``--current-from-history`` rebuilds that table from the
newest ``--all``/``--quick`` section of each scenario in the history).

    .venv/bin/python scripts/benchmark.py [--scenario config/ptc_nominal.yaml] [--duration 10]

``--all`` runs every shipped scenario (learning, identifier and two-axis ones
included) in lockstep as separate processes, composed and core only, and in
realtime as separate processes, next to the real-time floor of this machine
(``python -m servo_axis floor``, EventsExecutor, measured in the same
invocation at each period, or read with ``--floor FILE``: its ``--json``
lines). ``--quick`` does the same for the four scenarios of issue 23 only.
``--budget`` profiles one lockstep run (separate processes) and prints where
a step's time goes in each node process.

    .venv/bin/python scripts/benchmark.py --all [--duration 1] [--floor floor.jsonl]
    .venv/bin/python scripts/benchmark.py --quick
    .venv/bin/python scripts/benchmark.py --budget [--scenario config/ptc_nominal.yaml]

``--topology`` measures what the recorded graph's transport alone allows: the
ping-pong with a listener of both directions (the least a recorder costs) and a
reference stream, next to ``--scenario`` in lockstep, alternated ``--repeat`` times.

    .venv/bin/python scripts/benchmark.py --topology [--repeat 5] [--duration 2]
"""

from __future__ import annotations

import argparse
import copy
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

# Before numpy loads: the suite's small matrices run fastest on one BLAS thread.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import yaml

REPO = Path(__file__).resolve().parents[1]
PING_ROUNDS = 5000
INTRO = """# Benchmark history

Every measurement of `scripts/benchmark.py`, dated, oldest first, with the
notes written beside them. Ratios are to real time at the control period and
to a two-process ping-pong baseline measured in the same run: the machines
are shared and noisy, so only ratios within one run compare. Today's numbers
are the table of [benchmarks](../benchmarks.md).
"""

#: The markers around the table of today's numbers in docs/benchmarks.md.
CURRENT_START = "<!-- scripts/benchmark.py: today's table, start -->"
CURRENT_END = "<!-- scripts/benchmark.py: today's table, end -->"
CURRENT_COLUMNS = (
    "scenario",
    "T_u (ms)",
    "lockstep, separate: x real time (x baseline)",
    "lockstep, composed",
    "core only",
    "realtime misses (host floor)",
    "measured",
)
#: The headers of the two tables of an ``--all`` / ``--quick`` section (:func:`run_all`).
LOCK_HEADER = (
    "| scenario | T_u (ms) | separate: x real time (x baseline) | start-up / end (s) "
    "| composed | core only |"
)
RT_HEADER = (
    "| scenario | T_u (ms) | misses | floor misses | tick late p50/p99/max (us) "
    "| command late p50/p99/max (us) | rate | exit | RMS error rt / lockstep (um) "
    "| references held / late estimates |"
)


def table_count(counts: dict[str, int], name: str) -> int:
    """Messages of table topic ``name`` in a summary's counts, whatever the run's namespace."""
    from servo_axis.analysis.signals import table_name

    return sum(n for topic, n in counts.items() if table_name(topic) == name)


def child(role: str) -> None:
    """Child process of :func:`ping_pong`, until SIGINT.

    ``pong`` echoes every ``ping`` on ``pong`` and takes ``reference`` (if
    any) as bytes; ``listener`` takes ``ping``, ``pong`` and ``reference`` as
    bytes and does nothing else (the least a recorder of the streams costs
    the pair).
    """
    import rclpy
    from sensor_msgs.msg import JointState

    from servo_axis.nodes.runtime import STREAM_QOS, make_executor

    rclpy.init()
    node = rclpy.create_node(role)
    taken = ["reference"]
    if role == "pong":
        pub = node.create_publisher(JointState, "pong", STREAM_QOS)
        node.create_subscription(JointState, "ping", pub.publish, STREAM_QOS)
    else:
        taken += ["ping", "pong"]
    for topic in taken:
        node.create_subscription(JointState, topic, lambda _: None, STREAM_QOS, raw=True)
    ex = make_executor()
    ex.add_node(node)
    try:
        while rclpy.ok():
            ex.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def ping_pong(env: dict[str, str], listeners: int = 0, reference: bool = False) -> float:
    """Round trips per second between this process and a ``pong`` process, with
    ``listeners`` more processes taking every stream (:func:`child`) and, with
    ``reference``, one more JointState per round trip to ``pong`` and the listeners (the
    reference a feedback takes each step)."""
    os.environ.update(env)
    import rclpy
    from sensor_msgs.msg import JointState

    from servo_axis.nodes.runtime import STREAM_QOS, make_executor
    from servo_axis.wire import messages as msgs

    children = [
        subprocess.Popen(
            [sys.executable, __file__, flag],
            env=env,
            start_new_session=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for flag in ["--pong"] + ["--listener"] * listeners
    ]
    rclpy.init()
    node = rclpy.create_node("ping")
    pub = node.create_publisher(JointState, "ping", STREAM_QOS)
    got = [0]
    node.create_subscription(
        JointState, "pong", lambda m: got.__setitem__(0, got[0] + 1), STREAM_QOS
    )
    ex = make_executor()
    ref_pub = node.create_publisher(JointState, "reference", STREAM_QOS) if reference else None
    ex.add_node(node)
    try:
        while (
            pub.get_subscription_count() < 1 + listeners
            or (ref_pub is not None and ref_pub.get_subscription_count() < 1 + listeners)
            or node.count_publishers("pong") < 1
            or node.count_subscribers("pong") < 1 + listeners
        ):
            ex.spin_once(timeout_sec=0.05)
        time.sleep(0.5)  # the reverse direction matches a little later
        state = msgs.StateSample(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        ref = JointState(name=["x_motor"], position=[0.0], velocity=[0.0], effort=[0.0])

        def bounce(n: int) -> None:
            for k in range(n):
                if ref_pub is not None:
                    ref_pub.publish(ref)
                pub.publish(msgs.state_to_msg(state, axis="x", period_ns_=1_000_000))
                while got[0] <= k + offset[0]:
                    ex.spin_once(timeout_sec=1.0)

        offset = [-1]
        bounce(200)  # warm-up
        offset[0] = got[0] - 1
        t0 = time.perf_counter()
        bounce(PING_ROUNDS)
        return PING_ROUNDS / (time.perf_counter() - t0)
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        for child in children:
            child.send_signal(2)
            child.wait(timeout=10)


def write_section(out: Path, title: str, section: str) -> None:
    """Append ``section`` (which starts with ``title``) to the history ``out``, the title dated.

    The file keeps the history: an earlier section with the same title stays.
    """
    dated = f"{title.rstrip()} ({time.strftime('%Y-%m-%d %H:%M')})\n"
    body = section[len(title) :] if section.startswith(title) else "\n" + section
    old = out.read_text() if out.exists() else INTRO
    out.write_text(old.rstrip("\n") + "\n\n" + dated + body.rstrip("\n") + "\n")
    print(f"\nwritten to {out}")


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _table_after(text: str, header: str) -> list[list[str]]:
    """The rows of the first table of ``text`` whose header line is ``header``."""
    lines = text.splitlines()
    if header not in lines:
        return []
    rows = []
    for line in lines[lines.index(header) + 2 :]:
        if not line.startswith("|"):
            break
        rows.append(_cells(line))
    return rows


def current_row(
    name: str,
    period_ms: str,
    separate: str,
    composed: str,
    core: str,
    misses: str,
    measured: str,
) -> list[str]:
    """One row of today's table (the cells as they are shown)."""
    return [name, period_ms, separate, composed, core, misses, measured]


def rows_from_section(section: str, measured: str) -> dict[str, list[str]]:
    """Today's rows from an ``--all`` / ``--quick`` section of the history (its two tables).

    ``measured`` is what the rows' last cell says (when, at which commit, which mode).
    """
    realtime = {r[0]: r for r in _table_after(section, RT_HEADER)}
    rows = {}
    for r in _table_after(section, LOCK_HEADER):
        name, period, separate, _, composed, core = r[:6]
        rt = realtime.get(name)
        if rt and " of " in rt[2]:
            pct = rt[2][rt[2].index("(") + 1 : rt[2].index(")")]
            misses = f"{pct} ({rt[3]})"
        else:
            misses = "-"
        short = composed.split(":")[0] if composed.startswith("n/a") else composed
        rows[name] = current_row(name, period, separate, short, core, misses, measured)
    return rows


def read_current(page_text: str) -> dict[str, list[str]]:
    """The rows of today's table in the benchmarks page, by scenario."""
    if CURRENT_START not in page_text:
        return {}
    block = page_text[page_text.index(CURRENT_START) : page_text.index(CURRENT_END)]
    header = "| " + " | ".join(CURRENT_COLUMNS) + " |"
    return {r[0]: r for r in _table_after(block, header)}


def render_current(rows: dict[str, list[str]]) -> str:
    """Today's table, one row per scenario in name order, between its markers."""
    lines = [
        CURRENT_START,
        "",
        "| " + " | ".join(CURRENT_COLUMNS) + " |",
        "|" + " --- |" * len(CURRENT_COLUMNS),
        *("| " + " | ".join(rows[name]) + " |" for name in sorted(rows)),
        "",
        CURRENT_END,
    ]
    return "\n".join(lines)


def update_current(page: Path, new: dict[str, list[str]]) -> None:
    """Put ``new`` into today's table of ``page`` (other scenarios' rows stay)."""
    text = page.read_text() if page.exists() else "# Benchmarks\n"
    rows = {**read_current(text), **new}
    table = render_current(rows)
    if CURRENT_START in text:
        head = text[: text.index(CURRENT_START)]
        tail = text[text.index(CURRENT_END) + len(CURRENT_END) :]
        text = head + table + tail
    else:
        text = text.rstrip("\n") + "\n\n" + table + "\n"
    page.write_text(text)
    print(f"today's table in {page}: {len(new)} row(s) updated, {len(rows)} in all")


def sections_of(history: str) -> list[tuple[str, str]]:
    """``(title, body)`` of each ``## `` section of the history, oldest first."""
    parts = re.split(r"^## ", history, flags=re.MULTILINE)[1:]
    return [(p.split("\n", 1)[0], p.split("\n", 1)[1] if "\n" in p else "") for p in parts]


def measured_label(title: str, body: str) -> str:
    """When and at which commit a section was measured, and which mode (``--all``)."""
    when = re.search(r"\((\d{4}-\d\d-\d\d \d\d:\d\d)\)\s*$", title)
    commit = re.search(r"\bat ([0-9a-f]{7,12})\b", title + " " + body[:400])
    mode = "--quick" if "(--quick)" in title else "--all"
    return ", ".join([when.group(1) if when else "?", *([commit.group(1)] if commit else []), mode])


def current_from_history(history: str) -> dict[str, list[str]]:
    """Today's rows from the history alone: per scenario, its newest ``--all``/``--quick`` row."""
    rows: dict[str, list[str]] = {}
    for title, body in sections_of(history):
        if title.startswith("every scenario (--all") or title.startswith("every scenario (--quick"):
            rows.update(rows_from_section(body, measured_label(title, body)))
    return rows


def git_commit() -> str:
    """The checkout's short commit, ``+dirty`` with uncommitted changes; ``?`` outside git."""
    try:
        head = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"
    return head + ("+dirty" if dirty else "")


def learning_cost(
    args: argparse.Namespace,
    data: dict,
    scenario: Path,
    tmp: Path,
    domain: int,
    steps: int,
    period: float,
) -> int:
    """Steps/s with and without the learning unit as its own process (issue 3's < 15 % budget)."""
    if "learning" not in data:
        raise SystemExit("--learning-cost needs a scenario with a learning section")
    plain = copy.deepcopy(data)
    del plain["learning"]
    plain["feedforward"]["ros__parameters"]["learning"]["enabled"] = False
    without = tmp / f"without_{scenario.name}"
    without.write_text(yaml.safe_dump(plain))
    rates, samples, r = alternate(
        [("without learning unit", without), ("with learning unit", scenario)],
        args.repeat,
        tmp,
        domain,
    )
    base = rates["without learning unit"]
    with_ = rates["with learning unit"]
    table_text = "\n".join(
        [
            f"| {'case (separate processes, recorder on)':<40} | {'steps/s':>10} | {'x real time':>11} |",
            f"|{'-' * 42}|{'-' * 12}|{'-' * 13}|",
            *(f"| {n:<40} | {v:>10,.0f} | {v * period:>10.2f}x |" for n, v in rates.items()),
        ]
    )
    spread = "; ".join(
        f"{n}: " + ", ".join(f"{v:,.0f}" for v in vals) for n, vals in samples.items()
    )
    periods = table_count(r.summary.message_counts, "learning/cycle_stats")
    stall_ms = 1e3 * (steps / with_ - steps / base) / max(periods, 1)
    law_ms = law_cost_ms(data, scenario)
    text = (
        f"{table_text}\n\nMedians of {args.repeat} alternating runs ({spread} steps/s).\n"
        f"Cost of the learning unit: {100 * (1 - with_ / base):.1f} % of the steps/s; "
        f"{periods} period boundaries per run, so {stall_ms:.1f} ms of wall time per boundary "
        f"(the loop stands still there until the next correction is in), against "
        f"{1e3 / base:.3f} ms per step without learning. Of that, the law itself "
        f"(learn + next correction, in-process, median of 20): {law_ms:.2f} ms.\n"
    )
    print()
    print(text)
    out = Path(args.history)
    command = (
        f"`.venv/bin/python scripts/benchmark.py --scenario config/{scenario.name} "
        f"--duration {args.duration:g} --learning-cost --repeat {args.repeat}`"
    )
    when = time.strftime("%Y-%m-%d %H:%M")
    section = (
        f"## learning unit cost ({scenario.stem})\n\n{steps} steps per run, measured {when}.\n"
        f"Command: {command}\n\n{text}"
    )
    write_section(out, f"## learning unit cost ({scenario.stem})\n", section)
    return 0


def alternate(
    cases: list[tuple[str, Path]], repeat: int, tmp: Path, domain: int
) -> tuple[dict[str, float], dict[str, list[float]], Any]:
    """Median steps/s of each case, run alternately ``repeat`` times (the host is noisy)."""
    from servo_axis.run.runner import RunOptions, run_scenario

    samples: dict[str, list[float]] = {name: [] for name, _ in cases}
    last = None
    for rep in range(repeat):
        for name, path in cases:
            print(f"{name}, run {rep + 1} of {repeat} ...", flush=True)
            out_dir = tmp / f"{name.replace(' ', '_').replace(',', '')}_{rep}"
            last = run_scenario(
                path, RunOptions(out_dir=out_dir, domain_id=domain, progress=None, plots=False)
            )
            samples[name].append(last.summary.steps_per_s)
    rates = {name: float(sorted(v)[len(v) // 2]) for name, v in samples.items()}
    return rates, samples, last


def identifier_cost(
    args: argparse.Namespace, data: dict, scenario: Path, tmp: Path, domain: int, steps: int,
    period: float,
) -> int:  # fmt: skip
    """Steps/s of an identifier scenario with and without its identifier (issue 9)."""
    from servo_axis.run.processes import ros_environment
    from servo_axis.simulate import simulate, simulate_identification

    if "identifier" not in data:
        raise SystemExit("--identifier-cost needs a scenario with an identifier section")
    # Without: the same PTC + MNC on the initial estimates, no identifier.
    plain = copy.deepcopy(data)
    del plain["identifier"]
    without = tmp / f"without_{scenario.name}"
    without.write_text(yaml.safe_dump(plain))
    no_memory = copy.deepcopy(data)
    no_memory["identifier"]["ros__parameters"].setdefault("memory", {})["file"] = ""
    unpersisted = tmp / f"no_memory_{scenario.name}"
    unpersisted.write_text(yaml.safe_dump(no_memory))
    print("ping-pong baseline (2 processes) ...", flush=True)
    baseline = ping_pong(ros_environment(domain, tmp))
    cases = [
        ("without identifier", without),
        ("with identifier", scenario),
        ("with identifier, no memory file", unpersisted),
    ]
    rates, samples, last = alternate(cases, args.repeat, tmp, domain)
    core_without = core_steps_per_s(simulate, without, steps)
    core_with = core_steps_per_s(simulate_identification, scenario, steps)
    rows = [
        ("baseline: 2-process ping-pong", baseline),
        *((f"{n} (separate, recorder on)", v) for n, v in rates.items()),
        ("core only, without identifier", core_without),
        ("core only, with identifier", core_with),
    ]
    table_text = "\n".join(
        [
            f"| {'case':<45} | {'steps/s':>10} | {'x real time':>11} | {'x baseline':>10} |",
            f"|{'-' * 47}|{'-' * 12}|{'-' * 13}|{'-' * 12}|",
            *(
                f"| {n:<45} | {v:>10,.0f} | {v * period:>10.2f}x | {v / baseline:>9.2f}x |"
                for n, v in rows
            ),
        ]
    )
    spread = "; ".join(
        f"{n}: " + ", ".join(f"{v:,.0f}" for v in vals) for n, vals in samples.items()
    )
    base, with_ = rates["without identifier"], rates["with identifier"]
    estimates = table_count(last.summary.message_counts, "identifier/estimates")
    text = (
        f"{table_text}\n\nMedians of {args.repeat} alternating runs ({spread} steps/s).\n"
        f"Cost of the identifier: {100 * (1 - with_ / base):.1f} % of the steps/s "
        f"({estimates} estimates per run, one per {steps // max(estimates, 1)} steps); "
        f"persisting its state after every estimate: "
        f"{100 * (1 - with_ / rates['with identifier, no memory file']):.1f} %.\n"
    )
    print()
    print(text)
    command = (
        f"`.venv/bin/python scripts/benchmark.py --scenario config/{scenario.name} "
        f"--duration {args.duration:g} --identifier-cost --repeat {args.repeat}`"
    )
    when = time.strftime("%Y-%m-%d %H:%M")
    title = f"## identifier cost ({scenario.stem})\n"
    section = f"{title}\n{steps} steps per run, measured {when}.\nCommand: {command}\n\n{text}"
    write_section(Path(args.history), title, section)
    return 0


def law_cost_ms(data: dict, scenario: Path) -> float:
    """Median wall time (ms) of one ``learn`` + ``next_correction`` of the scenario's law, in-process."""
    import numpy as np

    from servo_axis.params import factories, resolve

    law = factories.build_learning_law(resolve.node_values(data, "learning"))
    rng = np.random.default_rng(0)
    times = []
    for trial in range(1, 21):
        error = 1e-6 * rng.standard_normal(law.samples_per_period)
        t0 = time.perf_counter()
        law.learn(error / (1.0 if law.side == "input" else 1.91e-3), period=trial)
        law.next_correction(period=trial + 1)
        times.append(time.perf_counter() - t0)
    return 1e3 * float(sorted(times)[len(times) // 2])


#: The scenarios of issue 23's realtime target (``--quick``).
QUICK = ("ptc_nominal", "rptc_detailed", "fast_reversal_sigmoid", "dlpid_tilt_lpf2")


def prepared(src: Path, tmp: Path, duration: float, **shared: Any) -> tuple[Path, dict]:
    """``src`` written to ``tmp`` with ``duration_s`` capped at ``duration``, files by absolute
    path and ``shared`` set under ``/**`` (e.g. ``mode="realtime"``)."""
    from servo_axis.params.scenario import load_scenario

    data = load_scenario(src)
    common = data.setdefault("/**", {"ros__parameters": {}})["ros__parameters"]
    common["duration_s"] = min(float(common.get("duration_s", duration)), duration)
    common.update(shared)
    for section in data.values():
        params = section.get("ros__parameters", {}) if isinstance(section, dict) else {}
        for sub in params.values():
            if isinstance(sub, dict):
                name = sub.get("file")
                if isinstance(name, str) and name and not Path(name).is_absolute():
                    if (src.parent / name).exists():
                        sub["file"] = str(src.resolve().parent / name)
    suffix = "_".join(f"{k}" for k in shared) or "lockstep"
    out = tmp / f"{src.stem}_{suffix}.yaml"
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out, data


def measure_floor(periods_us: list[int], ticks: int, domain_id: int) -> dict[int, dict]:
    """The floor (``python -m servo_axis floor``, EventsExecutor) at each period, by period in us.

    In ROS domain ``domain_id`` (the runs' when none runs meanwhile).
    """
    from servo_axis.run.floor import FloorError, FloorOptions, measure

    options = FloorOptions(ticks=ticks, executor="events", domain_id=domain_id)
    out: dict[int, dict] = {}
    for p in periods_us:
        print(f"real-time floor at {p} us (servo_axis floor, events) ...", flush=True)
        try:
            out[p] = measure(p, options)
        except FloorError as err:
            print(f"the floor failed at {p} us: {err}", flush=True)
    return out


def read_floor(path: Path) -> dict[int, dict]:
    """The floor from a file of ``python -m servo_axis floor --json`` lines, by period in us."""
    from servo_axis.run.floor import read_floor as read

    return read(path)


def one_run(scenario: Path, out_dir: Path, domain: int, composed: bool = False) -> Any:
    """A run's summary, or the first line of why it failed (a string)."""
    from servo_axis.run.runner import RunOptions, run_scenario

    try:
        options = RunOptions(
            out_dir=out_dir, composed=composed, domain_id=domain, progress=None, plots=False
        )
        r = run_scenario(scenario, options)
    except Exception as err:  # a row of the table says why
        return f"{type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}"[:90]
    return r.summary


def core_steps_per_s(fn: Callable[..., object], scenario: Path, steps: int) -> float:
    """Steps/s of ``fn(scenario, steps=steps)``, after an untimed call of a few steps.

    As in scripts/core_speed.py: the first call loads the compiled kernels
    (0.35 s for the elastic screw), which made a 1 s ``rptc_detailed`` read
    6x real time instead of about 60x.
    """
    fn(scenario, steps=min(steps, 10))
    t0 = time.perf_counter()
    fn(scenario, steps=steps)
    return steps / (time.perf_counter() - t0)


def core_rate(scenario: Path, data: dict) -> float | str:
    """Steps/s of the scenario's loop as plain calls (the simulate function that fits it)."""
    from servo_axis import simulate as sim

    fn = sim.simulate
    if "identifier" in data:
        fn = sim.simulate_identification  # type: ignore[assignment]
    elif "learning" in data:
        fn = sim.simulate_learning  # type: ignore[assignment]
    common = data["/**"]["ros__parameters"]
    period = float(common.get("control_period_s", 1e-3))
    steps = round(common["duration_s"] / period)
    try:
        return core_steps_per_s(fn, scenario, steps)
    except Exception as err:  # a cell of the table says why
        return f"{type(err).__name__}"


def around_steps(s: Any) -> str | None:
    """``start-up / end`` seconds of a run (the first axis's for a multi-axis run), or None."""
    axes = getattr(s, "axes", None)
    one = next(iter(axes.values())) if axes else s
    if getattr(one, "startup_s", None) is None or one.finish_s is None:
        return None
    return f"{one.startup_s:.2f} / {one.finish_s:.2f}"


def steps_per_s(s: Any) -> float:
    """Steps/s of a summary (a two-axis one: its slowest axis)."""
    axes = getattr(s, "axes", None)
    if isinstance(axes, dict) and axes:
        return min(float(a.steps_per_s) for a in axes.values())
    return float(s.steps_per_s)


def realtime_cells(s: Any) -> dict[str, Any]:
    """Misses and lateness of a realtime summary (single or two-axis)."""
    rts = [s.realtime] if getattr(s, "realtime", None) else []
    rts += [a.realtime for a in getattr(s, "axes", {}).values() if getattr(a, "realtime", None)]
    if not rts:
        return status_misses(s)
    rt = max(rts, key=lambda r: r.misses)
    return {
        "misses": rt.misses,
        "ticks": rt.ticks,
        "miss_pct": 100 * rt.misses / max(rt.ticks, 1),
        "tick": rt.tick_late_us,
        "command": rt.command_late_us,
        "rate": rt.timer_rate,
        "late": "/".join(
            "-" if v is None else str(v) for v in (rt.references_held, rt.late_estimates)
        ),
    }


def status_misses(s: Any) -> dict[str, Any]:
    """Misses from the last ``plant/status`` of the bag (a summary without ``realtime``)."""
    from servo_axis.recording.deserialize import read_messages

    run_dir = getattr(s, "_run_dir", None)
    if run_dir is None:
        return {}
    topics = [t for t in s.message_counts if t.endswith("plant/status")]
    last = None
    for m in read_messages(Path(run_dir) / "bag", topics=topics):
        last = m.message.data
    if last is None:
        return {}
    ticks = round(s.steps)
    return {
        "misses": int(last[1]), "ticks": ticks, "miss_pct": 100 * last[1] / max(ticks, 1),
        "tick": None, "command": None, "rate": float("nan"),
    }  # fmt: skip


def _pct(d: dict | None) -> str:
    if not d:
        return "-"
    return f"{d['p50']:.0f}/{d['p99']:.0f}/{d['max']:.0f}"


def bench_domain(args: argparse.Namespace) -> int:
    """The ROS domain of this invocation: ``--domain-id``, or one of 60..89 by pid (a
    second benchmark or a test suite beside it picks another with ``--domain-id``)."""
    return args.domain_id if args.domain_id is not None else 60 + os.getpid() % 30


def run_all(args: argparse.Namespace) -> int:
    """``--all`` / ``--quick``: the one table of every scenario and the realtime figures."""
    from servo_axis.params.scenario import axes_of
    from servo_axis.run.processes import ros_environment

    names = QUICK if args.quick else tuple(sorted(p.stem for p in (REPO / "config").glob("*.yaml")))
    if args.only:
        names = tuple(args.only.split(","))
    tmp = Path(tempfile.mkdtemp(prefix="servo_axis_bench_all_"))
    domain = bench_domain(args)
    env = ros_environment(domain, tmp)
    started = time.monotonic()
    print("ping-pong baseline (2 processes) ...", flush=True)
    base = ping_pong(env)
    rows = []
    periods: set[int] = set()
    for name in names:
        src = REPO / "config" / f"{name}.yaml"
        lock, data = prepared(src, tmp, args.duration)
        rt, _ = prepared(src, tmp, args.duration, mode="realtime")
        common = data["/**"]["ros__parameters"]
        period = float(common.get("control_period_s", 1e-3))
        periods.add(round(period * 1e6))
        row: dict[str, Any] = {"name": name, "period": period}
        for case, composed in (("separate", False), ("composed", True)):
            if composed and axes_of(data):
                row[case] = "n/a: a multi-axis run has separate processes only"
                continue
            print(f"{name}: lockstep {case} ...", flush=True)
            s = one_run(lock, tmp / f"{name}_{case}", domain, composed)
            row[case] = s if isinstance(s, str) else steps_per_s(s)
            if case == "separate" and not isinstance(s, str):
                row["lock_rms"] = (
                    s.tracking_error.all_samples.rms_m if hasattr(s, "tracking_error") else None
                )
                row["unit"] = getattr(s, "unit", "m")
                row["around"] = around_steps(s)
        print(f"{name}: core only ...", flush=True)
        row["core"] = core_rate(lock, data)
        print(f"{name}: realtime separate ...", flush=True)
        s = one_run(rt, tmp / f"{name}_rt", domain)
        if not isinstance(s, str):
            object.__setattr__(s, "_run_dir", tmp / f"{name}_rt")
        if isinstance(s, str):
            row["rt"] = s
        else:
            row["rt"] = realtime_cells(s)
            row["rt_exit"] = s.health.exit_code if s.health else None
            row["rt_rms"] = (
                s.tracking_error.all_samples.rms_m if hasattr(s, "tracking_error") else None
            )
            row["rt_factor"] = steps_per_s(s) * period
        rows.append(row)
    floor = (
        read_floor(Path(args.floor))
        if args.floor
        else measure_floor(sorted(periods), 10000, domain)
    )
    elapsed = time.monotonic() - started

    def rate(v: Any, period: float) -> str:
        if isinstance(v, str):
            return v
        return f"{v * period:.2f}x ({v / base:.2f})"

    lock_lines = [
        "| scenario | T_u (ms) | separate: x real time (x baseline) | start-up / end (s) "
        "| composed | core only |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    rt_lines = [
        "| scenario | T_u (ms) | misses | floor misses | tick late p50/p99/max (us) "
        "| command late p50/p99/max (us) | rate | exit | RMS error rt / lockstep "
        "| references held / late estimates |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        per = row["period"]
        core = row["core"]
        core_text = core if isinstance(core, str) else f"{core * per:.1f}x"
        lock_lines.append(
            f"| {row['name']} | {per * 1e3:g} | {rate(row['separate'], per)} | "
            f"{row.get('around') or '-'} | {rate(row['composed'], per)} | {core_text} |"
        )
        rt = row["rt"]
        fl = floor.get(round(per * 1e6))
        fl_text = f"{fl['miss_pct']:.2f} %" if fl else "-"
        if isinstance(rt, str) or not rt:
            rt_lines.append(
                f"| {row['name']} | {per * 1e3:g} | {rt or 'no figures'} | {fl_text} | | | | | | |"
            )
            continue
        from servo_axis.analysis.units import position_error

        error = position_error(row.get("unit", "m"))  # um, rad on a rotary table
        errs = (
            "/".join(error.format(v, ".3g") for v in (row.get("rt_rms"), row.get("lock_rms")))
            + f" {error.unit}"
        )
        rt_lines.append(
            f"| {row['name']} | {per * 1e3:g} | {rt['misses']} of {rt['ticks']} "
            f"({rt['miss_pct']:.2f} %) | {fl_text} | {_pct(rt['tick'])} | {_pct(rt['command'])} | "
            f"{rt['rate']:.4f} | {row['rt_exit']} | {errs} | {rt.get('late', '-')} |"
        )
    floor_lines = [
        "| period (us) | misses | tick late p50/p99/max (us) | round trip p50/p99/max (us) |",
        "| --- | --- | --- | --- |",
        *(
            f"| {p} | {f['misses']} of {f['ticks']} ({f['miss_pct']:.2f} %) | "
            f"{_pct(f['tick_late_us'])} | {_pct(f['round_trip_us'])} |"
            for p, f in sorted(floor.items())
        ),
    ]
    text = (
        f"Baseline (2-process ping-pong): {base:,.0f} round trips/s. Lockstep cells: x real time "
        f"(x baseline), from state 0 to the last step; the run's start-up (discovery, "
        f"handshakes) and end (the recorder catching up, the exit) are given apart.\n\n"
        + "\n".join(lock_lines)
        + "\n\nRealtime, separate processes, "
        "recorder on (misses: ticks whose command had not arrived by the deadline; lateness: "
        "tick = when the plant stepped after its deadline, command = arrival after the tick of "
        "the state it answers; rate = ticks per period of wall time):\n\n"
        + "\n".join(rt_lines)
        + "\n\nFloor (servo_axis floor, EventsExecutor, "
        + ("read from " + Path(args.floor).name if args.floor else "measured in this invocation")
        + "):\n\n"
        + "\n".join(floor_lines)
        + "\n"
    )
    print()
    print(text)
    print(f"({elapsed:.0f} s)")
    which = "--quick" if args.quick else "--all"
    when = time.strftime("%Y-%m-%d %H:%M")
    commit = git_commit()
    title = f"## every scenario ({which}) at {commit}\n"
    section = (
        f"{title}\nMeasured {when} on {platform.node()} ({os.cpu_count()} cores), at most "
        f"{args.duration:g} simulated s per run, {elapsed / 60:.1f} min in all.\n"
        f"Command: `.venv/bin/python scripts/benchmark.py {which} --duration {args.duration:g}"
        f"{' --floor ' + Path(args.floor).name if args.floor else ''}`\n\n{text}"
    )
    write_section(Path(args.history), title, section)
    update_current(Path(args.out), rows_from_section(text, f"{when}, {commit}, {which}"))
    return 0


#: Budget categories: (label, test on a pstats key ``(file, line, name)``), first match wins.
BUDGET = (
    ("wait + transport (executor, C)", lambda f, n: f == "~" and "spin_once" in n),
    ("publish (serialise + write, C)", lambda f, n: f == "~" and "publish" in n),
    ("messages: decode/encode/validate", lambda f, n: "servo_axis/wire/" in f),
    ("physics + control laws (core)", lambda f, n: "servo_axis/core/" in f),
    (
        "recorder writing (recording, mcap)",
        lambda f, n: "servo_axis/recording/" in f or "/mcap/" in f,
    ),
    ("node logic (nodes)", lambda f, n: "servo_axis/nodes/" in f),
    ("rclpy Python", lambda f, n: "/rclpy/" in f),
)


def budget_of(prof: Path, steps: int) -> dict[str, float]:
    """Microseconds per step of each :data:`BUDGET` category in one profile (``other``: the rest)."""
    import pstats

    st = pstats.Stats(str(prof))
    out = {label: 0.0 for label, _ in BUDGET}
    out["other Python"] = 0.0
    for (file, _line, name), (_cc, _nc, tt, _ct, _callers) in st.stats.items():  # type: ignore[attr-defined]
        label = next((lb for lb, test in BUDGET if test(file, name)), "other Python")
        out[label] += 1e6 * tt / steps
    return out


def budget(args: argparse.Namespace) -> int:
    """``--budget``: a lockstep run (separate processes) under cProfile; us per step per node."""
    from servo_axis.run.runner import RunOptions, run_scenario

    tmp = Path(tempfile.mkdtemp(prefix="servo_axis_budget_"))
    scenario, data = prepared(Path(args.scenario), tmp, args.duration)
    common = data["/**"]["ros__parameters"]
    steps = round(common["duration_s"] / common.get("control_period_s", 1e-3))
    prof_dir = tmp / "profiles"
    prof_dir.mkdir()
    domain = bench_domain(args)
    plain = run_scenario(
        scenario, RunOptions(out_dir=tmp / "plain", domain_id=domain, progress=None, plots=False)
    )
    os.environ["SERVO_AXIS_PROFILE"] = str(prof_dir)
    try:
        r = run_scenario(
            scenario, RunOptions(out_dir=tmp / "prof", domain_id=domain, progress=None, plots=False)
        )
    finally:
        del os.environ["SERVO_AXIS_PROFILE"]
    profs = sorted(prof_dir.glob("*.prof"))
    per = {p.stem.split(".")[0]: budget_of(p, steps) for p in profs}
    roles = sorted(per)
    labels = [lb for lb, _ in BUDGET] + ["other Python"]
    lines = [
        "| us per step | " + " | ".join(roles) + " |",
        "| --- |" + " --- |" * len(roles),
        *(f"| {lb} | " + " | ".join(f"{per[r][lb]:.0f}" for r in roles) + " |" for lb in labels),
        "| total (profiled) | " + " | ".join(f"{sum(per[r].values()):.0f}" for r in roles) + " |",
    ]
    text = (
        f"Unprofiled: {plain.summary.steps_per_s:,.0f} steps/s ({1e6 / plain.summary.steps_per_s:.0f} "
        f"us per step); profiled: {r.summary.steps_per_s:,.0f} steps/s. cProfile inflates "
        "Python-heavy items (about 2x); read the table as shares.\n\n" + "\n".join(lines) + "\n"
    )
    print()
    print(text)
    return 0


def topology(args: argparse.Namespace) -> int:
    """``--topology``: the ping-pong with listeners of both directions and a reference
    stream, and ``--scenario`` in lockstep (separate processes, recorder on), alternated
    ``--repeat`` times.

    A listener takes each message as bytes and does nothing else: the least a
    recorder costs the pair. The reference stream is one more JointState per
    round trip to the pong and the listener, as a feedforward's reference is
    each step (published here by the ping itself, on the round trip's path).
    The pair's rate with them bounds what a lockstep run with its recorder can
    reach in x baseline, whatever its nodes do.
    """
    from servo_axis.run.processes import ros_environment

    tmp = Path(tempfile.mkdtemp(prefix="servo_axis_bench_topology_"))
    domain = bench_domain(args)
    env = ros_environment(domain, tmp)
    scenario, _ = prepared(Path(args.scenario), tmp, args.duration)
    rates: dict[str, list[float]] = {}
    cases = {
        "ping-pong (the baseline)": (0, False),
        "ping-pong, a listener of both": (1, False),
        "ping-pong, a listener of both, a reference stream": (1, True),
        "ping-pong, 2 listeners of both": (2, False),
    }
    name = Path(args.scenario).stem
    for r in range(args.repeat):
        for case, (listeners, reference) in cases.items():
            print(f"{case} ({r + 1}/{args.repeat}) ...", flush=True)
            rates.setdefault(case, []).append(run_child_ping_pong(env, listeners, reference))
        print(f"{name} ({r + 1}/{args.repeat}) ...", flush=True)
        summary = one_run(scenario, tmp / f"run{r}", domain)
        rates.setdefault(f"{name}, separate processes, recorder on", []).append(
            steps_per_s(summary) if not isinstance(summary, str) else float("nan")
        )
    lines = [
        f"| {'case':<52} | {'round trips or steps/s':>24} | {'x baseline (same repeat)':>24} |",
        f"|{'-' * 54}|{'-' * 26}|{'-' * 26}|",
    ]
    base = rates["ping-pong (the baseline)"]
    for case, values in rates.items():
        ratios = [v / b for v, b in zip(values, base, strict=True)]
        lines.append(
            f"| {case:<52} | {min(values):>11,.0f} - {max(values):<10,.0f} "
            f"| {min(ratios):>11.2f} - {max(ratios):<10.2f} |"
        )
    floor_case = "ping-pong, a listener of both, a reference stream"
    run_case = f"{name}, separate processes, recorder on"
    of_floor = [v / f for v, f in zip(rates[run_case], rates[floor_case], strict=True)]
    lines.append(
        f"\n{name} / the ping-pong with a listener and a reference stream (the recorded "
        f"graph's transport alone), same repeat: {min(of_floor):.2f} - {max(of_floor):.2f}"
    )
    text = "\n".join(lines)
    print()
    print(text)
    scen = Path(args.scenario).resolve()
    shown = scen.relative_to(REPO) if scen.is_relative_to(REPO) else scen
    write_section(
        Path(args.history),
        "## lockstep transport: the ping-pong with listeners",
        f"`scripts/benchmark.py --topology --scenario {shown} "
        f"--duration {args.duration:g} --repeat {args.repeat}` on {platform.node()} "
        f"({os.cpu_count()} CPUs): ranges over the repeats; each ratio is to the two-process "
        f"ping-pong of the same repeat.\n\n{text}\n",
    )
    return 0


def run_child_ping_pong(env: dict[str, str], listeners: int, reference: bool) -> float:
    """:func:`ping_pong` in a process of its own (rclpy is initialised once per process)."""
    out = subprocess.run(
        [sys.executable, __file__, "--ping-pong", str(listeners)]
        + (["--with-reference"] if reference else []),
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        check=True,
    )
    return float(out.stdout.split()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--scenario", default=str(REPO / "config" / "ptc_nominal.yaml"))
    parser.add_argument("--duration", type=float, default=10.0, help="simulated seconds per run")
    parser.add_argument(
        "--out",
        default=str(REPO / "docs" / "benchmarks.md"),
        help="the page whose table of today's numbers --all/--quick update",
    )
    parser.add_argument(
        "--history",
        default=str(REPO / "docs" / "history" / "benchmarks.md"),
        help="the file every measurement is appended to, dated",
    )
    parser.add_argument(
        "--current-from-history",
        action="store_true",
        help="instead: rewrite today's table of --out from the newest --all/--quick "
        "section of each scenario in --history (nothing is measured)",
    )
    parser.add_argument(
        "--learning-cost",
        action="store_true",
        help="instead: steps/s of a learning scenario with and without its learning unit",
    )
    parser.add_argument(
        "--identifier-cost",
        action="store_true",
        help="instead: steps/s of an identifier scenario with and without its identifier",
    )
    parser.add_argument("--repeat", type=int, default=3, help="runs per case for the costs")
    parser.add_argument("--pong", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--listener", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--ping-pong", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--with-reference", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument(
        "--topology",
        action="store_true",
        help="instead: the ping-pong with listeners and a reference stream, next to --scenario",
    )
    parser.add_argument(
        "--all", action="store_true", help="every shipped scenario, lockstep and realtime"
    )
    parser.add_argument(
        "--quick", action="store_true", help="as --all for the four scenarios of issue 23"
    )
    parser.add_argument(
        "--floor",
        help="`python -m servo_axis floor --json` output to use instead of measuring",
    )
    parser.add_argument("--only", help="with --all: these scenarios (comma-separated names)")
    parser.add_argument(
        "--domain-id",
        type=int,
        choices=range(233),
        metavar="0..232",
        help="ROS domain of the runs (default: one of 60..89 by process id)",
    )
    parser.add_argument(
        "--budget", action="store_true", help="where a lockstep step's time goes (profiled run)"
    )
    args = parser.parse_args()
    if args.current_from_history:
        rows = current_from_history(Path(args.history).read_text())
        page = Path(args.out)
        text = page.read_text()
        if CURRENT_START in text:  # rebuilt whole: no row of an older table survives
            text = (
                text[: text.index(CURRENT_START)]
                + render_current({})
                + text[text.index(CURRENT_END) + len(CURRENT_END) :]
            )
            page.write_text(text)
        update_current(page, rows)
        return 0
    if args.pong or args.listener:
        child("pong" if args.pong else "listener")
        return 0
    if args.ping_pong is not None:
        print(ping_pong(dict(os.environ), args.ping_pong, args.with_reference))
        return 0
    if args.topology:
        if args.duration == 10.0:
            args.duration = 2.0
        return topology(args)
    if args.all or args.quick:
        if args.duration == 10.0:
            args.duration = 1.0
        return run_all(args)
    if args.budget:
        return budget(args)

    from servo_axis.params.scenario import load_scenario
    from servo_axis.run.processes import ros_environment
    from servo_axis.run.runner import RunOptions, run_scenario
    from servo_axis.simulate import simulate

    tmp = Path(tempfile.mkdtemp(prefix="servo_axis_bench_"))
    data = load_scenario(Path(args.scenario))
    data["/**"]["ros__parameters"]["duration_s"] = args.duration
    ff = data.get("feedforward", {}).get("ros__parameters", {})
    for term in ("friction_table", "gms"):  # files relative to the scenario
        table = ff.get(term, {}).get("file")
        if table and not Path(table).is_absolute():
            ff[term]["file"] = str(Path(args.scenario).resolve().parent / table)
    scenario = tmp / Path(args.scenario).name
    scenario.write_text(yaml.safe_dump(data))
    period = float(data["/**"]["ros__parameters"].get("control_period_s", 1e-3))
    steps = round(args.duration / period)
    domain = bench_domain(args)

    if args.learning_cost:
        return learning_cost(args, data, scenario, tmp, domain, steps, period)
    if args.identifier_cost:
        return identifier_cost(args, data, scenario, tmp, domain, steps, period)

    results: list[tuple[str, float]] = []
    env = ros_environment(domain, tmp)
    print("ping-pong baseline (2 processes) ...", flush=True)
    results.append(("baseline: 2-process ping-pong", ping_pong(env)))
    for name, composed in (("separate processes (4)", False), ("composed (1 process)", True)):
        print(f"{name} ...", flush=True)
        r = run_scenario(
            scenario,
            RunOptions(
                out_dir=tmp / name.split()[0],
                composed=composed,
                domain_id=domain,
                progress=None,
                plots=False,
            ),
        )
        counts = r.summary.message_counts
        expected = {"/state": steps, "/command": steps, "/reference": steps, "/clock": steps // 10}
        lost = {t: n - counts.get(t, 0) for t, n in expected.items()}
        assert not any(lost.values()), f"recorder lost messages: {lost}"
        results.append((f"{name}, recorder on", r.summary.steps_per_s))
    print("core only ...", flush=True)
    results.append(("core only (no ROS)", core_steps_per_s(simulate, scenario, steps)))

    base = results[0][1]
    lines = [
        f"| {'case':<40} | {'steps/s':>10} | {'x real time':>11} | {'x baseline':>10} |",
        f"|{'-' * 42}|{'-' * 12}|{'-' * 13}|{'-' * 12}|",
    ]
    for name, rate in results:
        lines.append(
            f"| {name:<40} | {rate:>10,.0f} | {rate * period:>10.2f}x | {rate / base:>9.2f}x |"
        )
    table_text = "\n".join(lines)
    print()
    print(table_text)
    scen = Path(args.scenario).resolve()
    shown = scen.relative_to(REPO) if scen.is_relative_to(REPO) else scen
    header = (
        f"Scenario `{scen.name}`, {steps} steps of T_u = {period * 1e3:g} ms per run, lockstep, "
        f"measured {time.strftime('%Y-%m-%d %H:%M')} on {platform.node()} ({os.cpu_count()} cores, "
        f"Python {platform.python_version()}, executor {os.environ.get('SERVO_AXIS_EXECUTOR', 'events')}).\n\n"
        f"Command: `.venv/bin/python scripts/benchmark.py --scenario {shown} --duration {args.duration:g}`\n\n"
    )
    out = Path(args.history)
    section = f"## {Path(args.scenario).stem}\n\n{header}{table_text}\n"
    write_section(out, f"## {Path(args.scenario).stem}\n", section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
