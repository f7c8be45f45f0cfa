"""The closed loop of a scenario without ROS: plain function calls.

Builds the same core objects the nodes build from the same parameter file and
steps them in the order the lockstep protocol guarantees (state[k] ->
command[k] -> plant step). It is the reference that the node graph must
reproduce bit for bit, and the "core only" line of the benchmark.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from servo_axis.bringup import load_scenario, node_params, resolve_table
from servo_axis.nodes import feedback, feedforward, plant
from servo_axis.params import values_from_mapping


@dataclass(frozen=True)
class Trajectory:
    """Per-step signals of a core-only run (arrays of length ``steps``)."""

    encoder_rad: np.ndarray
    scale_m: np.ndarray
    reference_rad: np.ndarray
    feedforward_A: np.ndarray
    command_A: np.ndarray


def scenario_values(
    scenario: dict[str, Any], role: str, schema: dict[str, object]
) -> dict[str, Any]:
    """Checked parameter values of one node of a scenario (no ROS)."""
    return values_from_mapping(schema, node_params(scenario, role), role)


def feedforward_values(scenario: dict[str, Any], scenario_path: Path) -> dict[str, Any]:
    """Checked feedforward parameters, the friction-table path made absolute."""
    values = scenario_values(scenario, "feedforward", feedforward.SCHEMA)
    values["friction_table.file"] = resolve_table(
        values["friction_table.file"], scenario_path.resolve().parent
    )
    return values


def simulate(scenario_path: Path, *, steps: int | None = None) -> Trajectory:
    """Run the scenario's loop (plant, feedback, feedforward) as plain calls."""
    scenario = load_scenario(scenario_path)
    pv = scenario_values(scenario, "plant", plant.SCHEMA)
    fbv = scenario_values(scenario, "feedback", feedback.SCHEMA)
    ffv = feedforward_values(scenario, scenario_path)
    n = plant.run_steps(pv) if steps is None else steps
    sim = plant.BallScrewPlant(plant.plant_params(pv), rng=np.random.default_rng(pv["noise_seed"]))
    loop = feedback.build_loop(fbv)
    gen = feedforward.build_generator(ffv)
    refs = gen.samples(0, n)
    lead = pv["lead_m_per_rad"]
    use_scale = fbv["sensor"] == "scale"
    out = np.empty((n, 5))
    y = sim.output()
    for k in range(n):
        r, _, u_ff = refs[k]
        angle = y.scale_m / lead if use_scale else y.encoder_rad
        u = loop.update(angle_rad=angle, reference_rad=r, feedforward_A=u_ff).current_A
        out[k] = (y.encoder_rad, y.scale_m, r, u_ff, u)
        y = sim.step(u)
    return Trajectory(*(out[:, i].copy() for i in range(5)))
