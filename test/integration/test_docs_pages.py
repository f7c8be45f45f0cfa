"""Every tutorial and how-to page runs as written, in a fresh copy of the repository.

One test per page (``docs/tutorials/*.md``, ``docs/how-to/*.md``): the page is
read at test time from a fresh copy of the repository's tracked files, its
commands run there as a user copies them, and what they print is checked
against the page's expected output; the rules and the markers are in
``docs_pages.py``. Where a page's command is one an older test ran, the page
test carries that test's assertions on what the page's command made.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
import subprocess
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from docs_pages import (
    REPO,
    Given,
    PageError,
    PageResult,
    PageRun,
    fresh_copy,
    layered_venv,
    left_behind,
    output_mismatch,
    parse_page,
)
from numpy.testing import assert_allclose, assert_array_equal

from servo_axis.params.scenario import load_scenario
from servo_axis.recording.deserialize import read_messages
from servo_axis.recording.reader import read_raw
from servo_axis.wire import cdr

pytestmark = pytest.mark.integration

PAGES = sorted(
    str(p.relative_to(REPO / "docs"))
    for folder in ("tutorials", "how-to")
    for p in (REPO / "docs" / folder).glob("*.md")
)


@dataclass
class Clone:
    """A fresh copy of the repository with a venv of its own on the suite's."""

    root: Path
    tracked: dict[str, str]


@pytest.fixture
def clone(tmp_path: Path) -> Clone:
    root = tmp_path / "clone"
    tracked = fresh_copy(root)
    layered_venv(root / ".venv")
    return Clone(root, tracked)


def run_page(
    page: str,
    clone: Clone,
    domain: int,
    givens: Mapping[str, Given] | None = None,
    more_domains: Callable[[], int] | None = None,
) -> PageResult:
    """The page's commands in ``clone``; nothing left behind outside ``runs/``."""
    parsed = parse_page(clone.root / "docs" / page, clone.root)
    result = PageRun(parsed, clone.root, domain, givens=givens, more_domains=more_domains).run()
    print(result.report())
    assert left_behind(clone.root, clone.tracked) == []
    return result


def summary(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text())


def only(pattern: str, root: Path) -> Path:
    (found,) = root.glob(pattern)
    return found


# -- the rules themselves -------------------------------------------------------------------


OUTPUT = """\
servo_axis run ptc_nominal: 2000 steps, run directory /tmp/x/runs/ptc_nominal-20261201-101112
[####] 2000/2000 steps

tracking error (um)          RMS            max
  all samples               3.68545         18.257
  at T_r instants           3.68559        18.1583

cycle   RMS (um)       max (um)
    1       3.0675         18.257
    2      3.86959         18.257
"""


@pytest.mark.parametrize(
    ("expected", "shown"),
    [
        ("tracking error (um)  RMS  max\n  all samples  3.68545  18.257", True),
        (
            "servo_axis run ptc_nominal: 2000 steps, run directory /.../runs/ptc_nominal-20261125-232600",
            True,
        ),
        ("tracking error (um) RMS max\n...\ncycle RMS (um) max (um)\n1 3.0675 18.257\n...", True),
        # a number as printed, not nearly
        ("  all samples  3.68546  18.257", False),
        # consecutive lines stay consecutive without a `...` line
        ("tracking error (um) RMS max\n  at T_r instants 3.68559 18.1583", False),
        # in order
        ("cycle RMS (um) max (um)\n...\ntracking error (um) RMS max", False),
        # a whole line, not a part of one
        ("all samples 3.68545", False),
        ("  all samples ... 18.257", True),
        # `...` with the blanks beside it: "run ..." shows "run directory" and "run:"
        ("servo_axis run ptc_nominal: ... steps, run ...", True),
        ("servo_axis run ... steps, ... /tmp/x/runs ...", True),
        ("servo_axis run ptc_nominal: 2000 steps, run directory /tmp/y/...", False),
    ],
)
def test_the_output_rules(expected: str, shown: bool) -> None:
    assert (output_mismatch(expected, OUTPUT) is None) is shown


def synthetic(tmp_path: Path, text: str) -> tuple[Path, dict[str, str]]:
    """A clone of two tracked files and a page of its own (``docs/page.md``)."""
    root = tmp_path / "synthetic"
    (root / "docs").mkdir(parents=True)
    (root / "tracked.txt").write_text("tracked\n")
    (root / "docs" / "page.md").write_text(text)
    tracked = {"tracked.txt": "", "docs/page.md": ""}
    return root, {k: hashlib.sha256((root / k).read_bytes()).hexdigest() for k in tracked}


def run_synthetic(tmp_path: Path, text: str) -> tuple[PageResult, Path, dict[str, str]]:
    root, tracked = synthetic(tmp_path, text)
    result = PageRun(parse_page(root / "docs" / "page.md", root), root, 117).run()
    return result, root, tracked


def test_a_page_runs_its_commands_checks_their_output_and_saves_its_files(tmp_path: Path) -> None:
    page = """
```yaml title="runs/given.yaml"
a: 1
```

```bash
cat runs/given.yaml
echo ROS_DOMAIN_ID=$ROS_DOMAIN_ID --domain-id 42   # the page's domain is the test's
false   # exit 1: a failure the page expects
```

```text
a: 1
ROS_DOMAIN_ID=42 --domain-id 42
```
"""
    result, root, tracked = run_synthetic(tmp_path, page)
    assert [r.exit_code for r in result.ran] == [0, 0, 1]
    assert "ROS_DOMAIN_ID=117 --domain-id 117" in result.ran[1].output
    assert (root / "runs" / "given.yaml").read_text() == "a: 1\n"
    assert left_behind(root, tracked) == []


@pytest.mark.parametrize(
    ("page", "problem"),
    [
        # an unexpected exit code
        ("```bash\nfalse\n```\n", "exited 1, the page expects 0"),
        # output the command did not print
        ("```bash\necho one\n```\n\n```text\ntwo\n```\n", "the output does not show"),
        # a text block that is no command's output and not marked
        ("```text\nwhatever\n```\n", "a text block after no bash block"),
        # a skip marker that matches no command
        ("<!-- docs-test: skip nothing -- no reason -->\n```bash\necho x\n```\n",
         "'skip nothing' matches no command"),
        # a marker without its reason, a marker far from its block
        ("<!-- docs-test: skip all -->\n```bash\necho x\n```\n", "not a docs-test directive"),
        ("<!-- docs-test: skip all -- far -->\nprose\n```bash\necho x\n```\n", "right before"),
    ],
)  # fmt: skip
def test_a_page_that_does_not_run_as_written_fails(tmp_path: Path, page: str, problem: str) -> None:
    with pytest.raises(PageError, match=re.escape(problem)):
        run_synthetic(tmp_path, page)


