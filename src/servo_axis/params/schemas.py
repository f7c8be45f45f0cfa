"""Every node parameter, once: default, SI unit, allowed range and meaning.

One :class:`~servo_axis.params.param.Param` per (dotted) key, per section of
a scenario file: :data:`SHARED` (``/**``), :data:`PLANT`, :data:`FEEDBACK`,
:data:`FEEDFORWARD`, :data:`LEARNING`, :data:`IDENTIFIER` and
:data:`RECORDER`: the nodes' own keys. The keys of a plant model, a
feedforward term, a learning law or an identification method are in the
extension's own module (:mod:`servo_axis.plugins`, or an outside package's),
beside its builder. The ranges are what each value means physically (a
period is > 0, a gain >= 0); what depends on several keys at once
(``sim_step_s`` divides ``control_period_s``, ``n Nq + 2 < Nd``, ...) is
checked by the objects the values build.
:func:`servo_axis.params.registry.parameter_sections` lists every section for
the parameter reference (``scripts/parameter_docs.py`` -> ``docs/parameters.md``).

Paper numbers refer to the papers of ``docs/papers.md`` (000: Fujimoto &
Takemura, RPTC with the n-times learning filter; 001: Hayashi et al.; 003:
Ge et al.; 004: Zhu & Fujimoto), "docs/design.md section 7" to the axis
presets of the design intent.
"""

from __future__ import annotations

from servo_axis.core.feedback.loop import SafetyLimits
from servo_axis.core.feedforward.sigmoid import (
    PAPER_PRESLIDING_M,
    PAPER_SIGMA_M2_PER_RAD,
    gamma_for_width,
)
from servo_axis.core.models.ball_screw import BallScrewParams
from servo_axis.params.param import Param, dataclass_defaults
from servo_axis.params.reference_schema import REFERENCE
from servo_axis.wire import topics

