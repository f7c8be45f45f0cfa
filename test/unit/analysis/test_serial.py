"""The one serialiser of the summary's dataclasses (analysis/serial.py).

The summaries under ``test/data/summaries`` are the ``summary.json`` of real
runs (ptc_nominal, rptc_ideal, dlpid_tilt_lpf2 shortened to 2 s,
fast_reversal_sigmoid), three written by the hand-written ``to_dict`` methods
this serialiser replaced: they must read and write back byte for byte, and
every dataclass value in them must survive ``from_dict(to_dict(x))`` exactly
(type for type: tuples stay tuples, ints ints). The rotary one,
``dlpid_tilt_lpf2_short``, names its errors in rad (``rms_rad``, issue 43):
it is the ``summary.json`` of ``python -m servo_axis run`` of
``dlpid_tilt_lpf2`` with ``/**.duration_s: 2.0``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import pytest

from servo_axis.analysis import serial
from servo_axis.analysis.health import NodeDeath, RunHealth
from servo_axis.analysis.metrics import ContourCycle
from servo_axis.analysis.signals import FaultRecord
from servo_axis.analysis.summary import (
    AxesSummary,
    ContourSummary,
    CycleStats,
    Deformation,
    DeformationStop,
    DeformationWindow,
    ErrorStats,
    Identification,
    ParameterValues,
    Realtime,
    ReferenceStop,
    RunSummary,
    SampleStats,
    TrackingError,
    UpdateCounts,
    load_summary,
    summary_from_dict,
)
from servo_axis.core.errors import ConfigError

DATA = Path(__file__).resolve().parents[2] / "data" / "summaries"
SHIPPED = sorted(DATA.glob("*.json"))

#: Every dataclass of ``summary.json``: the round trip must meet each one.
SUMMARY_CLASSES = {
    AxesSummary, ContourSummary, ContourCycle, CycleStats, Deformation, DeformationStop,
    DeformationWindow, ErrorStats, FaultRecord, Identification, NodeDeath, ParameterValues,
    Realtime, ReferenceStop, RunHealth, RunSummary, SampleStats, TrackingError, UpdateCounts,
}  # fmt: skip

REALTIME = {
    "period_ns": 1_000_000,
    "ticks": 1000,
    "misses": 7,
    "commands_missing": 2,
    "commands_late": 5,
    "timer_rate": 0.9996,
    "tick_late_us": {"p50": 3.1, "p99": 240.0, "max": 1800.0},
    "command_late_us": {"p50": 310.0, "p99": 980.0, "max": 4200.0},
    "floor": {"period_s": 0.001, "p99_us": 80.0},
    "scheduling": {"policy": "other", "priority": 0, "refused": "no CAP_SYS_NICE"},
}


def same(a: Any, b: Any, where: str = "") -> None:
    """``a`` and ``b`` equal value for value and type for type (NaN equal to NaN)."""
    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, tuple | list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            same(x, y, f"{where}[{i}]")
    elif isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, float) and math.isnan(a):
        assert math.isnan(b), where
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def dataclass_values(obj: Any) -> list[Any]:
    """Every dataclass instance in ``obj``, ``obj`` first, depth first."""
    found = []
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        found.append(obj)
        for f in dataclasses.fields(obj):
            found += dataclass_values(getattr(obj, f.name))
    elif isinstance(obj, tuple | list):
        for v in obj:
            found += dataclass_values(v)
    elif isinstance(obj, dict):
        for v in obj.values():
            found += dataclass_values(v)
    return found


def through_json(obj: Any) -> Any:
    """``obj.to_dict()`` written and read back as ``summary.json`` text is."""
    return json.loads(json.dumps(serial.to_dict(obj), indent=2, allow_nan=True))


def shipped(name: str) -> RunSummary:
    return RunSummary.from_json(DATA / f"{name}.json")


def built_values() -> list[Any]:
    """Summaries of real bags plus the blocks no shipped run has (realtime, deaths, faults, axes)."""
    runs = [RunSummary.from_json(p) for p in SHIPPED]
    base = runs[0]
    assert base.health is not None
    health = dataclasses.replace(
        base.health,
        outcome="failed",
        deterministic=False,
        exit_code=1,
        reasons=("feedback died",),
        deaths=(
            NodeDeath("feedback", -9, 0.25, 120, "restarted", 0.5),
            NodeDeath("learning", 1, 0.5, 240, "fallback"),
        ),
        bag_recovered=True,
    )
    faulted = dataclasses.replace(
        base,
        faults=(FaultRecord(step=1234, code=1, name="following_error", value=0.0021),),
        health=health,
        realtime=Realtime.from_dict(REALTIME),
        time_mode="realtime",
        period_name="trial",
        ilc_convergence={"nq": 2.0, "nominal": 0.5, "plant": 0.75},
    )
    contour = ContourSummary(
        axes=("x", "y"),
        centre_m=(0.001, -0.002),
        radius_m=0.01,
        target_radial_deviation_m=1e-7,
        circular_deviation_m=3.5e-6,
        max_radial_m=2.25e-6,
        cycles=(ContourCycle(1, 3.5e-6, 2.25e-6), ContourCycle(2, math.nan, math.nan)),
    )
    axes = AxesSummary(
        scenario="xy",
        description="two axes",
        wall_time_s=12.5,
        axes={"x": runs[0], "y": faulted},
        contour=contour,
        health=health,
    )
    stop = ReferenceStop(time_s=0.5, kind="reversal", deceleration_m_s2=1.25)
    return [*runs, faulted, axes, stop]


def test_the_shipped_summaries_are_the_four_runs() -> None:
    assert [p.stem for p in SHIPPED] == [
        "dlpid_tilt_lpf2_short", "fast_reversal_sigmoid", "ptc_nominal", "rptc_ideal"
    ]  # fmt: skip
    # The blocks they hold: an identification (dlpid), a deformation (elastic),
    # per-cycle statistics (ptc, rptc).
    assert shipped("dlpid_tilt_lpf2_short").identification is not None
    assert shipped("fast_reversal_sigmoid").deformation is not None
    assert len(shipped("rptc_ideal").tracking_error.cycles) == 7


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_a_shipped_summary_reads_and_writes_back_byte_for_byte(path: Path) -> None:
    text = path.read_text()
    assert RunSummary.from_json(path).to_json() == text
    assert summary_from_dict(json.loads(text)).to_json() == text
    # The generic to_dict is the file's mapping, key order included.
    data = json.loads(text)
    assert list(serial.to_dict(RunSummary.from_dict(data))) == list(data)


def test_every_summary_dataclass_round_trips_exactly() -> None:
    values = [v for top in built_values() for v in dataclass_values(top)]
    assert {type(v) for v in values} == SUMMARY_CLASSES
    for value in values:
        cls = type(value)
        again = cls.from_dict(through_json(value))
        same(again, value, cls.__name__)
        # and the generic function is the method
        same(serial.from_dict(cls, serial.to_dict(value)), value, cls.__name__)
        assert serial.to_dict(again) == serial.to_dict(value) or _has_nan(value)


def _has_nan(value: Any) -> bool:
    return "NaN" in json.dumps(serial.to_dict(value), allow_nan=True)


def test_an_axes_summary_round_trips_through_its_json_text() -> None:
    axes = built_values()[-2]
    assert isinstance(axes, AxesSummary)
    text = axes.to_json()
    again = AxesSummary.from_json(text)
    same(again, axes, "AxesSummary")
    assert again.to_json() == text
    assert isinstance(summary_from_dict(json.loads(text)), AxesSummary)


def test_omit_none_fields_are_not_written_and_read_back_as_none() -> None:
    run = shipped("ptc_nominal")
    data = run.to_dict()
    for name in ("period_name", "ilc_convergence", "error_unit", "identification"):
        assert name not in data
    for name in ("deformation", "realtime"):
        assert name not in data
    # A plain None field (no omit_none) is written as null.
    death = NodeDeath("feedback", 1, 0.5, 10, "fallback")
    assert death.to_dict()["restarted_after_s"] is None
    window = DeformationWindow(-0.1, -0.05, 0, None)
    assert window.to_dict() == {
        "start_s": -0.1, "end_s": -0.05, "valid_samples": 0, "mean_d_r_m_per_rad": None
    }  # fmt: skip
    assert DeformationWindow.from_dict(window.to_dict()) == window


def test_older_layouts_still_read() -> None:
    # A plant report before commands_late and the lateness percentiles.
    old = {k: REALTIME[k] for k in ("period_ns", "ticks", "misses", "commands_missing")}
    rt = Realtime.from_dict({**old, "timer_rate": 1})
    assert rt.commands_late == 0
    assert rt.tick_late_us is None and rt.command_late_us is None
    assert rt.floor is None and rt.scheduling is None
    # A number written as an int reads as the float its field holds.
    assert isinstance(rt.timer_rate, float) and rt.timer_rate == 1.0
    # A health block before nodes and bag_recovered.
    health = RunHealth.from_dict(
        {"outcome": "complete", "deterministic": True, "exit_code": 0, "reasons": [], "deaths": []}
    )
    assert health.nodes == {} and health.bag_recovered is False
    assert health.reasons == () and health.deaths == ()
    # A summary of before the optional blocks (no health, no identification, ...).
    data = shipped("ptc_nominal").to_dict()
    del data["health"]
    run = RunSummary.from_dict(data)
    assert run.health is None and run.realtime is None and run.deformation is None
    assert "health" not in run.to_dict()


def _keys(node: Any) -> set[str]:
    """Every key of a mapping and of the mappings and lists in it."""
    if isinstance(node, dict):
        return set(node).union(*(_keys(v) for v in node.values()))
    if isinstance(node, list):
        return set().union(*(_keys(v) for v in node))
    return set()


def test_a_rotary_run_names_its_errors_in_rad_and_an_older_one_still_reads() -> None:
    """issue 43: a tilting table's summary had ``rms_m`` keys holding rad."""
    text = (DATA / "dlpid_tilt_lpf2_short.json").read_text()
    data = json.loads(text)
    assert data["error_unit"] == "rad"
    keys = _keys(data["tracking_error"])
    assert {"rms_rad", "max_rad"} <= keys and not {k for k in keys if k.endswith("_m")}
    tilt = RunSummary.from_json(text)
    assert tilt.unit == "rad"
    assert tilt.rmsd == data["tracking_error"]["all_samples"]["rms_rad"]
    assert (
        tilt.tracking_error.cycles[0].reference_instants.max_m
        == (data["tracking_error"]["cycles"][0]["reference_instants"]["max_rad"])
    )
    # Written before the keys were named for rad: the same values read.
    older = {
        **data,
        "tracking_error": json.loads(json.dumps(data["tracking_error"]).replace('_rad"', '_m"')),
    }
    assert "rms_m" in older["tracking_error"]["all_samples"]
    same(RunSummary.from_dict(older), tilt, "older")
    assert RunSummary.from_dict(older).to_json() == text
    # In a multi-axis summary too; a linear axis keeps its m.
    axes = AxesSummary.from_dict(
        {"scenario": "two", "description": "", "wall_time_s": 1.0,
         "axes": {"tilt": data, "x": json.loads((DATA / "ptc_nominal.json").read_text())}}
    )  # fmt: skip
    written = axes.to_dict()["axes"]
    assert "rms_rad" in written["tilt"]["tracking_error"]["all_samples"]
    assert "rms_m" in written["x"]["tracking_error"]["all_samples"]