def test_terminals_share_the_page_s_domain_and_the_others_take_their_own(
    tmp_path: Path,
) -> None:
    page = """
```bash
# terminal 1: names the page's domain
echo one ROS_DOMAIN_ID=$ROS_DOMAIN_ID --domain-id 42
# terminal 2: names none
echo two ROS_DOMAIN_ID=$ROS_DOMAIN_ID
# terminal 3: names none either
echo three ROS_DOMAIN_ID=$ROS_DOMAIN_ID
```

<!-- docs-test: output of terminal 1 -->
```text
one ROS_DOMAIN_ID=42 --domain-id 42
```
"""
    root, _ = synthetic(tmp_path, page)
    fresh = iter([118, 119])
    parsed = parse_page(root / "docs" / "page.md", root)
    result = PageRun(parsed, root, 117, more_domains=lambda: next(fresh)).run()
    shown = {r.output.split()[0]: r.output.split()[1] for r in result.ran}
    assert shown == {"one": "ROS_DOMAIN_ID=117", "two": "ROS_DOMAIN_ID=118",
                     "three": "ROS_DOMAIN_ID=119"}  # fmt: skip
    # Without a terminal that names it, the first takes the test's domain.
    page = (
        "```bash\n# terminal 1: a\necho $ROS_DOMAIN_ID\n# terminal 2: b\necho $ROS_DOMAIN_ID\n```\n"
    )
    root, _ = synthetic(tmp_path / "second", page)
    fresh = iter([118])
    parsed = parse_page(root / "docs" / "page.md", root)
    result = PageRun(parsed, root, 117, more_domains=lambda: next(fresh)).run()
    assert [r.output.strip() for r in result.ran] == ["117", "118"]


def test_what_commands_leave_outside_runs_is_named(tmp_path: Path) -> None:
    page = """
```bash
mkdir -p runs/kept src/__pycache__ && touch runs/kept/x.png src/__pycache__/m.pyc
echo changed > tracked.txt
touch cycles.png
```
"""
    result, root, tracked = run_synthetic(tmp_path, page)
    assert len(result.ran) == 3
    assert left_behind(root, tracked) == [
        "cycles.png (untracked)",
        "tracked.txt (tracked, changed)",
    ]


def page_of_test(name: str) -> str:
    """``test_tutorials_first_run`` -> ``tutorials/first-run.md``."""
    for folder in ("tutorials", "how_to"):
        if name.startswith(f"test_{folder}_"):
            page = name.removeprefix(f"test_{folder}_").replace("_", "-")
            return f"{folder.replace('_', '-')}/{page}.md"
    return ""


def test_every_tutorial_and_how_to_has_its_test() -> None:
    tested = {page_of_test(name) for name in globals()} - {""}
    assert tested == set(PAGES), sorted(set(PAGES) ^ tested)


def test_the_readme(ros_env: int, clone: Clone) -> None:
    """The README's commands as a new user copies them, from its two first ones on."""
    result = run_page("../README.md", clone, ros_env)
    runs = clone.root / "runs"
    # The default run, another scenario, their comparison.
    for pattern in ("rptc_friction_table-*", "ptc_friction_table-*"):
        assert summary(only(pattern, runs))["health"]["exit_code"] == 0, pattern
    assert (runs / "cycles.png").stat().st_size > 10_000
    assert "rptc_friction_table" in result.output_of(".venv/bin/python -m servo_axis list")
    compared = result.output_of(".venv/bin/python -m servo_axis compare")
    assert "max tracking error per cycle (um)" in compared, compared
    # The axis without its feedback, the example PD in its place: a complete run whose
    # commands all came from the outside node (the suite started no feedback).
    outside = summary(only("ptc_nominal-*", runs))
    assert outside["health"]["outcome"] == "complete", outside["health"]
    assert "feedback" not in outside["health"]["nodes"], outside["health"]["nodes"]
    assert outside["message_counts"]["/x/command"] == outside["message_counts"]["/x/state"]
    # Measured, then identified into a scenario that names the fitted plant.
    fitted = load_scenario(runs / "my_axis.yaml")
    assert fitted["plant"]["ros__parameters"]["model"] == "ball_screw"
    assert len(result.skipped) == 3  # test.sh, mkdocs serve and build


# -- the tutorials ------------------------------------------------------------------------------


def test_tutorials_first_run(ros_env: int, clone: Clone) -> None:
    result = run_page("tutorials/first-run.md", clone, ros_env)
    runs = clone.root / "runs"
    default = summary(only("rptc_friction_table-*", runs))
    alone = summary(runs / "rptc_only")
    assert default["health"]["exit_code"] == alone["health"]["exit_code"] == 0
    assert not default["faults"] and not alone["faults"]
    # 000 Fig. 17/18 on one axis: the friction table takes the quadrant glitch out of
    # cycle 1, where nothing is learned yet; RPTC goes on from there, cycle after cycle,
    # to below what RPTC alone reaches.
    with_table = [c["max_m"] for c in default["tracking_error"]["cycles"]]
    rptc = [c["max_m"] for c in alone["tracking_error"]["cycles"]]
    assert len(with_table) == len(rptc) == 6
    assert with_table[0] < 0.5 * rptc[0]
    assert with_table[-1] < rptc[-1]
    assert all(b < a for a, b in itertools.pairwise(with_table)), with_table
    for name in ("cycles.png", "error.png"):
        assert (runs / name).stat().st_size > 10_000
    for name in ("error.png", "cycle_errors.png", "reference_position.png", "learning_memory.json"):
        assert (only("rptc_friction_table-*", runs) / name).is_file()
    assert "rptc_friction_table" in result.output_of(".venv/bin/python -m servo_axis list")
    # The compare-runs page quotes this compare's reductions (max, per cycle).
    compared = result.output_of(".venv/bin/python -m servo_axis compare runs/rptc_only")
    block = compared.split("max tracking error per cycle (um)", 1)[1].split("\n\n", 1)[0]
    reduction = {int(r.split()[0]): r.split()[-1] for r in block.splitlines()[2:]}
    assert sorted(reduction) == [1, 2, 3, 4, 5, 6]
    how_to = (clone.root / "docs" / "how-to" / "compare-runs.md").read_text()
    how_to = " ".join(how_to.split())
    assert f"{reduction[1]} % less in cycle 1" in how_to, reduction
    assert f"and {reduction[6]} % in the last, the headline" in how_to, reduction
    assert f"cycle 2's {reduction[2]} %" in how_to, reduction


