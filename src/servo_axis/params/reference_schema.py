"""The reference trajectory's keys, ``reference.*``, of the feedforward and the learning unit.

Both nodes generate the same reference from these keys (the learning unit's
are copied from the feedforward section by the resolver,
:mod:`servo_axis.params.resolve`), so they are declared once, here, and
:mod:`servo_axis.params.schemas` adds them to
:data:`~servo_axis.params.schemas.FEEDFORWARD` and
:data:`~servo_axis.params.schemas.LEARNING`.
"""

from __future__ import annotations

from servo_axis.params.param import Param

#: The reference trajectory (at the table), read by the feedforward and the learning unit.
REFERENCE: dict[str, Param] = {
    "reference.kind": Param(
        "sine",
        choices=("sine", "one_minus_cos", "point_to_point", "trials", "segments"),
        meaning="trajectory: offset + A sin(2 pi f t + phase); A (1 - cos 2 pi f t); "
        "minimum-jerk moves back and forth; trials of out-and-back moves (001); "
        "half-cosine moves one after the other (004 Fig. 11)",
    ),
    "reference.amplitude_m": Param(
        0.01,
        unit="m",
        minimum=0.0,
        meaning="amplitude A (sine, one_minus_cos); 000 Fig. 18: 10 mm",
    ),
    "reference.frequency_hz": Param(
        2.0,
        unit="Hz",
        above=0.0,
        meaning="frequency f (sine, one_minus_cos)",
    ),
    "reference.offset_m": Param(
        0.0, unit="m", meaning="offset of the sine; rest position of the trials"
    ),
    "reference.phase_rad": Param(0.0, unit="rad", meaning="phase of the sine at t = 0"),
    "reference.ramp_s": Param(
        0.0,
        unit="s",
        minimum=0.0,
        meaning="sine: time over which the phase speeds up smoothly from rest; 0 = none",
    ),
    "reference.distance_m": Param(
        0.01,
        unit="m",
        meaning="point_to_point: move length d (either sign, non-zero)",
    ),
    "reference.move_time_s": Param(
        0.2,
        unit="s",
        above=0.0,
        meaning="point_to_point: duration T of one minimum-jerk move",
    ),
    "reference.dwell_s": Param(
        0.1,
        unit="s",
        minimum=0.0,
        meaning="point_to_point: standstill after each move",
    ),
    "reference.trial_s": Param(
        1.0,
        unit="s",
        above=0.0,
        meaning="trials: length T of one trial (N = T / T_u samples; the learning period of "
        "a trial law)",
    ),
    "reference.amplitudes_m": Param(
        [0.002, 0.003],
        unit="m",
        meaning="trials: amplitude A of each trajectory x = offset + A sin^4(pi u) "
        "(out and back, one velocity reversal at its middle)",
    ),
    "reference.move_times_s": Param(
        [0.6, 0.5],
        unit="s",
        above=0.0,
        meaning="trials: duration T_m of each trajectory's move",
    ),
    "reference.start_times_s": Param(
        [0.1, 0.2],
        unit="s",
        minimum=0.0,
        meaning="trials: start t_0 of each trajectory's move within the trial "
        "(t_0 + T_m < trial_s: at rest at both ends)",
    ),
    "reference.first_trials": Param(
        [1, 6],
        minimum=1,
        meaning="trials: the trial (1-based) from which each trajectory is run; 1 first, "
        "increasing (001 Fig. 9a: Ref. 1 for trials 1-5, Ref. 2 from trial 6)",
    ),
    "reference.segment_distances_m": Param(
        [0.05, -0.05],
        unit="m",
        meaning="segments: distance d_i of each half-cosine move, non-zero; opposite signs "
        "meet at a reversal, equal signs at a stop without one",
    ),
    "reference.segment_durations_s": Param(
        [0.5, 0.5],
        unit="s",
        above=0.0,
        meaning="segments: duration T_i of each move (deceleration into its stop "
        "|d_i| (pi / T_i)^2 / 2)",
    ),
    "reference.segment_delay_s": Param(
        0.1, unit="s", minimum=0.0, meaning="segments: rest before the first move"
    ),
}