_BALL_SCREW = dataclass_defaults(BallScrewParams)
_LIMITS = dataclass_defaults(SafetyLimits)

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
    "state_stamps": Param(
        "grid",
        choices=("grid", "plant_clock"),
        meaning="how `state` is stamped: grid = sample k at k T_u; plant_clock (realtime, "
        "an outside plant that owns its clock, e.g. a driver's ROS time) = any monotonic "
        "clock at the nominal T_u: sample k is the state stamped nearest to t_0 + k T_u, "
        "t_0 the first state's stamp, and each command echoes its state's stamp",
    ),
    "external_roles": Param(
        [""],
        meaning="roles played by nodes from outside the suite (any node name; `--external` of "
        "`run`): their topics' first publisher whose node is no stranger elsewhere is the "
        "declared one, not a stranger; a subset of plant, feedback, feedforward, learning, "
        "identifier",
    ),
    "wait_for_producers": Param(
        False,
        meaning="subscribe to a topic of the topic table only once the node the run started "
        "for its producer role (by that role's name, in this namespace) publishes it; an "
        "outside role's topic (`external_roles`): once it has its declared publisher. A "
        "reader made on a stranger's publisher that was there first could match the producer "
        "on its own side late (a discovery message repaired later) and take the stranger's "
        "sample of step 0 before the producer's. True also applies only the messages of each "
        "topic's declared publisher (a stranger's are counted, never applied); the runner "
        "sets it true. false: once the topic has any publisher, whose messages are all taken "
        "(a node started by hand, beside a probe)",
    ),
    "realtime.max_miss_fraction": Param(
        0.05,
        minimum=0.0,
        maximum=1.0,
        meaning="realtime mode: the largest fraction of the plant's ticks whose command missed "
        "its deadline for which the loop counts as closed; above it the run ends with exit 5 "
        "(the loop was not closed) and the summary says why; ignored in lockstep",
    ),
    "realtime.middleware_priority": Param(
        49,
        minimum=0,
        maximum=99,
        meaning="realtime mode: SCHED_FIFO priority of the middleware's receive threads "
        "(dds.shm.<port>, dds.udp.<port>) of the plant and the feedback, which hand each "
        "sample to the executor (the per-sample path's first step; at most "
        "thread_priority - 1); 0 = SCHED_OTHER at nice -10 like the middleware's other threads (dds.asyn, "
        "dds.ev, dds.shm.wdog), which never get a realtime priority. On a quiet 2-core "
        "host 0 missed 5-10x more deadlines: see docs/explanation/realtime.md",
    ),
    "thread_priority": Param(
        50,
        minimum=0,
        maximum=99,
        meaning="realtime mode: SCHED_FIFO priority of the threads that do the per-sample "
        "work: the plant's clock thread and the executor thread of the plant and the feedback "
        "(the per-sample pair), as ros2_control's thread_priority; the middleware's threads "
        "stay SCHED_OTHER (nice -10) but its receive threads (realtime.middleware_priority); "
        "the feedforward generator's executor runs two below (its receive threads one below "
        "that), the other nodes at the default scheduler. 0: the default scheduler "
        "for all. Where the system refuses (no CAP_SYS_NICE or rtprio limit), a warning and "
        "the default scheduler; ignored in lockstep",
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
        meaning="plant model: the name of an installed entry point of servo_axis.plant_models "
        "(`python -m servo_axis list` shows them); ball_screw = rigid ball-screw axis with "
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
    "command_source": Param(
        "stamped",
        choices=("stamped", "drive_setpoint"),
        meaning="what a `command` is: stamped = the command of the state of its stamp "
        "(the suite's feedback); drive_setpoint (realtime only; lockstep refuses it) = a "
        "drive's set-point, as ros2_control's joint_state_topic_hardware_interface sends it: "
        "the newest message whatever its stamp, held until the next one; the motor torque "
        "(N m) is the `effort` of `<axis>_motor` (by name, or the only value), NaN = no "
        "command yet (held, counted); `command` is recorded but not counted",
    ),
    "setpoint_period_s": Param(
        0.0,
        unit="s",
        minimum=0.0,
        meaning="drive_setpoint: the commander's period P (ros2_control: 1 / the controller "
        "manager's update_rate); with setpoint_threshold_Nm < 0 a tick misses its deadline "
        "when the newest set-point is older than 1.5 P then (the commander's clock is not "
        "the plant's: any phase, jitter up to P / 2); 0 = control_period_s",
    ),
    "setpoint_threshold_Nm": Param(
        -1.0,
        unit="N m",
        meaning="drive_setpoint: the commander's trigger_joint_command_threshold. < 0 (the "
        "plugin's -1: it publishes every cycle) = a tick without a fresh set-point is a "
        "miss, and 2 s without one end the run (loop_open); >= 0 (the plugin's default "
        "1e-5: it publishes nothing while its command stays within that of the effort it "
        "read, which a drive cannot tell from a lost set-point) = such a tick is held and "
        "counted (realtime.setpoints.quiet_ticks), never a miss, and the loop counts as "
        "open only once the commander has left the graph",
    ),
}

#: The controlled output, shared by the feedback loop and the learning unit.
SENSOR = Param(
    "encoder",
    choices=("encoder", "scale"),
    meaning="which sensor is the controlled output: rotary encoder (semi-closed loop) "
    "or linear scale / R (full-closed)",
)

#: ``sigmoid.source`` of the feedforward term: where 004 eq. (9) takes ``sgn(v)`` and ``z``.
SIGMOID_SOURCES = ("reference", "stage")