#: Run in the clone's venv with the package installed: the plain-call loop of a scenario
#: and the message for a model that is not installed.
PLUGIN_CHECKS = """
import json, sys
from pathlib import Path
import numpy as np
from servo_axis.params.resolve import node_values
from servo_axis.params.scenario import load_scenario
from servo_axis.simulate import simulate
out = {}
for name in sys.argv[1:]:
    t = simulate(Path(name))
    out[name] = {f: getattr(t, f).tolist() for f in t.__dataclass_fields__}
bad = load_scenario(Path(sys.argv[1]))
bad["plant"]["ros__parameters"]["model"] = "no_such_axis"
try:
    node_values(bad, "plant")
except ValueError as err:
    out["unknown"] = str(err)
print(json.dumps(out))
"""


def test_tutorials_own_plugin(ros_env: int, clone: Clone, tmp_path: Path) -> None:
    scenario = clone.root / "test" / "data" / "outside_plugin" / "viscous_axis.yaml"
    bare = tmp_path / "bare.yaml"
    data = yaml.safe_load(scenario.read_text())
    data["feedforward"]["ros__parameters"]["viscous_ff"]["enabled"] = False
    bare.write_text(yaml.safe_dump(data))
    looked: dict = {}

    def plain_calls(root: Path, env: dict[str, str]) -> None:
        def python(*args: str) -> str:
            done = subprocess.run(
                [".venv/bin/python", *args],
                cwd=root, env=env, capture_output=True, text=True, timeout=300, check=False,
            )  # fmt: skip
            assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
            return done.stdout

        looked.update(json.loads(python("-c", PLUGIN_CHECKS, str(scenario), str(bare))))
        looked["params"] = python("-m", "servo_axis", "params")
        looked["reference"] = python("scripts/parameter_docs.py", "--check")

    page = clone.root / "docs" / "tutorials" / "own-plugin.md"
    parsed = parse_page(page, clone.root)
    result = PageRun(
        parsed, clone.root, ros_env, after={".venv/bin/python -m servo_axis run": plain_calls}
    ).run()
    print(result.report())
    assert left_behind(clone.root, clone.tracked) == []

    # The node graph's run is the plain-call loop's, bit for bit.
    run_dir = clone.root / "runs" / "viscous_axis"
    state: dict[int, object] = {}
    command: dict[int, object] = {}
    for m in read_raw(run_dir / "bag"):
        if m.topic in ("/x/state", "/x/command"):
            js = cdr.decode("sensor_msgs/msg/JointState", m.data)
            step = round(js.stamp_ns / 1e6)
            (state if m.topic == "/x/state" else command)[step] = js
    core = {k: np.array(v) for k, v in looked[str(scenario)].items()}
    steps = len(core["encoder_rad"])
    assert steps == 500 and sorted(state) == list(range(steps)) == sorted(command)
    assert_array_equal([state[k].position[0] for k in range(steps)], core["encoder_rad"])
    assert_array_equal([state[k].position[1] for k in range(steps)], core["scale_m"])
    assert_array_equal([command[k].effort[0] for k in range(steps)], core["command_Nm"])
    assert summary(run_dir).get("error_unit") is None  # the entry says linear: an error in m

    # Without the term: the numbers the page gives, from the plain calls.
    lead = 1.91e-3
    off = {k: np.array(v) for k, v in looked[str(bare)].items()}
    error = lead * off["reference_rad"] - off["scale_m"]
    rms_um, max_um = np.sqrt(np.mean(error**2)) * 1e6, np.max(np.abs(error)) * 1e6
    text = page.read_text()
    assert f"{rms_um:.6g} um RMS, {max_um:.6g} um max" in text, (rms_um, max_um)
    with_term = summary(run_dir)["tracking_error"]["all_samples"]["rms_m"] * 1e6
    assert with_term < 0.02 * rms_um

    # list and params name the package's extensions with their entry points and
    # package; params shows each key from its schema (the page's text blocks have
    # them whole), and every installed extension without a name.
    listed = result.output_of(".venv/bin/python -m servo_axis list")
    (row,) = [line for line in listed.splitlines() if line.split()[:1] == ["rigid_viscous_axis"]]
    assert row.endswith(
        "[servo_axis_outside.rigid_axis:PLANT_MODEL, servo-axis-outside-plugin 0.1.0]"
    )
    shown = result.output_of(".venv/bin/python -m servo_axis params rigid_viscous_axis")
    (viscous,) = [r for r in shown.splitlines() if r.split()[:1] == ["viscous_Nms_per_rad"]]
    # Param(0.2, unit="N m s/rad", above=0.0, meaning=...) of rigid_axis.py
    assert viscous.split()[1:7] == ["0.2", "N", "m", "s/rad", ">", "0"]
    assert viscous.endswith("b: viscous friction torque per rad/s")
    every = looked["params"]
    assert "\nfeedforward (term viscous_ff)  [servo_axis_outside.viscous_term:TERM, " in every
    assert (
        "\nplant (model rigid_viscous_axis)  [servo_axis_outside.rigid_axis:PLANT_MODEL, " in every
    )
    # docs/parameters.md is the shipped package's: unchanged by what is installed (so
    # test/unit/test_docs.py passes with the package installed).
    assert looked["reference"].strip().endswith("docs/parameters.md is up to date")
    reference = (clone.root / "docs" / "parameters.md").read_text()
    assert "rigid_viscous_axis" not in reference and "python -m servo_axis params" in reference
    # The message for a model that is not installed names the installed ones.
    message = looked["unknown"]
    assert message.startswith("parameter 'model': expected one of [")
    assert "'rigid_viscous_axis'" in message and "'ball_screw'" in message
    assert message.endswith("got 'no_such_axis'") and "\n" not in message

    # Uninstalled: nothing of the package is left in the clone's venv.
    site = only(".venv/lib/python*/site-packages", clone.root)
    assert not [p.name for p in site.iterdir() if "outside" in p.name]


def joint_states(bag: Path, topic: str) -> dict[int, object]:
    """The JointState messages of ``topic`` by stamp (ns)."""
    return {
        m.message.header.stamp.sec * 10**9 + m.message.header.stamp.nanosec: m.message
        for m in read_messages(bag, topics=[topic])
    }


