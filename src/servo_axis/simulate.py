"""The closed loop of a scenario without ROS: plain function calls.

Builds the same core objects the nodes build, from the same checked
parameter values and the same factories (:mod:`servo_axis.params.factories`),
and steps them in the order the lockstep protocol guarantees (state[k] ->
command[k] -> plant step). It is the reference that the node graph must
reproduce bit for bit, and the "core only" line of the benchmark. It runs
any registered plant model. Nothing here imports rclpy.

The values cross the same conversions as on the wire
(:mod:`servo_axis.core.drive`): the feedforward current becomes the torque
of ``reference`` with the generator's nominal ``K_T`` and a current again
with the feedback's; the loop's current becomes the torque of ``command``
with the nominal ``K_T`` and the plant's current reference with the plant's
own ``K_T``; a learned input correction becomes the torque of
``learning/input_correction`` and a current again. :class:`Trajectory`
holds the torques as the bag has them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from servo_axis.core.drive import current_from_torque, torque_from_current
from servo_axis.core.feedback.loop import FeedbackLoop
from servo_axis.core.feedback.output import controlled_output
from servo_axis.core.models.base import Plant, PlantOutput
from servo_axis.params import factories
from servo_axis.params.resolve import Resolved
from servo_axis.params.scenario import load_scenario
from servo_axis.params.values import FeedbackValues, FeedforwardValues, PlantValues


@dataclass(frozen=True)
class Trajectory:
    """Per-step signals of a core-only run (arrays of length ``steps``).

    ``encoder_rad``, ``scale_m`` (the sensors), ``reference_rad`` (the
    feedback reference), ``feedforward_Nm`` and ``command_Nm`` (the torques
    of ``reference`` and ``command``, N m: what the node graph publishes).
    """

    encoder_rad: np.ndarray
    scale_m: np.ndarray
    reference_rad: np.ndarray
    feedforward_Nm: np.ndarray
    command_Nm: np.ndarray


@dataclass(frozen=True)
class _Drive:
    """The torque constants of the wire's conversions: the feedforward's, the
    feedback's (nominal) and the plant's."""

    feedforward: float
    feedback: float
    plant: float

    @classmethod
    def of(cls, ffv: FeedforwardValues, fbv: FeedbackValues, pv: PlantValues) -> _Drive:
        return cls(
            feedforward=ffv.nominal.torque_constant_Nm_per_A,
            feedback=fbv.nominal.torque_constant_Nm_per_A,
            plant=factories.drive_constant(pv),
        )

    def step(
        self, loop: FeedbackLoop, y: PlantOutput, r: float, u_ff: float
    ) -> tuple[float, float, float]:
        """``(feedforward torque, command torque, plant current)`` of one sample, as on the wire.

        The conversions of :mod:`servo_axis.core.drive` written out (the same
        multiplication and division each), and the loop's
        :meth:`~servo_axis.core.feedback.loop.FeedbackLoop.current`: this runs every sample.
        """
        tau_ff = u_ff * self.feedforward  # torque_from_current
        u = loop.current(
            encoder_rad=y.encoder_rad,
            scale_m=y.scale_m,
            reference_rad=r,
            feedforward_A=tau_ff / self.feedback,  # current_from_torque
        )
        tau = u * self.feedback
        return tau_ff, tau, tau / self.plant


def simulate(
    scenario_path: Path,
    *,
    steps: int | None = None,
    watch: Callable[[Plant], None] | None = None,
) -> Trajectory:
    """Run the scenario's loop (plant, feedback, feedforward) as plain calls.

    Parameters
    ----------
    scenario_path : Path
        The scenario file.
    steps : int or None
        Control samples to run; None: the scenario's duration.
    watch : callable or None
        Called with the plant at every sample, after the command is computed
        and before the plant steps (its ``output()`` is then the sample's
        state): a study's way to keep a plant's inner signals. It must not
        change the plant.
    """
    resolved = Resolved(load_scenario(scenario_path), scenario_path)
    pv, fbv, ffv = resolved.plant, resolved.feedback, resolved.feedforward
    n = factories.run_steps(pv) if steps is None else steps
    sim = factories.build_plant(pv)
    loop = factories.build_loop(fbv)
    gen = factories.build_generator(ffv)
    drive = _Drive.of(ffv, fbv, pv)
    refs = gen.samples(0, n)
    # Rows kept as tuples, made an array at the end (the same floats).
    rows: list[tuple[float, float, float, float, float]] = []
    record = rows.append
    step = drive.step
    y = sim.output()
    for k in range(n):
        r, _, u_ff = refs[k]
        tau_ff, tau, current = step(loop, y, r, u_ff)
        record((y.encoder_rad, y.scale_m, r, tau_ff, tau))
        if watch is not None:
            watch(sim)
        y = sim.step(current)
    return _trajectory(rows, n)


def _trajectory(rows: list[tuple[float, float, float, float, float]], n: int) -> Trajectory:
    """The :class:`Trajectory` of ``n`` rows ``(encoder, scale, r, tau_ff, tau)``."""
    out = np.array(rows, dtype=float).reshape(n, 5)
    return Trajectory(*(out[:, i].copy() for i in range(5)))


@dataclass(frozen=True)
class LearningRun:
    """A core-only run with its learning unit (:func:`simulate_learning`)."""

    trajectory: Trajectory
    error_m: np.ndarray  #: per period, the error the law learned from (m at the table)
    law: object  #: the learning law after the run


def simulate_learning(scenario_path: Path, *, steps: int | None = None) -> LearningRun:
    """Run the loop of a scenario with its learning law, as plain calls.

    What the node graph does in lockstep, in the same order
    (``docs/learning_protocol.md``). An input-side (trial) law: at the last
    sample of period ``j`` the law learns from the error of period ``j``
    (m at the table, every control sample) and the correction for period
    ``j + 1`` is set before its first sample. A target-side (cycle) law,
    RPTC of paper 000: at the last reference instant ``k_last`` of cycle
    ``j`` the law learns from the cycle's error at the reference instants
    (rad at the motor, against the original target), and ``c_{j+1}`` is set
    before ``reference[k_last]``, which needs ``x_d`` one instant into cycle
    ``j + 1`` (the boundary protocol). Either way learning starts with
    ``start_cycle`` and the run's last period is not learned from.
    """
    resolved = Resolved(load_scenario(scenario_path), scenario_path)
    pv, fbv, ffv = resolved.plant, resolved.feedback, resolved.feedforward
    lv = resolved.learning
    law = factories.build_learning_law(lv)
    n = factories.run_steps(pv) if steps is None else steps
    sim = factories.build_plant(pv)
    loop = factories.build_loop(fbv)
    gen = factories.build_generator(ffv)
    reference = factories.build_reference(ffv)
    tu = pv.control_period_s
    lead = pv.lead_m_per_rad
    sensor = fbv.sensor
    target_side = law.side == "target"
    # The learning unit's samples: the reference instants for a target-side law.
    stride = factories.grid(pv).ratio if target_side else 1
    period = law.samples_per_period * stride  # control samples per period
    drive = _Drive.of(ffv, fbv, pv)
    kt_learning = lv.nominal.torque_constant_Nm_per_A
    out = np.empty((n, 5))
    errors = []
    y = sim.output()

    def end_of_period(j: int, last: int) -> None:
        """Learn from period ``j`` (0-based; its samples up to ``last``) and set period ``j + 1``'s."""
        ks = np.arange(j * period, (j + 1) * period, stride)
        target = reference.sample(ks * tu)[0] / lead
        measured = controlled_output(
            sensor, encoder_rad=out[ks, 0], scale_m=out[ks, 1], lead_m_per_rad=lead
        )
        error = target - measured  # rad at the motor
        errors.append(lead * error)
        if j + 2 >= lv.start_cycle:
            law.learn(error if target_side else lead * error, period=j + 1)
        if target_side:
            position, velocity = law.next_correction(period=j + 2)
            gen.set_correction(j + 1, np.asarray(position, float), np.asarray(velocity, float))
            return
        (learned,) = law.next_correction(period=j + 2)
        # learning/input_correction: a torque with the learning unit's
        # K_T, a current again with the feedforward's.
        torque = torque_from_current(
            np.asarray(learned, dtype=float), torque_constant_Nm_per_A=kt_learning
        )
        gen.set_correction(
            j + 1, current_from_torque(torque, torque_constant_Nm_per_A=drive.feedforward)
        )

    for k in range(n):
        if target_side:
            # state[k_last] is in: c_{j+1} before reference[k_last].
            j, idx = divmod(k, period)
            out[k, :2] = (y.encoder_rad, y.scale_m)
            if idx == period - stride and (j + 1) * period < n:
                end_of_period(j, k)
            gen.repeat_past_run(n)
        ((r, _, u_ff),) = gen.samples(k, k + 1)
        tau_ff, tau, current = drive.step(loop, y, r, u_ff)
        out[k] = (y.encoder_rad, y.scale_m, r, tau_ff, tau)
        y = sim.step(current)
        if not target_side:
            j, idx = divmod(k, period)
            if idx == period - 1 and k + 1 < n:
                end_of_period(j, k)
    return LearningRun(Trajectory(*(out[:, i].copy() for i in range(5))), np.array(errors), law)