def test_unknown_keys_are_ignored() -> None:
    assert ErrorStats.from_dict({"rms_m": 1e-6, "max_m": 2e-6, "p99_m": 3.0}) == ErrorStats(
        1e-6, 2e-6
    )


def test_a_missing_key_is_named(tmp_path: Path) -> None:
    with pytest.raises(KeyError, match="max_m"):
        ErrorStats.from_dict({"rms_m": 1e-6})
    data = json.loads((DATA / "ptc_nominal.json").read_text())
    del data["steps"]
    (tmp_path / "summary.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"not a servo_axis run summary: missing key 'steps'"):
        load_summary(tmp_path)


def test_a_value_of_the_wrong_shape_names_its_field(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match=r"TrackingError\.cycles: expected a list, got int"):
        TrackingError.from_dict(
            {"all_samples": {"rms_m": 1, "max_m": 1}, "reference_instants": {"rms_m": 1, "max_m": 1},
             "cycles": 3}
        )  # fmt: skip
    data = json.loads((DATA / "rptc_ideal.json").read_text())
    data["tracking_error"] = "big"
    (tmp_path / "summary.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"RunSummary\.tracking_error: expected a mapping"):
        load_summary(tmp_path)


def test_to_dict_and_from_dict_refuse_what_is_not_a_dataclass() -> None:
    with pytest.raises(TypeError, match="expected a dataclass instance, got dict"):
        serial.to_dict({"a": 1})
    with pytest.raises(TypeError, match="expected a dataclass, got"):
        serial.from_dict(dict, {})  # type: ignore[type-var]
    with pytest.raises(TypeError, match="ErrorStats: expected a mapping, got list"):
        ErrorStats.from_dict([1, 2])  # type: ignore[arg-type]


def test_summary_false_fields_are_neither_written_nor_read() -> None:
    @dataclasses.dataclass(frozen=True)
    class WithSeries(serial.Serial):
        rms_m: float
        series: tuple[float, ...] = dataclasses.field(default=(), metadata={"summary": False})

    value = WithSeries(1.5, (1.0, 2.0))
    assert value.to_dict() == {"rms_m": 1.5}
    assert WithSeries.from_dict({"rms_m": 1.5, "series": [9.0]}) == WithSeries(1.5)


def test_identification_values_come_back_as_numbers_not_strings() -> None:
    ident = shipped("dlpid_tilt_lpf2_short").identification
    assert isinstance(ident, Identification)
    assert isinstance(ident.final, ParameterValues) and isinstance(ident.updates, UpdateCounts)
    assert all(isinstance(v, float) for v in ident.final.values())
    assert isinstance(ident.updates.inertia_kgm2, int)
    deformation = shipped("fast_reversal_sigmoid").deformation
    assert isinstance(deformation, Deformation)
    assert all(isinstance(s, DeformationStop) for s in deformation.stops)
    assert all(isinstance(w, DeformationWindow) for s in deformation.stops for w in s.windows)
    assert isinstance(shipped("rptc_ideal").tracking_error.after_first_cycle, SampleStats)