def test_tutorials_own_controller(
    ros_env: int, clone: Clone, more_domains: Callable[[], int]
) -> None:
    run_page("tutorials/own-controller.md", clone, ros_env, more_domains=more_domains)
    mine, suite = clone.root / "runs" / "my_pd", clone.root / "runs" / "suite_pid"
    # The table of the page is the two runs' summaries.
    text = (clone.root / "docs" / "tutorials" / "own-controller.md").read_text()
    for run_dir in (mine, suite):
        errors = summary(run_dir)["tracking_error"]["all_samples"]
        assert f"| {errors['rms_m'] * 1e6:.6g} | {errors['max_m'] * 1e6:.6g} |" in text
    assert summary(mine)["health"]["exit_code"] == 0 and summary(mine)["health"]["deterministic"]
    # Every recorded command is the PD law of the recorded state and reference of its
    # sample (computed here, independently of the example).
    bag = mine / "bag"
    state, ref, cmd = (joint_states(bag, f"/x/{t}") for t in ("state", "reference", "command"))
    assert len(state) == len(cmd) == 2000
    inertia, w = 0.01, 2 * math.pi * 20.0
    kp, kd = inertia * w * w, 2 * 0.7 * inertia * w
    stamps = sorted(cmd)
    want = [
        ref[t].effort[0]
        + kp * (ref[t].position[0] - state[t].position[0])
        + kd * (ref[t].velocity[0] - state[t].velocity[0])
        for t in stamps
    ]
    assert_allclose([cmd[t].effort[0] for t in stamps], want, rtol=1e-12, atol=1e-12)
    assert {cmd[t].name[0] for t in stamps} == {"x_motor"}
    # The page's why: while the axis moves, the error is the Coulomb level over K_p.
    lead, coulomb = 1.91e-3, 3.2
    moving = [t for t in stamps if abs(state[t].velocity[0]) > 1.0]
    error = np.array([ref[t].position[0] - state[t].position[0] for t in moving])
    assert_allclose(np.median(np.abs(error)) * lead, coulomb / kp * lead, rtol=0.01)
    assert f"{coulomb / kp * lead * 1e6:.1f} um at the table" in text
    assert f"median is {np.median(np.abs(error)) * lead * 1e6:.1f} um" in text


def test_tutorials_study(ros_env: int, clone: Clone) -> None:
    import csv

    run_page("tutorials/study.md", clone, ros_env)
    out = clone.root / "runs" / "pid_bandwidth"
    assert not (clone.root / "runs" / "misspelt").exists()
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == ["ok"] * 6
    by_point = {
        (float(r["feedback.bandwidth_hz"]), float(r["disturbance.amplitude_Nm"])): r for r in rows
    }
    assert sorted(by_point) == [(b, a) for b in (20, 40, 80) for a in (0.25, 0.5)]
    for bandwidth in (20, 40, 80):
        # A linear loop (the nominal axis, ideal sensors): twice the disturbance, twice
        # the error.
        low, high = by_point[(bandwidth, 0.25)], by_point[(bandwidth, 0.5)]
        for figure in ("max_m", "last_rms_m"):
            assert_allclose(float(high[figure]), 2 * float(low[figure]), rtol=1e-9)
    # A stiffer loop leaves less of the 4 Hz disturbance.
    maxima = [float(by_point[(b, 0.5)]["max_m"]) for b in (20, 40, 80)]
    assert maxima[0] > maxima[1] > maxima[2] > 0
    names = {p.name for p in out.iterdir()}
    assert {"results.csv", "results.parquet", "manifest.json"} <= names
    for figure in ("max_m", "last_rms_m"):
        for key in ("feedback.bandwidth_hz", "disturbance.amplitude_Nm"):
            assert f"{figure}__vs__{key}.png" in names
    manifest = json.loads((out / "manifest.json").read_text())
    assert sorted(manifest["rows"], key=int) == [str(k) for k in range(6)]


def test_how_to_compare_runs(ros_env: int, clone: Clone, more_domains: Callable[[], int]) -> None:
    result = run_page("how-to/compare-runs.md", clone, ros_env, more_domains=more_domains)
    runs = clone.root / "runs"
    ptc, pid = summary(runs / "ptc_nominal"), summary(runs / "pid_nominal")
    for s in (ptc, pid):
        assert s["steps"] == 2000
        for topic in ("/x/state", "/x/command", "/x/reference"):
            assert s["message_counts"][topic] == 2000  # the recorder lost nothing
        assert s["message_counts"]["/clock"] == 200  # /clock every 10 samples
        assert not s["faults"]
        # The wall time is the steps': start-up and end are apart, and the three lie
        # within the command's own time.
        assert s["startup_s"] > 0 and s["finish_s"] > 0 and s["wall_time_s"] > 0
        assert_allclose(s["steps_per_s"], s["steps"] / s["wall_time_s"], rtol=1e-12)
    (took,) = [r.seconds for r in result.ran if "run ptc_nominal" in r.command.bare]
    assert ptc["startup_s"] + ptc["wall_time_s"] + ptc["finish_s"] < took
    for name in ("error.png", "cycle_errors.png"):
        assert (runs / "ptc_nominal" / name).stat().st_size > 10_000
    for name in ("cycles.png", "error.png", "rmsd.png"):
        assert (runs / name).stat().st_size > 10_000
    # The reference starts at rest with the axis, so PTC tracks from sample 0: below
    # 1 nm at the T_r instants of every cycle, where the PID alone is off by micrometres.
    ptc_ss = ptc["tracking_error"]["reference_instants"]["max_m"]
    pid_ss = pid["tracking_error"]["reference_instants"]["max_m"]
    assert ptc_ss < 1e-9 and pid_ss > 1e-6 and pid_ss / max(ptc_ss, 1e-300) > 1e3
    for cycle in ptc["tracking_error"]["cycles"]:
        assert cycle["reference_instants"]["max_m"] < 1e-9


def predicted_dob_ratio(frequency_hz: float, scenario: Path) -> float:
    """|error with DOB / error without| for an input disturbance, from the
    discrete transfer functions of the loop (scipy's own ZOH and bilinear
    discretisations, not the core's): plant P(z), PID C(z), DOB inverse
    model N(z) on the differenced angle and low-pass filter L(z) on the
    previous current, so ``u = -C y - N (1 - z^-1)/T y + L z^-1 u``."""
    from scipy import signal

    from servo_axis.core.feedback.pid import design_pid_pole_placement

    data = load_scenario(scenario)
    common = data["/**"]["ros__parameters"]
    nominal = common["nominal"]
    j, d, kt = (
        nominal["inertia_kgm2"],
        nominal["damping_Nms_per_rad"],
        nominal["torque_constant_Nm_per_A"],
    )
    period = common["control_period_s"]
    fb = data["feedback"]["ros__parameters"]
    gains = design_pid_pole_placement(
        bandwidth_hz=fb["bandwidth_hz"],
        inertia_kgm2=j,
        damping_Nms_per_rad=d,
        torque_constant_Nm_per_A=kt,
    )
    z = np.exp(2j * np.pi * frequency_hz * period)

    def at_z(num: Any, den: Any, method: str) -> complex:
        numd, dend, _ = signal.cont2discrete((num, den), period, method=method)
        return complex(np.polyval(np.ravel(numd), z) / np.polyval(np.ravel(dend), z))

    wq = 2 * np.pi * fb["dob"]["cutoff_hz"]
    plant = at_z([kt], [j, d, 0.0], "zoh")
    pid = at_z(*gains.transfer_function(), "bilinear")
    inverse = at_z([wq * j / kt, wq * d / kt], [1.0, wq], "bilinear")
    lpf = at_z([wq], [1.0, wq], "bilinear")
    with_dob = plant / (1 + plant * (pid + inverse * (1 - 1 / z) / period) / (1 - lpf / z))
    without = plant / (1 + plant * pid)
    return float(abs(with_dob / without))