@dataclass(frozen=True)
class IdentificationRun:
    """A core-only run with the online identifier (:func:`simulate_identification`).

    ``estimates`` holds one row per estimate used (the values of an
    ``identifier/estimates`` message, :data:`servo_axis.wire.cdr.ESTIMATE_LABELS`).
    """

    trajectory: Trajectory
    estimates: np.ndarray
    angle_rad: np.ndarray  #: the true table angle at each step (no noise)


def simulate_identification(scenario_path: Path, *, steps: int | None = None) -> IdentificationRun:
    """Run the loop of a scenario with its identifier (paper 003), as plain calls.

    What the node graph does in lockstep, in the same order: ``state[k]``
    (the encoder angle), ``command[k]``, the identifier takes both (the
    torque of ``command[k]``, ``K_T i[k]`` with the nominal ``K_T``), and an estimate from step
    ``k`` is set in the generator, from ``k + 1 + latency``, before any
    sample from there on is computed; estimates that would apply after the
    run are not used (the node does not publish them). Without an
    identifier section it is the plain loop, with the true angle.
    """
    resolved = Resolved(load_scenario(scenario_path), scenario_path)
    pv, fbv, ffv = resolved.plant, resolved.feedback, resolved.feedforward
    identifier = None
    if resolved.has("identifier"):
        iv = resolved.identifier
        identifier = factories.build_identifier(iv)
        _, latency = factories.identifier_schedule(iv)
    n = factories.run_steps(pv) if steps is None else steps
    sim = factories.build_plant(pv)
    loop = factories.build_loop(fbv)
    gen = factories.build_generator(ffv)
    drive = _Drive.of(ffv, fbv, pv)
    samples: list[tuple[float, float, float, float, float]] = []
    record = samples.append
    angles: list[float] = []
    angle = angles.append
    rows: list[list[float | bool]] = []
    next_samples, current_of, take = gen.samples, loop.current, sim.step
    kt_ff, kt_fb, kt_plant = drive.feedforward, drive.feedback, drive.plant
    update = identifier.update if identifier is not None else None
    # The samples up to the next estimate's first step are given at once (what
    # the feedforward node's preview does; the generator cuts its blocks the same
    # way whatever is asked for, and nothing before that step uses the estimate).
    ahead: list[tuple[float, float, float]] = []
    ahead_start = ahead_end = 0
    y = sim.output()
    for k in range(n):
        if k >= ahead_end:
            waits = gen.next_estimate_step
            ahead_start, ahead_end = k, n if waits is None else min(waits, n)
            # (An estimate not set: sample k alone, which the generator refuses.)
            ahead_end = max(ahead_end, k + 1)
            ahead = next_samples(k, ahead_end)
        r, _, u_ff = ahead[k - ahead_start]
        # _Drive.step written out: the same conversions, one call fewer a sample.
        tau_ff = u_ff * kt_ff
        tau = (
            current_of(
                encoder_rad=y.encoder_rad,
                scale_m=y.scale_m,
                reference_rad=r,
                feedforward_A=tau_ff / kt_fb,
            )
            * kt_fb
        )
        current = tau / kt_plant
        record((y.encoder_rad, y.scale_m, r, tau_ff, tau))
        angle(y.angle_rad)
        if update is not None:
            e = update(k, y.encoder_rad, tau)
            if e is not None and e.step + 1 + latency < n:
                applies = e.step + 1 + latency
                gen.set_estimate(
                    applies,
                    inertia_kgm2=e.J,
                    damping_Nms_per_rad=e.D,
                    unbalance_Nm=e.U,
                    coulomb_Nm=e.C,
                )
                # The flags as bools: np.array makes the same 1.0 / 0.0 of them.
                rows.append([e.step, applies, e.J, e.D, e.U, e.C, e.kappa, *e.updated])
        y = take(current)
    return IdentificationRun(
        _trajectory(samples, n),
        np.array(rows, dtype=float).reshape(-1, 11),
        np.array(angles, dtype=float),
    )
