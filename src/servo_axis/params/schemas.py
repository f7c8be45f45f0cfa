"""Every node parameter, once: default, SI unit, allowed range and meaning.

One :class:`~servo_axis.params.schema.Param` per (dotted) key, per section of
a scenario file: :data:`SHARED` (``/**``), :data:`PLANT` and the keys of its
model (:data:`BALL_SCREW` for ``model: ball_screw``), :data:`FEEDBACK`,
:data:`FEEDFORWARD`, :data:`LEARNING` and :data:`RECORDER`. The ranges are
what each value means physically (a period is > 0, a gain >= 0); what
depends on several keys at once (``sim_step_s`` divides
``control_period_s``, ``n Nq + 2 < Nd``, ...) is checked by the objects the
values build. :data:`SECTIONS` lists them for the parameter reference
(``scripts/parameter_docs.py`` -> ``docs/parameters.md``).

Paper numbers refer to the papers of ``docs/papers.md`` (000: Fujimoto &
Takemura, RPTC with the n-times learning filter; 001: Hayashi et al.; 003:
Ge et al.; 004: Zhu & Fujimoto), "docs/design.md section 7" to the axis
presets of the design intent.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from servo_axis.core.feedback.loop import SafetyLimits
from servo_axis.core.feedforward.sigmoid import (
    PAPER_PRESLIDING_M,
    PAPER_SIGMA_M2_PER_RAD,
    gamma_for_width,
)
from servo_axis.core.friction.model import FrictionParams
from servo_axis.core.models.ball_screw import BallScrewParams, DisturbanceParams
from servo_axis.core.models.elastic_ball_screw import (
    NUT_FRICTION_MODELS,
    ElasticBallScrewParams,
)
from servo_axis.core.models.tilting_table import TiltingTableParams
from servo_axis.params.schema import Param
from servo_axis.wire import topics


def _dataclass_defaults(cls: type) -> dict[str, object]:
    """Field defaults of a core parameter dataclass (the axis preset is stated there once)."""
    return {
        f.name: f.default for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING
    }


_BALL_SCREW = _dataclass_defaults(BallScrewParams)
_FRICTION = _dataclass_defaults(FrictionParams)
_DISTURBANCE = _dataclass_defaults(DisturbanceParams)
_LIMITS = _dataclass_defaults(SafetyLimits)
_ELASTIC = _dataclass_defaults(ElasticBallScrewParams)
_SIGMOID_GAMMA = gamma_for_width(
    sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, half_width_m=PAPER_PRESLIDING_M / 2
)

#: Keys every node accepts (the ``/**`` block of a scenario file).
SHARED: dict[str, Param] = {
    "mode": Param(
        "lockstep",
        choices=("lockstep", "realtime"),
        meaning="time mode: lockstep = the plant owns /clock and waits for every input "
        "(deterministic); realtime = wall-clock steps, late inputs are deadline misses",
    ),
    "control_period_s": Param(
        _BALL_SCREW["control_period_s"],
        unit="s",
        minimum=1e-6,
        maximum=1.0,
        meaning="control period T_u (command hold, sampling of the loop); "
        "the reference period is T_r = 2 T_u (000 Sect. III)",
    ),
    "duration_s": Param(
        2.0,
        unit="s",
        above=0.0,
        meaning="length of the run: round(duration_s / control_period_s) >= 1 control samples",
    ),
    "axis": Param(
        "x",
        meaning="axis name: the JointState names are `<axis>_motor` and `<axis>_table`",
    ),
    "lead_m_per_rad": Param(
        _BALL_SCREW["lead_m_per_rad"],
        unit="m/rad",
        above=0.0,
        meaning="ball-screw lead R: table position x = R theta (docs/design.md section 7: 1.91 mm/rad)",
    ),
    "nominal.torque_constant_Nm_per_A": Param(
        0.715,
        unit="N m/A",
        above=0.0,
        meaning="K_T of the nominal plant P_n = K_T / (J s^2 + D s), eq. (1) of 000, "
        "used to design PID, DOB and PTC",
    ),
    "nominal.inertia_kgm2": Param(
        0.01,
        unit="kg m^2",
        above=0.0,
        meaning="J of the nominal plant P_n, eq. (1) of 000",
    ),
    "nominal.damping_Nms_per_rad": Param(
        0.1,
        unit="N m s/rad",
        minimum=0.0,
        meaning="D of the nominal plant P_n, eq. (1) of 000",
    ),
    "scenario.name": Param(
        "",
        meaning="scenario name (summary, plots; a learning memory file must carry the same)",
    ),
    "scenario.description": Param("", meaning="one-line description of the scenario"),
    "external_roles": Param(
        [""],
        meaning="roles played by nodes from outside the suite (any node name; `--external` of "
        "`run`): their topics' first publisher is the declared one, not a stranger; a subset "
        "of plant, feedback, feedforward, learning, identifier",
    ),
    "report_dir": Param(
        "",
        meaning="folder where each node writes `<node>.health.json` (rejected messages, "
        "strangers on its topics, fallbacks) for the run's summary; empty: none (the runner "
        "sets it to the run's logs/)",
    ),
}

#: The plant node's own keys; its model's keys are in the model's schema.
PLANT: dict[str, Param] = {
    "model": Param(
        "ball_screw",
        meaning="plant model (registered name): ball_screw = rigid ball-screw axis with "
        "resonance modes, dead time and friction, eq. (30) of 000",
    ),
    "noise_seed": Param(
        0,
        minimum=0,
        meaning="seed of the random generator of the sensor noise (same seed, same run)",
    ),
    "publish_clock": Param(
        True,
        meaning="publish /clock (the simulation time) for the nodes that use sim time",
    ),
    "clock_every_steps": Param(
        10,
        unit="steps",
        minimum=1,
        meaning="publish /clock every this many control samples (logs and timers only)",
    ),
    "wait_for_state_subscribers": Param(
        0,
        minimum=0,
        meaning="start only once this many subscribers of `state` have matched",
    ),
    "wait_for_clock_subscribers": Param(
        0,
        minimum=0,
        meaning="start only once this many subscribers of /clock have matched",
    ),
    "wait_for_status_subscribers": Param(
        0,
        minimum=0,
        meaning="start only once this many subscribers of `plant/status` have matched",
    ),
    "flow_control": Param(
        False,
        meaning="lockstep: wait for the recorder's acknowledgements (recorder/progress) "
        "so that it never loses a message",
    ),
    "max_recorder_lag_steps": Param(
        200,
        unit="steps",
        minimum=1,
        meaning="with flow_control: publish state[k] only once the recorder has step "
        "k - max_recorder_lag_steps",
    ),
    "command_timeout_s": Param(
        2.0,
        unit="s",
        above=0.0,
        meaning="lockstep: how long a gone feedback (liveliness of `command`) gets to come "
        "back before the plant applies zero current (a fallback; each such step counted as a "
        "command timeout); while it lives the plant waits however long it takes. Likewise how "
        "long a gone recorder gets before flow control is switched off. Realtime: unused",
    ),
    "status_every_steps": Param(
        50,
        unit="steps",
        minimum=1,
        meaning="publish plant/status (the feedforward's progress signal) every this many samples",
    ),
}

#: Keys of the plant with ``model: ball_screw``: eq. (30) of 000 with docs/design.md section 7 defaults.
BALL_SCREW: dict[str, Param] = {
    "torque_constant_Nm_per_A": Param(
        _BALL_SCREW["torque_constant_Nm_per_A"],
        unit="N m/A",
        above=0.0,
        meaning="K_T of eq. (30) of 000: motor torque per ampere of current (0.715)",
    ),
    "inertia_kgm2": Param(
        _BALL_SCREW["inertia_kgm2"],
        unit="kg m^2",
        above=0.0,
        meaning="J of eq. (30): rigid-body inertia at the motor (0.01)",
    ),
    "damping_Nms_per_rad": Param(
        _BALL_SCREW["damping_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="D of eq. (30): viscous damping at the motor (0.1)",
    ),
    "modes.frequency_hz": Param(
        [0.0],
        unit="Hz",
        minimum=0.0,
        meaning="resonance frequencies f_i of eq. (30), one per mode (> 0); "
        "all three modes.* lists [0.0] = no mode",
    ),
    "modes.zeta": Param(
        [0.0],
        minimum=0.0,
        meaning="damping ratios zeta_i of the modes of eq. (30) (> 0 for a mode)",
    ),
    "modes.a": Param(
        [0.0],
        meaning="relative gains a_i of the modes of eq. (30): K_i = a_i K_T / J (docs/design.md section 7)",
    ),
    "dead_time_s": Param(
        _BALL_SCREW["dead_time_s"],
        unit="s",
        minimum=0.0,
        meaning="dead time T_d of eq. (30) (000: 70 us), a whole number of sim_step_s",
    ),
    "sim_step_s": Param(
        _BALL_SCREW["sim_step_s"],
        unit="s",
        above=0.0,
        meaning="integration step h of the plant (exact ZOH); divides control_period_s",
    ),
    "current_limit_A": Param(
        _BALL_SCREW["current_limit_A"],
        unit="A",
        above=0.0,
        meaning="amplifier saturation: the current command is clipped to +-current_limit_A",
    ),
    "initial_angle_rad": Param(0.0, unit="rad", meaning="motor angle at step 0"),
    "initial_velocity_rad_s": Param(0.0, unit="rad/s", meaning="motor velocity at step 0"),
    "friction.rolling_coulomb_Nm": Param(
        _FRICTION["rolling_coulomb_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="rolling (Maxwell-slip) friction level T_c at the motor once the balls roll "
        "(region B, 000 Fig. 4; 001: 3.2 N m); 0 = off",
    ),
    "friction.presliding_width_m": Param(
        _FRICTION["presliding_width_m"],
        unit="m",
        above=0.0,
        meaning="pre-sliding width at the table: displacement from a reversal at which rolling "
        "friction reaches T_c (region A; about 10 um)",
    ),
    "friction.elements": Param(
        _FRICTION["elements"],
        minimum=1,
        maximum=200,
        meaning="number of Maxwell-slip elements (knots of the piecewise-linear virgin curve)",
    ),
    "friction.coulomb_Nm": Param(
        _FRICTION["coulomb_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="plain Coulomb friction level at the motor, T_c tanh(w / w_s); 0 = off",
    ),
    "friction.coulomb_smoothing_rad_s": Param(
        _FRICTION["coulomb_smoothing_rad_s"],
        unit="rad/s",
        above=0.0,
        meaning="velocity w_s of the tanh regularisation of the Coulomb term",
    ),
    "friction.viscous_Nms_per_rad": Param(
        _FRICTION["viscous_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="viscous friction at the motor, in addition to the damping D",
    ),
    "disturbance.amplitude_Nm": Param(
        _DISTURBANCE["amplitude_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="amplitude A of the input disturbance torque A sin(2 pi f t + phi) at the motor "
        "(000 Fig. 13); 0 = none",
    ),
    "disturbance.frequency_hz": Param(
        _DISTURBANCE["frequency_hz"],
        unit="Hz",
        above=0.0,
        meaning="frequency f of the input disturbance torque",
    ),
    "disturbance.phase_rad": Param(
        _DISTURBANCE["phase_rad"],
        unit="rad",
        meaning="phase phi of the input disturbance torque at t = 0",
    ),
    "encoder.resolution": Param(
        2.0 * math.pi / 2**20,
        unit="rad",
        minimum=0.0,
        meaning="rotary-encoder count on the motor angle (2 pi / 2^20 rad, docs/design.md section 7); 0 = ideal",
    ),
    "encoder.noise_std": Param(
        0.0,
        unit="rad",
        minimum=0.0,
        meaning="standard deviation of Gaussian encoder noise before quantisation",
    ),
    "scale.resolution": Param(
        100e-9,
        unit="m",
        minimum=0.0,
        meaning="linear-scale count on the table position (100 nm, docs/design.md section 7); 0 = ideal",
    ),
    "scale.noise_std": Param(
        0.0,
        unit="m",
        minimum=0.0,
        meaning="standard deviation of Gaussian scale noise before quantisation",
    ),
}

#: Keys of the plant model ``tilting_table`` (paper 003 eq. (2); defaults: its Table I).
_TILT = _dataclass_defaults(TiltingTableParams)
TILTING_TABLE: dict[str, Param] = {
    "torque_constant_Nm_per_A": Param(
        _TILT["torque_constant_Nm_per_A"],
        unit="N m/A",
        above=0.0,
        meaning="K_T: the wire carries a current i, the motor torque is T_m = K_T i",
    ),
    "inertia_kgm2": Param(
        _TILT["inertia_kgm2"], unit="kg m^2", above=0.0, meaning="J of 003 eq. (2) (50e-4)"
    ),
    "damping_Nms_per_rad": Param(
        _TILT["damping_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="D of 003 eq. (2) (130e-4)",
    ),
    "unbalance_Nm": Param(
        _TILT["unbalance_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="U = F R of 003 eq. (1)-(2), the largest unbalance torque (0.3)",
    ),
    "coulomb_Nm": Param(
        _TILT["coulomb_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="C of 003 eq. (2): Coulomb friction that sticks at zero velocity (0.02)",
    ),
    "sim_step_s": Param(
        _TILT["sim_step_s"],
        unit="s",
        above=0.0,
        meaning="RK4 sub-step of the integration; divides control_period_s",
    ),
    "current_limit_A": Param(
        _TILT["current_limit_A"],
        unit="A",
        above=0.0,
        meaning="amplifier saturation (15.27: the test bench's peak torque at K_T = 1)",
    ),
    "initial_angle_rad": Param(0.0, unit="rad", meaning="table angle at step 0"),
    "initial_velocity_rad_s": Param(0.0, unit="rad/s", meaning="table velocity at step 0"),
    "noise_rad": Param(
        _TILT["noise_rad"],
        unit="rad",
        minimum=0.0,
        meaning="half-width of the uniform encoder noise, seeded by noise_seed (003: 1e-5)",
    ),
    "encoder.resolution": Param(
        _TILT["encoder_resolution_rad"],
        unit="rad",
        minimum=0.0,
        meaning="encoder count applied after the noise; 0 = ideal",
    ),
}

#: Keys of the plant model ``elastic_ball_screw`` (paper 004; defaults and the
#: choices behind them: :mod:`servo_axis.core.models.elastic_ball_screw`).
ELASTIC_BALL_SCREW: dict[str, Param] = {
    "torque_constant_Nm_per_A": Param(
        _ELASTIC["torque_constant_Nm_per_A"], unit="N m/A", above=0.0, meaning="K_T (004 Table I)"
    ),
    "motor_inertia_kgm2": Param(
        _ELASTIC["motor_inertia_kgm2"],
        unit="kg m^2",
        above=0.0,
        meaning="J_m: motor and screw rotation (J_n - M_t R^2 = 1.604e-3, so that the rigid "
        "body is J_n = 2.6e-3 of 004 eq. (1))",
    ),
    "motor_damping_Nms_per_rad": Param(
        _ELASTIC["motor_damping_Nms_per_rad"],
        unit="N m s/rad",
        minimum=0.0,
        meaning="B_m (B_n - C_t R^2 = 0.0335, so that the rigid body has B_n = 0.070)",
    ),
    "table_mass_kg": Param(
        _ELASTIC["table_mass_kg"],
        unit="kg",
        above=0.0,
        meaning="M: nut and table (004 Table I: 273)",
    ),
    "table_damping_Ns_per_m": Param(
        _ELASTIC["table_damping_Ns_per_m"],
        unit="N s/m",
        minimum=0.0,
        meaning="C_t: viscosity of the linear guide (004 Table I: 1e4)",
    ),
    "axial_stiffness_N_per_m": Param(
        _ELASTIC["axial_stiffness_N_per_m"],
        unit="N/m",
        above=0.0,
        meaning="k_a: screw axial, nut and bearings in series (1.55e8: first axial mode 150 Hz); "
        "a mode outside 100-200 Hz is logged as a warning",
    ),
    "torsional_stiffness_Nm_per_rad": Param(
        _ELASTIC["torsional_stiffness_Nm_per_rad"],
        unit="N m/rad",
        above=0.0,
        meaning="k_t: screw torsion between motor and nut, in series with k_a as R^2 / k_t",
    ),
    "screw_damping_Ns_per_m": Param(
        _ELASTIC["screw_damping_Ns_per_m"],
        unit="N s/m",
        minimum=0.0,
        meaning="c_s: structural damping of the deformation (1.6e4: about 5 % on the axial mode)",
    ),
    "contact_zone_m": Param(
        _ELASTIC["contact_zone_m"],
        unit="m",
        minimum=0.0,
        meaning="g: soft zone of the ball contacts around zero load (004 Fig. 7: nonlinear "
        "springs); 0 = linear spring",
    ),
    "contact_stiffness_ratio": Param(
        _ELASTIC["contact_stiffness_ratio"],
        above=0.0,
        maximum=1.0,
        meaning="k_0 / k_h: stiffness at zero load over the loaded stiffness",
    ),
    "nut_friction_Nm": Param(
        _ELASTIC["nut_friction_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="rolling friction of nut and screw bearings at the motor once rolling",
    ),
    "nut_presliding_m": Param(
        _ELASTIC["nut_presliding_m"],
        unit="m",
        above=0.0,
        meaning="its pre-sliding width at the table (004 Fig. 4b: about 15 um)",
    ),
    "guide_friction_N": Param(
        _ELASTIC["guide_friction_N"],
        unit="N",
        minimum=0.0,
        meaning="rolling friction of the linear guide once rolling (pattern I/II at the stop "
        "switches at a deceleration of guide_friction_N / table_mass_kg)",
    ),
    "guide_presliding_m": Param(
        _ELASTIC["guide_presliding_m"], unit="m", above=0.0, meaning="its pre-sliding width"
    ),
    "friction_elements": Param(
        _ELASTIC["friction_elements"],
        minimum=1,
        maximum=200,
        meaning="Maxwell-slip elements per friction set",
    ),
    "nut_friction": Param(
        _ELASTIC["nut_friction"],
        choices=NUT_FRICTION_MODELS,
        meaning="what drives the ball nut's friction: displacement (the motor angle, nut and "
        "bearings in one set) or contact (the balls' contact deformation, so that it reverses "
        "with the load's flank, 004 Sect. III-B; the bearings apart)",
    ),
    "contact_travel_m": Param(
        _ELASTIC["contact_travel_m"],
        unit="m",
        minimum=0.0,
        meaning="contact: D, the balls' contact deformation is D tanh(F / F_p) in series with "
        "the linear k_h (contact_zone_m must be 0)",
    ),
    "nut_preload_N": Param(
        _ELASTIC["nut_preload_N"],
        unit="N",
        above=0.0,
        meaning="contact: F_p, the preload: the load over which the balls change flank",
    ),
    "contact_presliding_m": Param(
        _ELASTIC["contact_presliding_m"],
        unit="m",
        above=0.0,
        meaning="contact: the nut's pre-sliding width on the contact deformation; below "
        "contact_travel_m",
    ),
    "bearing_friction_Nm": Param(
        _ELASTIC["bearing_friction_Nm"],
        unit="N m",
        minimum=0.0,
        meaning="contact: rolling friction of the screw bearings at the motor (0 with "
        "displacement: nut_friction_Nm holds both)",
    ),
    "bearing_presliding_m": Param(
        _ELASTIC["bearing_presliding_m"],
        unit="m",
        above=0.0,
        meaning="contact: the bearings' pre-sliding width at the table",
    ),
    "current_bandwidth_hz": Param(
        _ELASTIC["current_bandwidth_hz"],
        unit="Hz",
        minimum=0.0,
        meaning="first-order current loop (004: 1 kHz); 0 = ideal",
    ),
    "sim_step_s": Param(
        _ELASTIC["sim_step_s"],
        unit="s",
        above=0.0,
        meaning="RK4 sub-step; divides control_period_s",
    ),
    "current_limit_A": Param(
        _ELASTIC["current_limit_A"], unit="A", above=0.0, meaning="amplifier saturation"
    ),
    "initial_position_m": Param(
        _ELASTIC["initial_position_m"],
        unit="m",
        meaning="table position at step 0 (motor at x / R, at rest, relaxed)",
    ),
    "encoder.resolution": Param(
        2.0 * math.pi / 2**20,
        unit="rad",
        minimum=0.0,
        meaning="rotary-encoder count on the motor (004: 2^20 pulses/rev); 0 = ideal",
    ),
    "encoder.noise_std": Param(
        0.0, unit="rad", minimum=0.0, meaning="Gaussian encoder noise before quantisation"
    ),
    "scale.resolution": Param(
        100e-9,
        unit="m",
        minimum=0.0,
        meaning="linear-scale count on the table (004: 100 nm); 0 = ideal",
    ),
    "scale.noise_std": Param(
        0.0, unit="m", minimum=0.0, meaning="Gaussian scale noise before quantisation"
    ),
}

#: The controlled output, shared by the feedback loop and the learning unit.
SENSOR = Param(
    "encoder",
    choices=("encoder", "scale"),
    meaning="which sensor is the controlled output: rotary encoder (semi-closed loop) "
    "or linear scale / R (full-closed)",
)

FEEDBACK: dict[str, Param] = {
    "bandwidth_hz": Param(
        40.0,
        unit="Hz",
        above=0.0,
        meaning="position-loop bandwidth of the PID: all four closed-loop poles at -2 pi f on P_n "
        "(pole placement, Tustin; 000: 40/45 Hz)",
    ),
    "dob.enabled": Param(
        False,
        meaning="disturbance observer on the motor angle: inverse nominal model + low-pass "
        "(004 Sect. II)",
    ),
    "dob.cutoff_hz": Param(
        80.0,
        unit="Hz",
        above=0.0,
        meaning="cut-off of the DOB low-pass filter (004: 80 Hz), below the Nyquist frequency",
    ),
    "dob.sensor": Param(
        "encoder",
        choices=("encoder", "scale"),
        meaning="the angle the DOB observes: rotary encoder (004 Fig. 5: the motor angle, for "
        "the DOB's bandwidth, while the PID may close on the scale) or linear scale / R",
    ),
    "deformation.enabled": Param(
        False,
        meaning="publish the deformation ratio d_r = dx_t/dth_m - R of 004 eqs. (5)-(7) from "
        "the scale and the encoder on `deformation`, every sample",
    ),
    "deformation.window_samples": Param(
        4,
        unit="samples",
        minimum=1,
        meaning="p of 004 eq. (6): the differences are taken over p samples",
    ),
    "deformation.min_rotation_rad": Param(
        1e-4,
        unit="rad",
        minimum=0.0,
        meaning="below this motor rotation over p samples d_r is not defined (published as 0 "
        "with valid = 0): the encoder's count dominates near a stop",
    ),
    "use_feedforward": Param(
        True,
        meaning="add the feedforward current of `reference` to the PID output (false: PID alone)",
    ),
    "sensor": SENSOR,
    "limits.following_error_m": Param(
        _LIMITS["following_error_m"],
        unit="m",
        above=0.0,
        meaning="trip when the following error |r - y| at the table exceeds this",
    ),
    "limits.travel_m": Param(
        _LIMITS["travel_m"],
        unit="m",
        above=0.0,
        meaning="trip when the table position |y| exceeds this",
    ),
    "limits.current_A": Param(
        _LIMITS["current_A"],
        unit="A",
        above=0.0,
        meaning="trip when the current demand |u| exceeds this",
    ),
    "input_timeout_s": Param(
        0.5,
        unit="s",
        above=0.0,
        meaning="lockstep: how long a gone feedforward generator (liveliness of `reference`) "
        "gets to come back while a state waits for its reference, before the loop trips to "
        "zero current (a fallback); while it lives the loop waits. Trip within 1 s lease + "
        "input_timeout_s + input_timeout_s / 10 of its death. Realtime: wall time after a "
        "state without its reference",
    ),
    "max_preview_steps": Param(
        20000,
        unit="steps",
        minimum=1,
        meaning="reject a reference more than this many samples ahead of the last state",
    ),
    "wait_for_command_subscribers": Param(
        0,
        minimum=0,
        meaning="subscribe to `state` (which the plant waits for) and `reference` only once "
        "this many subscribers of `command` (the plant, the recorder) have matched: no "
        "command is published unheard",
    ),
}

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

FEEDFORWARD: dict[str, Param] = {
    **REFERENCE,
    "ptc.enabled": Param(
        True,
        meaning="multirate PTC feedforward on P_n, u = B^-1 (x_d[i+1] - A x_d[i]) at T_r = 2 T_u "
        "(000 Sect. III-A); false: reference only",
    ),
    "friction_table.enabled": Param(
        False,
        meaning="data-based friction table feedforward f(|y_d - y_rev|) / K_T with the sign "
        "of the motion (000 Fig. 17)",
    ),
    "friction_table.file": Param(
        "",
        meaning="friction table CSV (`servo_axis friction-table`); a relative path is relative "
        "to the scenario file",
    ),
    "preview_steps": Param(
        200,
        unit="steps",
        minimum=2,
        meaning="publish references up to this many samples ahead of the plant",
    ),
    "wait_for_reference_subscribers": Param(
        0,
        minimum=0,
        meaning="start publishing only once this many subscribers of `reference` have matched",
    ),
    "learning.enabled": Param(
        False,
        meaning="add the learning unit's correction (RPTC) to the target of each cycle; "
        "a cycle waits for its correction",
    ),
    "learning.cycle_s": Param(
        0.5,
        unit="s",
        above=0.0,
        meaning="learning cycle T_d = N_d T_r (000 Sect. III-B), a whole number of control periods",
    ),
    "learning.law": Param(
        "rptc",
        meaning="the learning unit's law (the runner copies the learning section's `law`): "
        "it decides target- or input-side corrections",
    ),
    "learning.timeout_s": Param(
        0.5,
        unit="s",
        above=0.0,
        meaning="lockstep: how long a gone learning unit (liveliness of learning/correction) "
        "gets to come back before a cycle waiting for its correction runs with the last one "
        "(a fallback); while it lives the cycle waits. Realtime: wall time the plant may stand "
        "still at the cycle boundary; keep below the feedback's input_timeout_s",
    ),
    "dob.enabled": Param(
        False,
        meaning="the feedback's DOB is on (the runner copies it from the feedback section): the "
        "compensation terms then enter outside it, as 004 Fig. 5 adds F_c",
    ),
    "dob.cutoff_hz": Param(
        80.0,
        unit="Hz",
        above=0.0,
        meaning="the feedback's DOB cut-off (copied from the feedback section)",
    ),
    "gms.enabled": Param(
        False,
        meaning="GMS-model friction compensation (Al-Bender et al. 2005; the conventional "
        "method of 004 Sect. II-C) on the reference's motion",
    ),
    "gms.file": Param(
        "",
        meaning="GMS parameter file (`servo_axis gms-fit` of a friction_id run); a relative "
        "path is relative to the scenario file",
    ),
    "gms.plant": Param(
        "",
        meaning="the plant the file must have been identified on (`<model>:<hash>` of the "
        "plant section); the runner sets it from the scenario; empty: not checked",
    ),
    "sigmoid.enabled": Param(
        False,
        meaning="sigmoid friction compensation of 004 eq. (9) with d_r^ = sigma / z of eq. (8), "
        "z the distance to the nearest reversal of the reference (before and after it)",
    ),
    "sigmoid.sigma_m2_per_rad": Param(
        PAPER_SIGMA_M2_PER_RAD,
        unit="m^2/rad",
        above=0.0,
        meaning="sigma of 004 eq. (8) (0.04 with z in mm and d_r in mm/rad)",
    ),
    "sigmoid.gamma_m_per_rad": Param(
        _SIGMOID_GAMMA,
        unit="m/rad",
        above=0.0,
        meaning="gamma of 004 eq. (9); the default makes |F_c| reach 0.9 F_0 at z = x_s / 2 "
        "= 7.5 um (gamma = 0.9 sigma / (x_s / 2 sqrt(1 - 0.81)))",
    ),
    "sigmoid.coulomb_Nm": Param(
        0.43,
        unit="N m",
        above=0.0,
        meaning="F_0 of 004 eq. (9): the Coulomb level of the friction at the motor "
        "(the sliding level of the friction_id run)",
    ),
    "sigmoid.search_horizon_s": Param(
        1.0,
        unit="s",
        above=0.0,
        meaning="how far ahead the next reversal of the reference is looked for",
    ),
    "mnc.enabled": Param(
        False,
        meaning="multirate nonlinearity compensator (003 eqs. (12)-(15)): unbalance U sin(theta_d) "
        "and, with mnc.friction, the arctan friction model of eq. (14), at T_r",
    ),
    "mnc.friction": Param(
        True,
        meaning="compensate friction with eq. (14) (the proposal); false = unbalance only, the "
        "previous MARC of eq. (17) (with an identifier the runner sets it from its method)",
    ),
    "mnc.unbalance_Nm": Param(
        0.1,
        unit="N m",
        minimum=0.0,
        meaning="U until the first online estimate applies (003 Table I initial estimate 0.1; "
        "with an identifier the runner copies its initial.unbalance_Nm)",
    ),
    "mnc.coulomb_Nm": Param(
        0.01,
        unit="N m",
        minimum=0.0,
        meaning="C until the first online estimate applies (003 Table I initial estimate 0.01; "
        "with an identifier the runner copies its initial.coulomb_Nm)",
    ),
    "mnc.alpha_s_per_rad": Param(
        1e4, unit="s/rad", above=0.0, meaning="alpha of the friction model, eq. (14) (003: 1e4)"
    ),
    "mnc.omega_th_rad_s": Param(
        0.05, unit="rad/s", minimum=0.0, meaning="w_th, the dead zone of eq. (14) (003: 0.05)"
    ),
    "adaptive.enabled": Param(
        False,
        meaning="take online estimates from identifier/estimates: the PTC model is rebuilt from "
        "J, D (003 eq. (11)) and the MNC gets U, C, each from the step the estimate applies "
        "from; samples from there on wait for it (the runner sets it when an identifier runs)",
    ),
    "adaptive.rls_period_s": Param(
        4e-3,
        unit="s",
        above=0.0,
        meaning="T_RLS, one estimate per this period (the runner copies the identifier's "
        "rls_period_s)",
    ),
    "adaptive.latency_s": Param(
        4e-3,
        unit="s",
        above=0.0,
        meaning="an estimate computed from the samples up to step k applies from step "
        "k + 1 + latency / T_u (the runner copies the identifier's latency_s)",
    ),
    "adaptive.timeout_s": Param(
        10.0,
        unit="s",
        above=0.0,
        meaning="lockstep: how long a gone identifier (liveliness of identifier/estimates) gets "
        "to come back before the feedforward keeps its last estimates for the rest of the run "
        "(a fallback; a restarted identifier resumes well within it); while it lives the axis "
        "waits. Realtime: wall time the plant may stand "
        "still waiting for an estimate",
    ),
}

LEARNING: dict[str, Param] = {
    **REFERENCE,
    "law": Param(
        "rptc",
        meaning="learning law (registered name): rptc = repetitive PTC with the n-times "
        "filter (000); silc = standard ILC, pilc_bf / pilc_bfft = projection-based ILC with "
        "basis functions / and the data-based friction table (001)",
    ),
    "cycle_s": Param(
        0.5,
        unit="s",
        above=0.0,
        meaning="learning cycle T_d = N_d T_r: a whole number N_d >= 4 of reference periods "
        "T_r = 2 T_u (000 Sect. III-B)",
    ),
    "nq": Param(
        20,
        minimum=0,
        meaning="N_q of the zero-phase learning filter Q = ((z + 2 + z^-1) / 4)^N_q, "
        "eq. (2) of 000",
    ),
    "n": Param(
        1,
        minimum=1,
        meaning="n of the n-times learning filter Q~n = I - (I - Q)^n, eq. (19) (1 = Q); "
        "n N_q + 2 < N_d, eq. (29)",
    ),
    "start_cycle": Param(
        2,
        minimum=2,
        meaning="first cycle (1-based) run with a learned correction: the error of cycle "
        "start_cycle - 1 is the first learned (000 Fig. 17 switch)",
    ),
    "memory.file": Param(
        "",
        meaning="JSON file the correction is saved to after every cycle and resumed from; "
        "'' = not persisted",
    ),
    "memory.resume": Param(
        True,
        meaning="start from the correction in memory.file when the file exists",
    ),
    "wait_for_correction_subscribers": Param(
        0,
        minimum=0,
        meaning="subscribe to `state` (which the plant waits for) only once this many "
        "subscribers of learning/correction have matched: no correction is published unheard",
    ),
    "wait_for_stats_subscribers": Param(
        0,
        minimum=0,
        meaning="likewise for learning/cycle_stats",
    ),
    "late_join": Param(
        False,
        meaning="join a running `state` stream at the first step received (a unit respawned "
        "mid-run; the runner sets it) instead of expecting step 0",
    ),
    "memory.on_bad_file": Param(
        "fail",
        choices=("fail", "clear"),
        meaning="memory.file unreadable, corrupt or of another scenario / N_d / N_q / n / T_r: "
        "fail = stop the node, clear = start from zero",
    ),
    "sensor": SENSOR,
}

#: Keys of the trial laws of paper 001 (``silc``, ``pilc_bf``, ``pilc_bfft``).
ILC: dict[str, Param] = {
    "feedback.bandwidth_hz": Param(
        FEEDBACK["bandwidth_hz"].default,
        unit="Hz",
        above=0.0,
        meaning="bandwidth of the feedback section's PID (the runner copies it): the learning "
        "filter L is the ZPETC of S_n P_n of that loop (001 Sect. IV-A-3)",
    ),
}

#: Keys of the projection-based laws (001 Sect. III-B/C).
PILC: dict[str, Param] = {
    "x_mu_m": Param(
        5e-6,
        unit="m",
        above=0.0,
        meaning="x_mu of the friction basis b_rf, eq. (13) (001: 5 um)",
    ),
    "threshold_m": Param(
        1e-4,
        unit="m",
        above=0.0,
        meaning="displacement from a reversal beyond which W = 1 (eq. (27)) and below which the "
        "friction table is used (001: 100 um)",
    ),
}

#: The identifier node's keys (paper 003 Sect. III-B, IV-A; Table I). The
#: initial J and D are the shared nominal.inertia_kgm2 / nominal.damping_Nms_per_rad:
#: the PID, the PTC and the RLS start from the same model.
IDENTIFIER: dict[str, Param] = {
    "method": Param(
        "dlpid",
        meaning="identification method (registered name): dlpid = double-layer parameter "
        "identification, RLS of J, D, U plus the friction layer of eq. (8) (003); marc = the "
        "previous MARC, RLS of J, D, U only, friction unmodelled (003 [11])",
    ),
    "rls_period_s": Param(
        4e-3,
        unit="s",
        above=0.0,
        meaning="T_RLS: the layers run once per this period, a whole number of reference "
        "periods T_r (003: 4 ms)",
    ),
    "latency_s": Param(
        4e-3,
        unit="s",
        above=0.0,
        meaning="an estimate computed from the samples up to step k applies from step "
        "k + 1 + latency_s / T_u; at least rls_period_s, a whole number of T_r",
    ),
    "pd_cutoff_hz": Param(
        20.0,
        unit="Hz",
        above=0.0,
        meaning="double pole of G_LPF / G_PD (003 Fig. 3; not given in the paper), below the "
        "Nyquist frequency of T_u",
    ),
    "initial.unbalance_Nm": Param(
        0.1, unit="N m", minimum=0.0, meaning="U_hat[0] (003 Table I: 0.1)"
    ),
    "bounds.inertia_kgm2": Param(
        [1e-4, 0.1], unit="kg m^2", above=0.0, meaning="[min, max] of J_hat, eq. (6)"
    ),
    "bounds.damping_Nms_per_rad": Param(
        [1e-4, 0.1], unit="N m s/rad", minimum=0.0, meaning="[min, max] of D_hat, eq. (6)"
    ),
    "bounds.unbalance_Nm": Param(
        [0.0, 2.0], unit="N m", minimum=0.0, meaning="[min, max] of U_hat, eq. (6)"
    ),
    "forgetting": Param(
        [0.999, 0.999, 0.995],
        above=0.0,
        maximum=1.0,
        meaning="forgetting factor of J, D, U, each in (0, 1] (003 Table I: 0.999, 0.999, "
        "0.995; per parameter: forget, then update)",
    ),
    "initial_covariance": Param(1e3, above=0.0, meaning="P[0] = p0 I of the RLS"),
    "conditions.angle_min_rad": Param(
        0.1, unit="rad", minimum=0.0, meaning="U is updated only when theta > this (eq. (16))"
    ),
    "conditions.velocity_min_rad_s": Param(
        0.2, unit="rad/s", minimum=0.0, meaning="D only when |theta'| > this (eq. (16))"
    ),
    "conditions.acceleration_min_rad_s2": Param(
        0.5, unit="rad/s^2", minimum=0.0, meaning="J only when |theta''| > this (eq. (16))"
    ),
    "pe_window": Param(
        100, minimum=3, meaning="W of the PE index of eq. (7), in RLS periods (003: 100)"
    ),
    "memory.file": Param(
        "",
        meaning="JSON file the identifier's whole state is saved to after every estimate and "
        "resumed from; '' = not persisted (the runner puts it in the run directory)",
    ),
    "memory.resume": Param(
        True,
        meaning="a restarted identifier (late_join) resumes from memory.file when it exists; "
        "a fresh start never does (a state is the middle of a run) and overwrites it",
    ),
    "wait_for_estimate_subscribers": Param(
        0,
        minimum=0,
        meaning="subscribe to `state` and `command` only once this many subscribers of "
        "identifier/estimates have matched (the runner sets it)",
    ),
    "late_join": Param(
        False,
        meaning="a restarted identifier (the runner sets it): resume after the last sample of "
        "its memory file, from the streams' history, instead of expecting step 0",
    ),
}

#: The keys of method ``dlpid`` only: the friction layer of 003 eq. (8).
DLPID_FRICTION: dict[str, Param] = {
    "initial.coulomb_Nm": Param(
        0.01, unit="N m", minimum=0.0, meaning="C_hat[0] (003 Table I: 0.01; dlpid only)"
    ),
    "bounds.coulomb_Nm": Param(
        [0.0, 1.0], unit="N m", minimum=0.0, meaning="[min, max] of C_hat (dlpid)"
    ),
    "friction.cutoff_hz": Param(
        2.0,
        unit="Hz",
        above=0.0,
        meaning="q of the friction layer's low-pass, eq. (8) (003: 2 or 100 Hz); dlpid only",
    ),
    "friction.velocity_min_rad_s": Param(
        0.2,
        unit="rad/s",
        above=0.0,
        meaning="C_hat is held while |theta'| is at or below this (dlpid)",
    ),
}

#: What the recorder records by default: the topics of the loop's three nodes.
_DEFAULT_RECORDED = topics.recorded_topics(("plant", "feedback", "feedforward"))

RECORDER: dict[str, Param] = {
    "output_dir": Param(
        "",
        meaning="bag directory to create (required)",
    ),
    "topics": Param(
        [t.name for t in _DEFAULT_RECORDED],
        meaning="topics to record (relative to the node's namespace); the runner adds "
        "those of the learning unit when it runs",
    ),
    "types": Param(
        [t.type_name for t in _DEFAULT_RECORDED],
        meaning="message type (pkg/msg/Type) of each of `topics`, in the same order",
    ),
    "latched_topics": Param(
        [t.name for t in _DEFAULT_RECORDED if t.qos == "latched"],
        meaning="those of `topics` subscribed with the latched (transient-local) QoS",
    ),
    # The per-sample streams (the topic table's `counted`): the run ends only
    # when every sample of each is on disk. A stream whose publisher's
    # liveliness lapsed (a dead feedforward generator) stops being counted,
    # so that it cannot stall the axis its feedback loop has just tripped.
    "counted_topics": Param(
        [t.name for t in _DEFAULT_RECORDED if t.counted],
        meaning="those of `topics` whose smallest message count is the steps acknowledged "
        "on recorder/progress",
    ),
    "final_topics": Param(
        [""],
        meaning="lockstep: topics the plant publishes every final_every_steps samples from "
        "step 0 (/clock, plant/status); a step is acknowledged only once those up to it are "
        "written too; the runner sets both; [''] = none",
    ),
    "final_every_steps": Param(
        [1],
        minimum=1,
        meaning="the publishing period (samples) of each of final_topics",
    ),
    "compression": Param(
        "zstd",
        choices=("zstd", "lz4", "none"),
        meaning="MCAP chunk compression",
    ),
    "ack_every_steps": Param(
        50,
        unit="steps",
        minimum=1,
        meaning="publish recorder/progress every this many recorded steps (and at the end)",
    ),
    "wait_for_publishers": Param(
        True,
        meaning="report ready (a first recorder/progress) only once every topic has a publisher",
    ),
}

#: Every schema by section title, for the parameter reference.
SECTIONS: dict[str, Mapping[str, Param]] = {
    "/**": SHARED,
    "plant": PLANT,
    "plant (model ball_screw)": BALL_SCREW,
    "plant (model tilting_table)": TILTING_TABLE,
    "plant (model elastic_ball_screw)": ELASTIC_BALL_SCREW,
    "feedback": FEEDBACK,
    "feedforward": FEEDFORWARD,
    "learning": LEARNING,
    "learning (laws silc, pilc_bf, pilc_bfft)": ILC,
    "learning (laws pilc_bf, pilc_bfft)": PILC,
    "identifier": IDENTIFIER,
    "identifier (method dlpid)": DLPID_FRICTION,
    "recorder": RECORDER,
}
