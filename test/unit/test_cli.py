"""The command line's bad options: one line on stderr, exit 2, nothing created.

Everything here is refused before a node starts (``main`` in this process);
the runs themselves are in test/integration.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from servo_axis.__main__ import EXAMPLES, build_parser, main
from servo_axis.analysis.metrics import error_statistics
from servo_axis.analysis.summary import RunSummary
from servo_axis.analysis.text import last_cycle_table, reduction, rmsd_table
from servo_axis.core.errors import ConfigError
from servo_axis.params.names import check_domain_id, check_namespace, namespace_problem


def one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err
    return err.strip()


# --------------------------------------------------------------------------- names


@pytest.mark.parametrize("name", ["/", "/x", "/machine_1/x", "/_a/B9", "/" + "a" * 244])
def test_namespaces_ros_accepts(name: str) -> None:
    assert namespace_problem(name) is None
    assert check_namespace(name) == name


@pytest.mark.parametrize(
    ("name", "problem"),
    [
        ("", "empty"),
        ("x", "absolute"),
        ("/bad-name", "segment 'bad-name'"),
        ("/a//b", "'//'"),
        ("/a/", "end with '/'"),
        ("/9a", "segment '9a'"),
        ("/a b", "segment 'a b'"),
        ("/~a", "segment '~a'"),
        ("/" + "a" * 245, "at most 245"),
    ],
)
def test_namespaces_ros_rejects(name: str, problem: str) -> None:
    found = namespace_problem(name)
    assert found is not None and problem in found
    with pytest.raises(ConfigError, match="--namespace"):
        check_namespace(name)


def test_domain_ids() -> None:
    assert check_domain_id("0") == 0 and check_domain_id(232) == 232
    for bad, why in (("-1", "outside 0..232"), ("233", "outside"), ("x", "not an integer")):
        with pytest.raises(ConfigError, match=f"ROS_DOMAIN_ID: .*{why}"):
            check_domain_id(bad, "ROS_DOMAIN_ID")


# --------------------------------------------------------------------------- run


@pytest.mark.parametrize(
    ("option", "value", "named"),
    [
        ("--domain-id", "-1", "outside 0..232"),
        ("--domain-id", "999", "999 is outside 0..232"),
        ("--domain-id", "1.5", "not an integer"),
        ("--namespace", "/bad-name", "'/bad-name' is not a valid ROS namespace"),
        ("--namespace", "x", "absolute"),
        ("--namespace", "/x/", "end with '/'"),
        ("--respawn-limit", "-1", "expected an integer >= 0"),
        ("--external-timeout", "-5", "'-5': expected a finite number > 0"),
        ("--external-timeout", "0", "expected a finite number > 0"),
        ("--external-timeout", "inf", "expected a finite number > 0"),
        ("--live-port", "0", "'0': expected an integer 1..65535"),
        ("--live-port", "70000", "expected an integer 1..65535"),
        ("--live-port", "x", "expected an integer 1..65535"),
    ],
)
def test_run_refuses_a_bad_option_before_anything(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, value: str, named: str
) -> None:
    out = tmp_path / "run"
    assert main(["run", "ptc_nominal", "--out", str(out), f"{option}={value}"]) == 2
    err = one_line_error(capsys)
    assert err.startswith(f"error: argument {option}: ") and named in err
    assert not out.exists()


def test_run_names_the_out_it_cannot_create(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    afile = tmp_path / "file"
    afile.write_text("x")
    for out, why in (
        (Path("/proc/x"), "[Errno 2]"),
        (afile / "run", "[Errno 20] Not a directory"),
    ):
        assert main(["run", "ptc_nominal", "--out", str(out)]) == 2
        err = one_line_error(capsys)
        assert err.startswith(f"error: --out {out}: cannot create it: {why}"), err
        assert not out.exists()
    assert main(["run", "ptc_nominal", "--out", str(afile)]) == 2
    assert one_line_error(capsys) == f"error: --out {afile}: exists and is not a directory"


def test_run_refuses_a_bad_ros_domain_id_from_the_environment(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", "999")
    out = tmp_path / "run"
    assert main(["run", "ptc_nominal", "--out", str(out)]) == 2
    assert one_line_error(capsys) == (
        "error: ROS_DOMAIN_ID: 999 is outside 0..232 (the ROS 2 domain id range)"
    )
    assert not out.exists()


# --------------------------------------------------------------------------- other commands


def test_summary_and_compare_of_a_directory_that_is_not_a_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for argv in (["summary", str(tmp_path)], ["compare", str(tmp_path)]):
        assert main(argv) == 2
        assert one_line_error(capsys) == f"error: {tmp_path}: not a run directory: no summary.json"
    assert main(["summary", str(tmp_path / "none")]) == 2
    assert "not a run directory: no such directory" in one_line_error(capsys)
    # A run killed before its runner wrote the summary: what to do next, for each bag.
    for bags in (["bag"], ["x/bag", "y/bag"]):
        run = tmp_path / "killed" / str(len(bags))
        for bag in bags:
            (run / bag).mkdir(parents=True)
        identify = [
            "identify",
            str(run),
            "--model",
            "ball_screw",
            "--out",
            str(tmp_path / "x.yaml"),
        ]
        for argv in (["summary", str(run)], identify):
            assert main(argv) == 2
            recover = " and ".join(f"python -m servo_axis bag recover {run / b}" for b in bags)
            assert one_line_error(capsys) == (
                f"error: {run}: no summary.json: the run has not ended, or was killed before its "
                f"runner wrote it; {recover} makes its bag readable and writes the summary of "
                "what was recorded"
            )
    (tmp_path / "summary.json").write_text('{"steps": 3}')
    assert main(["summary", str(tmp_path)]) == 2
    assert "summary.json: not a servo_axis run summary: missing key 'scenario'" in one_line_error(
        capsys
    )
    (tmp_path / "summary.json").write_text("{not json")
    assert main(["summary", str(tmp_path)]) == 2
    assert "not a servo_axis run summary" in one_line_error(capsys)
    assert main(["friction-table", str(tmp_path / "none"), "--out", str(tmp_path / "t.csv")]) == 2
    assert "not a run directory" in one_line_error(capsys)


@pytest.mark.parametrize(
    "argv",
    [
        ["friction-table", "r", "--out", "t.csv", "--bin-width-m", "0"],
        ["friction-table", "r", "--out", "t.csv", "--max-displacement-m", "nan"],
        ["friction-table", "r", "--out", "/nonexistent/t.csv"],
        ["gms-fit", "r", "--out", "g.txt", "--elements", "21"],
        ["gms-fit", "r", "--out", "g.txt", "--plot", "/nonexistent/f.png"],
        ["compare", "r", "--zoom-cycle", "0"],
        ["compare", "r", "--out", "/nonexistent/c.png"],
        ["list", "--config-dir", "/nonexistent"],
        ["run"],
        ["nosuchcommand"],
    ],
)
def test_every_other_option_is_checked_in_one_line(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(argv) == 2
    err = one_line_error(capsys)
    assert err.startswith("error: ") and err.endswith("--help)")


def test_list_of_a_folder_without_scenarios(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["list", "--config-dir", str(tmp_path)]) == 2
    assert (
        one_line_error(capsys)
        == f"error: --config-dir {tmp_path}: no scenario files (*.yaml) there"
    )


def test_every_argument_has_help_and_the_help_ends_with_examples(
    capsys: pytest.CaptureFixture[str],
) -> None:
    def parsers(p: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
        found = [p]
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    found += parsers(sub)
        return found

    every = parsers(build_parser())
    # main, run, friction-table, gms-fit, sweep, identify, summary, list, params, compare,
    # bag, recover, floor
    assert len(every) == 13
    for p in every:
        for action in p._actions:
            assert action.help and action.help != argparse.SUPPRESS, (p.prog, action.dest)
    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    assert text.rstrip().endswith(EXAMPLES.rstrip())
    assert "python -m servo_axis run ptc_nominal --out runs/ptc" in text


# --------------------------------------------------------------------------- compare


def summary(cycle_s: float | None = 0.25, scale: float = 1.0, **changes: Any) -> RunSummary:
    """A 1 s run at T_u = 1 ms, error ``scale`` um times a sine of the cycle."""
    step = np.arange(1000)
    e = scale * 1e-6 * np.sin(2 * np.pi * step / 250 + 0.3)
    stats = error_statistics(e, step, period_s=1e-3, cycle_s=cycle_s)
    data = {
        "scenario": "demo",
        "description": "",
        "scenario_file": "/nonexistent/demo.yaml",
        "processes": "separate processes",
        "time_mode": "lockstep",
        "control_period_s": 0.001,
        "steps": 1000,
        "sim_time_s": 1.0,
        "wall_time_s": 0.5,
        "steps_per_s": 2000.0,
        "realtime_factor": 2.0,
        "message_counts": {},
        "faults": [],
        "ptc": True,
        "friction_table": False,
        "reference_period_s": cycle_s,
        "tracking_error": stats,
        **changes,
    }
    return RunSummary.from_dict(data)


def write_run(path: Path, s: RunSummary, reference: dict[str, Any] | None = None) -> str:
    path.mkdir()
    (path / "summary.json").write_text(s.to_json())
    if reference is not None:  # the runner's params.yaml layout
        params = {
            "/**": {"ros__parameters": {"control_period_s": 0.001, "duration_s": 1.0}},
            "/**/plant": {"ros__parameters": {}},
            "/**/feedforward": {"ros__parameters": {"reference": reference}},
        }
        (path / "params.yaml").write_text(yaml.safe_dump(params))
    return str(path)


def test_compare_refuses_runs_with_another_cycle_or_period_unless_forced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = write_run(tmp_path / "a", summary(0.25))
    b = write_run(tmp_path / "b", summary(0.5))
    c = write_run(tmp_path / "c", summary(0.25, control_period_s=0.0005))
    assert main(["compare", a, b]) == 2
    assert one_line_error(capsys) == (
        "error: the runs do not compare: cycle: a 0.25 s, b 0.5 s (--force compares them anyway)"
    )
    assert main(["compare", a, c]) == 2
    assert "control period: a 0.001 s, c 0.0005 s" in one_line_error(capsys)
    assert main(["compare", a, b, "--force"]) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith("warning: compared anyway (--force): cycle: a 0.25 s, b 0.5 s")
    assert captured.out.startswith("max tracking error per cycle (um)")


def test_compare_refuses_runs_with_another_reference(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sine = {"kind": "sine", "amplitude_m": 0.01, "frequency_hz": 4.0}
    a = write_run(tmp_path / "a", summary(), sine)
    b = write_run(tmp_path / "b", summary(), {**sine, "frequency_hz": 2.0})
    same = write_run(tmp_path / "same", summary(scale=0.5), sine)
    steps = write_run(tmp_path / "steps", summary(), {"kind": "point_to_point"})
    assert main(["compare", a, b]) == 2
    assert "reference.frequency_hz: a 4, b 2" in one_line_error(capsys)
    assert main(["compare", a, steps]) == 2
    assert "reference.kind: a sine, steps point_to_point" in one_line_error(capsys)
    assert main(["compare", a, same]) == 0
    out = capsys.readouterr().out
    # The headline: half the max and half the RMS of a in the last cycle.
    row = next(line for line in out.splitlines() if line.startswith("same "))
    assert_allclose([float(x) for x in row.split()[3::2]], [50.0, 50.0], atol=0.006)


def test_a_reduction_against_a_zero_base_is_n_a_and_columns_never_touch() -> None:
    assert math.isnan(reduction(1e-6, 0.0)) and math.isnan(reduction(1e-6, 5e-13))
    assert_allclose(reduction(0.5e-6, 2e-6), 75.0, rtol=1e-12)
    tiny = summary(scale=1e-11)  # ~1e-17 m: a PTC on its own nominal model
    big = summary(scale=5.8713e5)  # 0.587 m, a wider number than its column
    labels = ["ptc", "a_rather_long_label"]
    table = last_cycle_table([tiny, big], labels)
    rows = table.splitlines()[2:]
    assert [r.split() for r in rows][1][3] == "n/a"
    for row in rows:
        assert len(row.split()) == 6, row  # label, cycle, max, cut, RMS, cut: never run together
    rmsd = rmsd_table([tiny, big], labels).splitlines()[2:]
    assert [r.split()[2] for r in rmsd] == ["base", "n/a"]
    # A value wider than its column still keeps two spaces to the next.
    huge = summary(scale=-1.234567e12)
    for row in last_cycle_table([summary(), huge], ["a", "b"]).splitlines()[2:]:
        assert len(row.split()) == 6, row


def test_a_zoom_cycle_outside_the_runs_cycles_is_one_line_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`compare q q5 --zoom-cycle 9` on 6-cycle runs drew an empty panel and exited 0."""
    a = write_run(tmp_path / "a", summary())  # 4 cycles of 0.25 s
    b = write_run(tmp_path / "b", summary(scale=0.5))
    out, error_out = tmp_path / "c.png", tmp_path / "e.png"
    argv = ["compare", a, b, "--out", str(out), "--error-out", str(error_out)]
    assert main([*argv, "--zoom-cycle", "9"]) == 2
    assert one_line_error(capsys) == (
        "error: --zoom-cycle 9: not a complete cycle of a, b; every run completed cycles 1 to 4"
    )
    assert not out.exists() and not error_out.exists()
    assert capsys.readouterr().out == ""  # no table either
    aperiodic = write_run(tmp_path / "n", summary(cycle_s=None))
    assert (
        main(["compare", aperiodic, aperiodic, "--error-out", str(error_out), "--zoom-cycle", "1"])
        == 2
    )
    assert "no cycle is complete in every run" in one_line_error(capsys)
    assert not error_out.exists()