def test_how_to_scenarios(ros_env: int, clone: Clone) -> None:
    result = run_page("how-to/scenarios.md", clone, ros_env)
    runs = clone.root / "runs"
    dob, pid = runs / "dob_disturbance", only("pid_disturbance-*", runs)
    assert "dob_disturbance" in result.output_of(".venv/bin/python -m servo_axis list")
    assert "tracking error (um)" in result.output_of(".venv/bin/python -m servo_axis summary")
    for run_dir in (dob, pid):
        assert summary(run_dir)["health"]["exit_code"] == 0 and not summary(run_dir)["faults"]
    assert summary(pid)["scenario_file"] == str(runs / "my_scenario.yaml")
    # --set: the nodes got the file's keys with the two overridden (params.yaml), the
    # summary names the overrides, and the run is as long as the override says.
    pid60 = runs / "pid60"
    given = yaml.safe_load((pid60 / "params.yaml").read_text())
    shipped = load_scenario(clone.root / "config" / "pid_disturbance.yaml")
    assert shipped["feedback"]["ros__parameters"]["bandwidth_hz"] == 40.0
    assert given["/**/feedback"]["ros__parameters"]["bandwidth_hz"] == 60
    assert given["/**"]["ros__parameters"]["duration_s"] == 1
    plant = given["/**/plant"]["ros__parameters"]["disturbance"]
    assert plant == shipped["plant"]["ros__parameters"]["disturbance"]
    assert summary(pid60)["overrides"] == ["feedback.bandwidth_hz=60", "shared.duration_s=1"]
    assert summary(pid60)["steps"] == 1000 and summary(pid60)["health"]["exit_code"] == 0
    amplitudes = {}
    for name, run_dir in (("pid", pid), ("dob", dob)):
        angle = np.array(
            [m.message.position[0] for m in read_messages(run_dir / "bag", topics=["/x/state"])]
        )
        # The 4 Hz component over the second second (4 whole periods), once the
        # transients of the 40 Hz loop have died out.
        k = np.arange(1000, 2000)
        amplitudes[name] = 2 / k.size * abs(np.sum(angle[k] * np.exp(-2j * np.pi * 4.0 * k * 1e-3)))
    ratio = amplitudes["dob"] / amplitudes["pid"]
    predicted = predicted_dob_ratio(4.0, clone.root / "config" / "dob_disturbance.yaml")
    print(f"DOB leaves {ratio:.6f} of the 4 Hz error; predicted {predicted:.6f}")
    # About 1/13 here (|1 - Q| of the continuous filter would say 1/20; the sampled
    # observer's delays cost the rest).
    np.testing.assert_allclose(ratio, predicted, rtol=1e-3)
    assert ratio < 0.1


def test_how_to_friction_models(ros_env: int, clone: Clone) -> None:
    from servo_axis.identify.friction import table_from_run
    from servo_axis.storage import load_friction_table

    run_page("how-to/friction-models.md", clone, ros_env)
    made = load_friction_table(clone.root / "runs" / "friction_table.csv")
    shipped = load_friction_table(clone.root / "config" / "friction_table_ball_screw_x.csv")
    # Through the command a user runs; it writes what table_from_run builds, also once
    # the scenario file the run was made from has moved and an edited one (another
    # axis: lead, inertia, sensor) stands in its place: the run directory is all it reads.
    scenario = clone.root / "config" / "friction_id.yaml"
    data = load_scenario(scenario)
    scenario.rename(scenario.with_name("moved.yaml"))
    data["/**"]["ros__parameters"]["lead_m_per_rad"] = 0.005
    data["/**"]["ros__parameters"].setdefault("nominal", {})["inertia_kgm2"] = 0.03
    data.setdefault("feedback", {"ros__parameters": {}})["ros__parameters"]["sensor"] = "scale"
    scenario.write_text(yaml.safe_dump(data))
    again = table_from_run(clone.root / "runs" / "friction_id")
    assert_array_equal(made.torque_Nm, again.torque_Nm)
    assert_allclose(made.displacement_m, again.displacement_m, rtol=0, atol=1e-15)
    # The shipped table is this one (bit for bit where it was made; rounding elsewhere).
    assert_allclose(made.displacement_m, shipped.displacement_m, rtol=0, atol=1e-15)
    assert_allclose(made.torque_Nm, shipped.torque_Nm, rtol=1e-9, atol=1e-12)
    print("the shipped table, byte for byte:", (clone.root / "runs" / "friction_table.csv").read_bytes()
          == (clone.root / "config" / "friction_table_ball_screw_x.csv").read_bytes())  # fmt: skip
    # The identified table spans the Coulomb level of the plant (3.2 N m).
    assert made.torque_Nm[0] == pytest.approx(-3.2, rel=0.15)
    assert made.torque_Nm[-1] == pytest.approx(3.2, rel=0.1)