#: What the feedback copies of the feedforward section's ``sigmoid.*``
#: (:func:`~servo_axis.params.resolve.feedback_overrides`): with
#: ``sigmoid.source: stage`` the law is computed in the loop, from the scale.
FEEDBACK_SIGMOID: dict[str, Param] = {
    "sigmoid.enabled": Param(
        False,
        meaning="the feedforward section's sigmoid.enabled (copied): 004 eq. (9) is on",
    ),
    "sigmoid.source": Param(
        "reference",
        choices=SIGMOID_SOURCES,
        meaning="the feedforward section's sigmoid.source (copied); stage: this loop adds "
        "F_c / K_T of 004 eq. (9) from the measured table position, outside the DOB",
    ),
    "sigmoid.sigma_m2_per_rad": Param(
        PAPER_SIGMA_M2_PER_RAD,
        unit="m^2/rad",
        above=0.0,
        meaning="sigma of 004 eq. (8) (copied from the feedforward section)",
    ),
    "sigmoid.gamma_m_per_rad": Param(
        gamma_for_width(
            sigma_m2_per_rad=PAPER_SIGMA_M2_PER_RAD, half_width_m=PAPER_PRESLIDING_M / 2
        ),
        unit="m/rad",
        above=0.0,
        meaning="gamma of 004 eq. (9) (copied from the feedforward section)",
    ),
    "sigmoid.coulomb_Nm": Param(
        0.43,
        unit="N m",
        above=0.0,
        meaning="F_0 of 004 eq. (9), N m at the motor (copied from the feedforward section)",
    ),
}

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
    "wait_for_state_readers": Param(
        0,
        minimum=0,
        meaning="an outside plant (which publishes state[0] once `command` has a publisher): "
        "make the `command` publisher only once `state` has a publisher and this many "
        "subscribers (the run's readers), held 0.5 s; 0: the suite's plant, no wait",
    ),
    "recorder_lag_steps": Param(
        0,
        unit="steps",
        minimum=0,
        meaning="an outside plant in lockstep: answer state[k] only once the recorder has "
        "acknowledged step k + 1 - recorder_lag_steps (recorder/progress), so that a plant "
        "with a keep-last 10 `state` writer never overruns it; 0: no such wait",
    ),
    "forward_commands_topic": Param(
        "",
        meaning="also send each command as ros2_control's forward command controllers take "
        "it (effort_controllers/JointGroupEffortController, ros2_controllers 4.42.1): "
        "std_msgs/Float64MultiArray, data = [motor torque reference (N m)], empty layout, no "
        "stamp, reliable volatile keep-last 10, on this topic (absolute, e.g. "
        "/effort_controller/commands, or relative to the axis's namespace); the "
        "controller's `joints` must be [<axis>_motor]; not recorded; empty = off",
    ),
    **FEEDBACK_SIGMOID,
}


FEEDFORWARD: dict[str, Param] = {
    **REFERENCE,
    "ptc.enabled": Param(
        True,
        meaning="multirate PTC feedforward on P_n, u = B^-1 (x_d[i+1] - A x_d[i]) at T_r = 2 T_u "
        "(000 Sect. III-A); false: reference only",
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
    "progress_from_state": Param(
        False,
        meaning="take the plant's progress from the stamps of `state` instead of "
        "`plant/status` (an outside plant need publish `state` only)",
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
    "adaptive.enabled": Param(
        False,
        meaning="take online estimates from identifier/estimates: the PTC model is rebuilt from "
        "J, D (003 eq. (11)) and the MNC gets U, C, each from the step the estimate applies "
        "from; samples from there on wait for it (realtime: until they are due, then a late "
        "estimate applies from the next sample not yet published) (the runner sets it when an "
        "identifier runs)",
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
        "waits. Realtime: unused (no sample waits for an estimate past its due time)",
    ),
}

LEARNING: dict[str, Param] = {
    **REFERENCE,
    "law": Param(
        "rptc",
        meaning="learning law: the name of an installed entry point of servo_axis.learning_laws; "
        "rptc = repetitive PTC with the n-times "
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

#: The identifier node's keys (paper 003 Sect. III-B, IV-A; Table I). The
#: initial J and D are the shared nominal.inertia_kgm2 / nominal.damping_Nms_per_rad:
#: the PID, the PTC and the RLS start from the same model.
IDENTIFIER: dict[str, Param] = {
    "method": Param(
        "dlpid",
        meaning="identification method: the name of an installed entry point of "
        "servo_axis.identification_methods; dlpid = double-layer parameter "
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
    # As ros2 bag record --max-bag-size / --max-bag-duration: one bag
    # directory, files <bag>_0.mcap, <bag>_1.mcap, ... listed in metadata.yaml.
    "max_bag_size_bytes": Param(
        0,
        unit="bytes",
        minimum=0,
        meaning="split the bag: start its next MCAP file before a message once the file "
        "holds this many bytes (what is on disk: the file ends up to one chunk, 1 MiB, "
        "larger), as `ros2 bag record --max-bag-size`; 0 = no split, else >= 1024",
    ),
    "max_bag_duration_s": Param(
        0.0,
        unit="s",
        minimum=0.0,
        meaning="split the bag: start its next MCAP file before a message logged more than "
        "this after the file's first (log times are simulation times), as `ros2 bag record "
        "--max-bag-duration`; 0 = no split",
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