def test_how_to_identify_your_axis(
    ros_env: int, clone: Clone, more_domains: Callable[[], int]
) -> None:
    import re

    result = run_page("how-to/identify-your-axis.md", clone, ros_env, more_domains=more_domains)
    runs = clone.root / "runs"
    shown = result.output_of(
        ".venv/bin/python -m servo_axis identify runs/frf --model ball_screw \\"
    )
    printed = {
        m.group(1): float(m.group(2))
        for m in re.finditer(r"^(\S+)\s+(-?[\d.]+(?:e-?\d+)?)\s+\S+\s+", shown, re.MULTILINE)
    }
    # The page's table of the ball screw is what the node graph's runs give (it was made
    # with the plain-call loops, which the node graph reproduces bit for bit): each key to
    # the digits the table shows.
    page = (clone.root / "docs" / "how-to" / "identify-your-axis.md").read_text()
    table = page.split("**`ball_screw`**", 1)[1].split("\n\n", 2)[1]
    rows = re.findall(r"^\| `([^`]+)` \| ([^|]+) \| (-?[\d.e-]+) \+- ", table, re.MULTILINE)
    assert len(rows) == 12, table
    truth = load_scenario(clone.root / "config" / "measure_frf_ball_screw.yaml")
    for key, true_value, identified in rows:
        digits = identified.split("e")[0].split(".")[-1]
        exponent = int(identified.split("e")[1]) if "e" in identified else 0
        last_digit = 10.0 ** (exponent - len(digits))
        assert abs(printed[key] - float(identified)) <= last_digit, (key, printed[key], identified)
        assert float(true_value) == pytest.approx(_key(truth, key), abs=1e-15), key
    written = yaml.safe_load((runs / "my_axis.yaml").read_text())["plant"]["ros__parameters"]
    for key in ("inertia_kgm2", "damping_Nms_per_rad"):
        assert_allclose(written[key], printed[key], rtol=1e-5)
        assert_allclose(written[key], _key(truth, key), rtol=0.03)
    # The dead time is written rounded to the 10 us sim_step_s.
    assert_allclose(written["dead_time_s"], round(printed["dead_time_s"] / 1e-5) * 1e-5, rtol=1e-12)
    assert_allclose(written["modes"]["frequency_hz"], [printed["modes.frequency_hz[0]"],
                    printed["modes.frequency_hz[1]"]], rtol=1e-5)  # fmt: skip
    for name in ("report.md", "bode_encoder.png"):
        assert (runs / "report" / name).stat().st_size > 1000
    # The written scenario ran as it is, on the fitted axis: the measurement's move.
    again = summary(only("my_axis-*", runs))
    assert again["health"]["exit_code"] == 0 and again["steps"] == summary(runs / "sine")["steps"]
    assert not (runs / "x.yaml").exists()


def _key(scenario: dict[str, Any], key: str) -> float:
    """The plant's value of a dotted key of the identify table (``modes.a[1]``)."""
    plant = scenario["plant"]["ros__parameters"]
    name, _, index = key.partition("[")
    value: Any = plant
    for part in name.split("."):
        value = value.get(part, 0.0) if isinstance(value, dict) else value
    return float(value[int(index.rstrip("]"))] if index else value)


def test_how_to_develop(ros_env: int, clone: Clone) -> None:
    # ruff passes on the clone; the generated parameter reference and the figure of
    # the learning filters are the committed ones (run_page: no tracked file changed).
    result = run_page("how-to/develop.md", clone, ros_env)
    assert "written" in result.output_of(".venv/bin/python scripts/parameter_docs.py")
    assert "written" in result.output_of(".venv/bin/python scripts/learning_figures.py")


def test_how_to_reproducible_install(ros_env: int, clone: Clone) -> None:
    # Every command is marked (network, minutes); the page is parsed and checked for it.
    result = run_page("how-to/reproducible-install.md", clone, ros_env)
    assert not result.ran and len(result.skipped) == 3


def test_how_to_outside_plant(ros_env: int, clone: Clone) -> None:
    from servo_axis.simulate import simulate

    run_page("how-to/outside-plant.md", clone, ros_env)
    out = clone.root / "runs" / "outside_plant"
    mine = summary(out)
    assert mine["health"]["exit_code"] == 0 and mine["health"]["deterministic"]
    bag = out / "bag"
    state, cmd = joint_states(bag, "/x/state"), joint_states(bag, "/x/command")
    stamps = sorted(state)
    assert stamps == [k * 1_000_000 for k in range(2000)] == sorted(cmd)
    # The states are the exact replay of the recorded commands through the exact
    # zero-order-hold solution of J w' = tau - B w (written again here).
    inertia, damping, period, lead, limit = 0.01, 0.1, 0.001, 0.00191, 21.45
    a = math.exp(-damping * period / inertia)
    angle, speed = [0.0], [0.0]
    for t in stamps[:-1]:
        tau = max(-limit, min(limit, cmd[t].effort[0]))
        w_inf = tau / damping
        gained = w_inf * period + (speed[-1] - w_inf) * (1 - a) * inertia / damping
        angle.append(angle[-1] + gained)  # the example's order of operations
        speed.append(w_inf + (speed[-1] - w_inf) * a)
    assert_array_equal([state[t].position[0] for t in stamps], angle)
    assert_array_equal([state[t].velocity[0] for t in stamps], speed)
    assert_array_equal([state[t].position[1] for t in stamps], lead * np.array(angle))
    # The suite's own plant (the plain-call loop, which its node graph reproduces bit for
    # bit) gives the same tracking error within 1e-6.
    own = simulate(clone.root / "config" / "pid_nominal.yaml")
    error = lead * (own.reference_rad - own.encoder_rad)
    errors = mine["tracking_error"]["all_samples"]
    assert errors["rms_m"] > 1e-6  # the PID alone: micrometres, not rounding
    assert_allclose(errors["rms_m"], np.sqrt(np.mean(error**2)), rtol=1e-6)
    assert_allclose(errors["max_m"], np.max(np.abs(error)), rtol=1e-6)


def test_how_to_watch_a_run(ros_env: int, clone: Clone) -> None:
    result = run_page("how-to/watch-a-run.md", clone, ros_env)
    watcher = result.output_of("ROS_DOMAIN_ID=42 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST")
    # It ended quietly on Ctrl-C (exit 0, the page's default), no traceback.
    assert "Traceback" not in watcher and "KeyboardInterrupt" not in watcher, watcher[-2000:]
    # The run stopped by Ctrl-C says so and keeps what it recorded.
    watched = summary(clone.root / "runs" / "watched")
    assert watched["health"]["outcome"] == "interrupted" and watched["health"]["exit_code"] == 130
    assert 0 < watched["message_counts"]["/x/state"] < 600_000
    assert watched["overrides"] == ["shared.duration_s=600"], watched.get("overrides")


def test_how_to_live_view(ros_env: int, clone: Clone) -> None:
    run_page("how-to/live-view.md", clone, ros_env)
    # The extra installed into the clone's venv: servo_axis from the clone itself.
    site = only(".venv/lib/python*/site-packages", clone.root)
    assert [p.name for p in site.glob("servo_axis-*.dist-info")]
    live = summary(clone.root / "runs" / "live")
    assert live["health"]["exit_code"] == 0 and live["health"]["deterministic"]
    assert live["message_counts"]["/x/state"] == 2000


ROLES = ("recorder", "plant", "feedback", "feedforward")
#: The measurement recover-a-bag kills: its command, as the page gives it.
KILLED_RUN = ".venv/bin/python -m servo_axis run measure_frf_ball_screw"


def killed_after(command: str, steps: int) -> Given:
    """The page's ``command`` (a run), every process of it SIGKILLed once ``steps`` are
    written: the given of recover-a-bag.

    The recorder acknowledges the steps it has written on ``recorder/progress`` and
    flushes every 0.25 s. Once ``steps`` are acknowledged the plant is stopped
    (SIGSTOP: in lockstep no step is taken without it, however fast the machine, so
    the run cannot reach its end first); once the bag on disk holds every state up to
    ``steps`` (read as ``bag recover`` reads an unfinished file: a loaded host once
    flushed later than a fixed 0.6 s, and the page's identify found steps missing),
    the runner and its nodes are SIGKILLed at once.
    """

    def on_disk(bag: Path) -> set[int]:
        try:
            return {
                cdr.decode("sensor_msgs/msg/JointState", m.data).stamp_ns // 500_000
                for m in read_raw(bag, topics=["/x/state"])
            }
        except Exception:  # a file still being written: read it again
            return set()

    def given(root: Path, where: str, env: dict[str, str]) -> None:
        import os
        import signal
        import time

        from servo_axis.run.fastdds import clean_stale_shm
        from servo_axis.run.processes import pids_of
        from servo_axis.run.progress import ProgressWatcher

        assert f"--out {where} " in command, (where, command)
        out, started = root / where, time.time()
        runner = subprocess.Popen(
            ["bash", "-c", command], cwd=root, env=env, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL, start_new_session=True,
        )  # fmt: skip
        watcher = ProgressWatcher("/x", domain_id=int(env["ROS_DOMAIN_ID"]))
        try:
            deadline = time.monotonic() + 240
            while watcher.steps < steps:
                assert runner.poll() is None and time.monotonic() < deadline, "no run went on"
                watcher.spin(0.05)
            (plant,) = pids_of(out, "plant")
            os.kill(plant, signal.SIGSTOP)
            flushed = time.monotonic() + 60
            while not set(range(steps)) <= on_disk(out / "bag"):
                assert time.monotonic() < flushed, f"the first {steps} states never reached disk"
                watcher.spin(0.2)
        finally:
            watcher.close()
            os.killpg(runner.pid, signal.SIGKILL)  # the runner; its nodes by PR_SET_PDEATHSIG
            runner.wait()
        deadline = time.monotonic() + 30
        while any(pids_of(out, role) for role in ROLES):
            assert time.monotonic() < deadline, "node processes outlived their SIGKILLed runner"
            time.sleep(0.1)
        clean_stale_shm(since=started)  # what the SIGKILLed participants left in /dev/shm
        assert not (out / "bag" / "metadata.yaml").exists() and not (out / "summary.json").exists()

    return given


@pytest.mark.shm
def test_how_to_recover_a_bag(
    ros_env: int, clone: Clone, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import shlex

    from rosbags.rosbag2 import Reader

    from servo_axis.__main__ import main
    from servo_axis.analysis.summary import RunSummary, load_summary
    from servo_axis.identify.data import from_simulation
    from servo_axis.identify.driver import identify

    parsed = parse_page(clone.root / "docs" / "how-to" / "recover-a-bag.md", clone.root)
    (command,) = [
        c.text for b in parsed.blocks for c in b.commands if c.bare.startswith(KILLED_RUN)
    ]
    # (the excitation ends at step 6000: 1 s + (1 + 3) x 0.5 s at T_u = 0.5 ms)
    result = run_page(
        "how-to/recover-a-bag.md",
        clone,
        ros_env,
        givens={"killed-run": killed_after(command, 6100)},
    )
    run = clone.root / "runs" / "frf"
    bag = run / "bag"
    # Before: one line, naming what to do.
    before, after = [
        r for r in result.ran if r.command.bare.endswith("servo_axis summary runs/frf")
    ]
    assert before.exit_code == 2 and after.exit_code == 0
    told = before.output
    assert told.count("\n") == 1 and "python -m servo_axis bag recover runs/frf/bag" in told
    # bag recover: the bag readable (with rosbags too), each topic's count printed,
    # and the summary of what was recorded, said on a second line.
    recovered = result.output_of(".venv/bin/python -m servo_axis bag recover").splitlines()
    assert len(recovered) == 2 and recovered[1].startswith("runs/frf: summary.json written, of ")
    assert (bag / "metadata.yaml").is_file() and (bag / "bag_0.mcap.unfinished").is_file()
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert reader.message_count == sum(1 for _ in reader.messages())
    for topic in ("/x/state", "/x/command"):
        assert f"{topic} {counts[topic]}," in recovered[0], recovered[0]
    # The summary of what was recorded: every state in the bag, and why it ends there.
    states = counts["/x/state"]
    s = load_summary(run)
    assert isinstance(s, RunSummary) and s.health is not None
    assert 6100 <= s.steps == states < 8000 and s.sim_time_s == states * 5e-4
    assert s.health.outcome == "failed" and s.health.bag_recovered
    assert f"{states} of its 8000 steps were recorded" in s.health.reasons[0]
    assert "this summary was made after the run" in after.output

    # identify on the recovered run: the fit of the plain-call loop of the scenario the
    # page gives (its --set keys; 3 s, the excitation), key for key, near the truth.
    data = load_scenario(clone.root / "config" / "measure_frf_ball_screw.yaml")
    words = shlex.split(command.replace("\\\n", " "), comments=True)
    for value in (w for k, w in itertools.pairwise(words) if k == "--set"):
        key, _, number = value.partition("=")
        section, *path = key.split(".")
        node = data["/**" if section == "shared" else section]["ros__parameters"]
        for name in path[:-1]:
            node = node[name]
        node[path[-1]] = yaml.safe_load(number)
    assert data["feedforward"]["ros__parameters"]["excitation"]["periods"] == 3
    data["/**"]["ros__parameters"]["duration_s"] = 3.0
    short = tmp_path / "frf_short.yaml"
    short.write_text(yaml.safe_dump(data, sort_keys=False))
    plain = identify("ball_screw", [from_simulation(short)])
    out = clone.root / "runs" / "frf_axis.yaml"
    written = yaml.safe_load(out.read_text())["plant"]["ros__parameters"]
    assert_allclose(written["inertia_kgm2"], plain.key("inertia_kgm2").value, rtol=1e-12)
    assert_allclose(
        written["modes"]["frequency_hz"][0], plain.key("modes.frequency_hz[0]").value, rtol=1e-12
    )
    truth = data["plant"]["ros__parameters"]
    assert_allclose(written["inertia_kgm2"], truth["inertia_kgm2"], rtol=0.03)
    assert_allclose(written["modes"]["frequency_hz"], truth["modes"]["frequency_hz"], rtol=0.03)
    page = " ".join((clone.root / "docs" / "how-to" / "recover-a-bag.md").read_text().split())
    j, d, f = truth["inertia_kgm2"], truth["damping_Nms_per_rad"], truth["modes"]["frequency_hz"]
    assert f"{j} kg m^2, {d} N m s/rad, {f[0]:g} Hz" in page, (j, d, f)

    # The run directory is all identify needs: the scenario file moved, and one edited
    # in its place (another excitation, another plant), change nothing.
    shipped = clone.root / "config" / "measure_frf_ball_screw.yaml"
    edited = load_scenario(shipped)
    shipped.rename(shipped.with_name("moved.yaml"))
    edited["feedforward"]["ros__parameters"]["excitation"]["settle_periods"] = 2
    edited["plant"]["ros__parameters"]["current_limit_A"] = 12.3  # a key the fit copies
    shipped.write_text(yaml.safe_dump(edited, sort_keys=False))
    (clone.root / "runs" / "after_the_move").mkdir()
    again = clone.root / "runs" / "after_the_move" / out.name  # the name is the file's stem
    monkeypatch.chdir(clone.root)  # as the page's command, which the file's header names
    assert main(["identify", "runs/frf", "--model", "ball_screw", "--out", str(again)]) == 0
    assert yaml.safe_load(again.read_text()) == yaml.safe_load(out.read_text())

    def fitted(path: Path) -> list[str]:  # the header's "key = value +- error (source)" lines
        return [s for s in path.read_text().splitlines() if s.startswith("#   ") and " = " in s]

    assert len(fitted(out)) > 3 and fitted(again) == fitted(out)


@pytest.mark.realtime
def test_how_to_ros2_control(ros_env: int, clone: Clone) -> None:
    from test_outside_plant import joint_arrays, plant_clock_steps
    from test_ros2_control import TARGET, check_applied

    run_page("how-to/ros2-control.md", clone, ros_env)
    runs = clone.root / "runs"

    # ros2_control driving the emulated axis (the plugin publishing every cycle): the run
    # completes; the realtime block reports the misses, judged against the commander's
    # 2 ms period, and the set-points (NaN ones counted, never applied); the states are
    # the replay of set-points the stand-in sent.
    setpoint, log = summary(runs / "setpoint"), json.loads((runs / "standin.json").read_text())
    assert setpoint["health"]["outcome"] == "complete"
    rt = setpoint["realtime"]
    assert rt["ticks"] == 2000
    assert rt["misses"] == rt["commands_missing"] and rt["commands_late"] == 0
    # Exit 5 with more than 5 % misses (a starved stand-in may also go silent for 2 s:
    # loop_open, exit 5 too); else 0: nothing else is wrong with the run.
    code = setpoint["health"]["exit_code"]
    assert code == 5 or rt["misses"] <= 0.05 * rt["ticks"], rt
    if code == 5:
        assert setpoint["health"]["reasons"][0].startswith("the loop was not closed: ")
    # The host's floor, measured before it, beside its misses.
    (floor,) = [json.loads(line) for line in (runs / "floor.jsonl").read_text().splitlines()]
    assert rt["floor"] == floor and floor["period_us"] == 1000 and floor["ticks"] == 2000
    assert 0 <= floor["misses"] <= floor["ticks"]
    points = rt["setpoints"]
    assert points["period_ns"] == 2_000_000 and points["quiet_ticks"] == 0
    sent = sum(v is not None for v in log["published"])
    assert 0 < points["received"] <= sent  # none made up (and 2 s at 500 Hz: about 1000)
    assert 0 < points["unset"] <= sum(v is None for v in log["published"])
    assert not setpoint["health"]["nodes"]["plant"].get("rejected"), setpoint["health"]
    angle = check_applied(runs / "setpoint", log, 2000)
    assert abs(angle[-1] - TARGET) < 1e-3 * TARGET  # the PD settled on its target

    # The suite's controllers on an axis ros2_control drives, through the bridge: the
    # states carry the broadcaster's stamps from after the run started (its first
    # messages are not step 0), in the suite's layout, x_table's NaN replaced as the
    # page says; the summary's error is the bag's states' against the references of
    # their plant-clock steps; each torque the effort controller took is a recorded
    # command, in the order sent.
    out, drive = runs / "drive", summary(runs / "drive")
    standin = json.loads((runs / "drive_standin.json").read_text())
    assert drive["health"]["outcome"] == "complete"
    # 4: the stand-in's Python loop stalled for tens of ms and the loop tripped; 5
    # exactly when the misses exceed realtime.max_miss_fraction.
    code, rt = drive["health"]["exit_code"], drive["realtime"]
    assert (code == 5) == (rt["misses"] / rt["ticks"] > 0.05 and code != 4), (code, rt)
    steps_run, lead, limit = 2000, 0.00191, 21.45
    bag = out / "bag"
    stamps, position, velocity, effort = joint_arrays(bag, "/x/state")
    published = np.array(standin["stamps"])
    assert set(stamps.tolist()) <= set(published.tolist())  # the broadcaster's own stamps
    assert stamps[0] - published[0] > 10**9  # not its first message: the start rule
    assert np.all(np.diff(stamps) > 0)
    steps = plant_clock_steps(stamps)
    assert steps[-1] >= steps_run - 1  # the run ended on the broadcaster's clock
    assert_allclose(position[:, 1], lead * position[:, 0], rtol=1e-12, atol=0)
    assert_allclose(velocity[:, 1], lead * velocity[:, 0], rtol=1e-12, atol=0)  # NaN -> R w
    assert np.all(effort[:, 1] == 0.0)  # NaN friction force -> 0
    assert np.all(np.abs(effort[:, 0]) <= limit)  # the torque the axis held
    ref_stamps, reference, _, _ = joint_arrays(bag, "/x/reference")
    ref_of = dict(zip((ref_stamps // 1_000_000).tolist(), reference[:, 0], strict=True))
    within = steps < steps_run
    error = np.array([ref_of[k] for k in steps[within]]) - position[within, 0]
    rms = float(np.sqrt(np.mean((lead * error) ** 2)))
    assert_allclose(drive["tracking_error"]["all_samples"]["rms_m"], rms, rtol=1e-9)
    assert standin["dropped"] == 0 and not standin["deactivated"]
    command_stamps, _, _, torque = joint_arrays(bag, "/x/command")
    taken = standin["taken"]
    assert len(taken) >= 100, len(taken)
    it = iter(torque[:, 0].tolist())  # each taken value is the next recorded command it equals
    assert all(any(t == c for c in it) for t in taken), taken[:5]
    assert set(command_stamps.tolist()) <= set(stamps.tolist())  # each answers a state
    if code in (0, 5):  # not tripped: the axis followed the reference
        assert np.ptp(position[:, 0]) > 0.01, code  # rad
