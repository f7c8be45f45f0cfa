"""Elastic ball-screw axis: motor and table joined by the screw and nut (paper 004).

Two inertias, as in 004 Fig. 8 reduced to what the deformation ratio of
eqs. (5)-(7) can see::

    J_m th''  = K_T i_a - B_m th' - R F_s - T_f          (motor + screw rotation)
    M   x_t'' = F_s - C_t x_t' - f_g                     (nut + table, eq. (4))
    F_s = k(delta) + c_s delta',   delta = R th - x_t    (screw, nut and bearings)

``delta`` is the elastic deformation of everything between the motor shaft
and the table, in m at the table: positive when the screw pushes the table
forward (Pattern I during a positive motion, 004 Fig. 9), negative when it
brakes it (Pattern II, Fig. 10). ``d_r = dx_t/dth - R = -d delta / d th``
(eqs. (5)-(7)), so the deformation ratio is exactly the rate at which the
deformation changes per motor angle.

The spring: the screw's axial and torsional stiffness, the nut and the
bearings are lumped in series into one axial stiffness ``k_h = 1 / (1/k_a +
R^2/k_t)``. The balls between screw and nut are "nonlinear springs" (004
Sect. III-A, Fig. 7): without preload the contact is soft near zero load and
stiffens under load. That is modelled as
``k(delta) = k_h delta - (k_h - k_0) g tanh(delta / g)``: stiffness ``k_0``
at zero load, ``k_h`` once ``|delta|`` is a few ``g``, smooth everywhere,
potential energy ``k_h delta^2 / 2 - (k_h - k_0) g^2 ln cosh(delta / g)``.
With ``g = 0`` the spring is linear.

Friction: rolling friction with pre-sliding, as Maxwell-slip element sets
(:class:`~servo_axis.core.friction.maxwell_slip.MaxwellSlip`), at the nut and
the screw bearings (``T_f``, a torque on the motor side, its pre-sliding width
given at the table) and at the linear guide (``f_g`` on the table). Both are
rate independent: at rest they act as springs to ground, so nothing chatters
at zero speed. During a deceleration the screw must push (Pattern I) while
``|M x_t''| < f_g`` and brake (Pattern II) once the deceleration is higher,
so the pattern at zero speed depends on the deceleration (004 Sect. III-B).

Ball-nut friction driven by the contact (``nut_friction = "contact"``)
-----------------------------------------------------------------------
The spring becomes a linear part ``k_h`` (screw axial and torsion, bearings,
the balls once loaded on one flank) in series with the balls' contact, whose
deformation is ``delta_c = D tanh(F / F_p)`` (004 Fig. 7: the balls as
nonlinear springs): ``F / k_h + D tanh(F / F_p) = delta``, solved for ``F``
at every RK4 stage (:func:`servo_axis.core.models.ball_screw_kernels.contact_load`; the soft
zone ``g`` must then be 0). ``delta_c`` is the micro-motion of the screw
groove against the nut across the balls: it stays near ``+-D`` while one
flank carries the load and travels ``2 D`` when the load changes flank
(Pattern I <-> II, Figs. 9-10), stiffness ``1 / (1/k_h + D/F_p)`` there and
``k_h`` beyond a few ``F_p``. The torque ``T_f`` of the friction between
balls and grooves is a Maxwell-slip set driven by ``delta_c`` (level
``nut_friction_Nm``, pre-sliding width ``contact_presliding_m`` < ``D`` on the
virgin curve), so it keeps its sign while the load stays on one flank,
whatever the speed, and reverses with the flank: before the table stops when
the deceleration is high (the screw brakes the nut and "F_bs, F_b, T_f and
T also change their directions", Sect. III-B-2), after the stop when it is
low (Pattern I at the stop, II only in the acceleration after the reverse,
Sect. III-B-1). Between the change of flank and the stop ``T_f`` turns the
screw in its direction of rotation: 004's picture of the forces, not a
passive contact law (the energy it brings in is ``2 T_n`` times the motor's
rotation over that stretch, a few mrad).

Preload (Sect. III-B, whose analysis neglects the initial deformations it
causes): the nut's preload closes the play of the balls (no backlash) and
sets ``F_p``, the load over which the balls pass from one flank to the other
(both flanks loaded below it); ``D`` is their Hertzian travel between the
flanks, so that a higher preload is a higher ``F_p`` (a stiffer zero-load
contact, ``F_p / D``); the preload's drag torque is the nut's friction level
``nut_friction_Nm``, and the contact's pre-sliding width a fraction of ``D``.
The calibrated values (``D`` = 19 um, ``F_p`` = 80 N, eq. (8)'s sigma) are in
the ``*_contact_*`` scenarios, made by ``scripts/calibrate_contact.py``; the
zero-load stiffness ``F_p / D`` = 4.2e6 N/m puts the table on a mode near
20 Hz while the load changes flank (the loaded mode stays at 150 Hz).

The screw's support bearings (004 Fig. 8: the left-hand one fixed, "the
friction of the bearing at the right side of the screw is small", Sect.
III-A) carry ``F_b`` and the screw's rotation; their rolling friction stays
a function of the motor angle (``bearing_friction_Nm``,
``bearing_presliding_m``), the guide's ``f_g`` of the table's displacement.
With ``"displacement"`` (the default) ``nut_friction_Nm`` is nut and bearings
in one set on the motor angle, as before. The sub-step loop of ``"contact"``
is :func:`servo_axis.core.models.ball_screw_kernels.elastic_ball_screw_contact_period`.

Current loop: a first-order lag of ``current_bandwidth_hz`` (004 Sect. II-A:
1 kHz) from the commanded to the actual current ``i_a``, solved exactly over
each control period (the command is held); 0 makes it ideal.

Integration: classical RK4 with sub-steps of ``sim_step_s``; the friction of
both element sets is updated at the end of each sub-step from its
displacement and held over the next one (its springs are far
slower than the sub-step: about 45 Hz for the table on the guide's elements
at the default values, against 10 us sub-steps of 50 us). ``i_a`` is
evaluated exactly at each RK4 stage. The sub-step loop is compiled
(:func:`servo_axis.core.models.ball_screw_kernels.elastic_ball_screw_period`).

Sensors: the rotary encoder reads ``th`` (2^20 pulses/rev), the linear scale
``x_t`` (100 nm), both quantised to the nearest count (optional seeded
noise, :mod:`servo_axis.core.sensors`).

Parameters and the choices behind them (004 Table I where it fits)
-------------------------------------------------------------------
Table I lists ``J_m = 2.3e-3 kg m^2``, ``B_m = 1.177 N m s/rad``, the screw
(9.353 kg, 1.169 m, ``B_b = 0.05``), ``M_t = 273 kg``, ``C_t = 1e4 N s/m``
and ``R = 1.91 mm/rad``; eq. (1) gives the identified rigid model ``J_n =
2.6e-3 kg m^2``, ``B_n = 0.070 N m s/rad``. The two do not add up (``J_m +
J_screw + M_t R^2 = 4.8e-3``; ``B_m`` alone is 17 times ``B_n``), and the
issue asks for the low-frequency response to match ``J_n, B_n`` within 10 %.
The table's ``M_t``, ``C_t`` and ``R`` set the forces that decide the
deformation pattern, so they are kept, and the motor side takes the rest:
``J_m = J_n - M_t R^2 = 1.604e-3 kg m^2`` (motor and screw rotation),
``B_m = B_n - C_t R^2 = 0.0335 N m s/rad``. The stiffness is not given:
``k_a = 1.55e8 N/m`` (screw axial in series with nut and bearings: a 36 mm
steel screw, the diameter of 9.353 kg over 1.169 m, has ``E A / L = 3.7e8``
over half its length; nut and bearings about 5e8 each) and ``k_t = 2.3e4 N
m/rad`` (the torsion of that screw over half its length), so ``k_h = 1.50e8
N/m`` and the first axial mode (torque to motor angle resonance) is at 150
Hz, inside the 100-200 Hz the issue asks for; ``c_s`` gives it about 5 %
damping. Friction: the guide 120 N (about 0.45 % of the table's weight), the
nut and bearings 0.2 N m, pre-sliding 15 um each (004 Fig. 4b), so the
pattern at the stop turns from I to II above a deceleration of
``f_g / M_t = 0.44 m/s^2`` (the 25 (1 - cos 2 pi t) mm reference of 004
Sect. V reverses at 0.99 m/s^2). The contact zone ``g = 1 um`` with ``k_0 =
0.1 k_h`` is our choice for a ball nut without preload.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from servo_axis.core.errors import (
    ConfigError,
    require_finite,
    require_nonnegative,
    require_positive,
)
from servo_axis.core.friction.maxwell_slip import MaxwellSlip
from servo_axis.core.models.base import NominalModel, PlantOutput, clipped_current, sim_steps
from servo_axis.core.models.base import plant_output as _plant_output
from servo_axis.core.sensors import PositionSensor, SensorParams

#: What may drive the ball nut's friction (``nut_friction``).
NUT_FRICTION_MODELS = ("displacement", "contact")

#: The first axial mode a ball screw of this kind has (issue 10: "between 100 and 200 Hz").
TYPICAL_MODE_HZ = (100.0, 200.0)

_ENCODER_2_20 = 2.0 * math.pi / 2**20

#: The fields of :class:`PlantOutput`, in order: what :func:`~servo_axis.core.models.base.plant_output` fills.
OUTPUT_FIELDS = tuple(f.name for f in fields(PlantOutput))


@dataclass(frozen=True, kw_only=True)
class ElasticBallScrewParams:
    """Physical parameters of the elastic ball-screw axis (defaults: 004 Table I, see module).

    Parameters
    ----------
    torque_constant_Nm_per_A : float
        ``K_T``, N m/A, > 0 (0.715, Table I).
    motor_inertia_kgm2 : float
        ``J_m``: motor and screw rotation, kg m^2, > 0 (1.604e-3 = ``J_n - M_t R^2``).
    motor_damping_Nms_per_rad : float
        ``B_m``, N m s/rad, >= 0 (0.0335 = ``B_n - C_t R^2``).
    table_mass_kg : float
        ``M``: nut and table, kg, > 0 (273, Table I).
    table_damping_Ns_per_m : float
        ``C_t``: viscosity of the linear guide, N s/m, >= 0 (1e4, Table I).
    lead_m_per_rad : float
        ``R``, m/rad, > 0 (1.91e-3, Table I).
    axial_stiffness_N_per_m : float
        ``k_a``: screw axial, nut and bearings in series, N/m, > 0 (1.55e8).
    torsional_stiffness_Nm_per_rad : float
        ``k_t``: screw torsion between motor and nut, N m/rad, > 0 (2.3e4).
    screw_damping_Ns_per_m : float
        ``c_s``: structural damping of the deformation, N s/m, >= 0 (1.6e4:
        about 5 % of critical for the first axial mode).
    contact_zone_m : float
        ``g``: width of the soft zone of the ball contacts around zero load,
        m, >= 0 (1e-6; 0: linear spring).
    contact_stiffness_ratio : float
        ``k_0 / k_h``: stiffness at zero load over the loaded stiffness, in
        (0, 1] (0.1).
    nut_friction_Nm : float
        Rolling friction of the nut and the screw bearings once the balls roll,
        at the motor, N m, >= 0 (0.2).
    nut_presliding_m : float
        Its pre-sliding width, at the table, m, > 0 (15e-6, 004 Fig. 4b).
    guide_friction_N : float
        Rolling friction of the linear guide once it rolls, N, >= 0 (120).
    guide_presliding_m : float
        Its pre-sliding width, m, > 0 (15e-6).
    friction_elements : int
        Maxwell-slip elements per friction set, 1..200 (8).
    nut_friction : str
        What drives the ball nut's friction: ``"displacement"`` (default: the
        motor angle, one set for nut and bearings) or ``"contact"`` (the
        contact deformation of the balls; the bearings apart, see the module).
    contact_travel_m : float
        ``"contact"``: ``D``, half the travel of the balls' contact deformation
        between the two flanks, m, >= 0 (20e-6; see the module).
    nut_preload_N : float
        ``"contact"``: ``F_p``, the preload: the load over which the balls pass
        from one flank to the other, N, > 0 (50).
    contact_presliding_m : float
        ``"contact"``: the nut's pre-sliding width on the contact deformation
        (virgin curve), m, > 0 (0.5e-6); below ``contact_travel_m`` so that a
        change of flank reverses it.
    bearing_friction_Nm : float
        ``"contact"``: rolling friction of the screw bearings at the motor,
        N m, >= 0 (0; with ``"displacement"`` it is part of
        ``nut_friction_Nm`` and must be 0).
    bearing_presliding_m : float
        ``"contact"``: its pre-sliding width, at the table, m, > 0 (7.5e-6).
    current_bandwidth_hz : float
        Bandwidth of the current loop (first-order), Hz, >= 0 (1000, 004
        Sect. II-A; 0: ideal).
    control_period_s : float
        ``T_u``, s, > 0 (0.5e-3, 004 Sect. II-B): the current is held over it.
    sim_step_s : float
        RK4 sub-step, s, dividing ``control_period_s`` (50e-6).
    current_limit_A : float
        Amplifier saturation, A, > 0 (30).
    initial_position_m : float
        Table position at step 0 (motor at ``x / R``, spring relaxed), m.
    encoder, scale : SensorParams
        Rotary encoder (rad; 2^20 pulses/rev) and linear scale (m; 100 nm).
    """

    torque_constant_Nm_per_A: float = 0.715
    motor_inertia_kgm2: float = 1.604e-3
    motor_damping_Nms_per_rad: float = 0.0335
    table_mass_kg: float = 273.0
    table_damping_Ns_per_m: float = 1.0e4
    lead_m_per_rad: float = 1.91e-3
    axial_stiffness_N_per_m: float = 1.55e8
    torsional_stiffness_Nm_per_rad: float = 2.3e4
    screw_damping_Ns_per_m: float = 1.6e4
    contact_zone_m: float = 1.0e-6
    contact_stiffness_ratio: float = 0.1
    nut_friction_Nm: float = 0.2
    nut_presliding_m: float = 7.5e-6
    guide_friction_N: float = 120.0
    guide_presliding_m: float = 7.5e-6
    friction_elements: int = 8
    nut_friction: str = "displacement"
    contact_travel_m: float = 20e-6
    nut_preload_N: float = 50.0
    contact_presliding_m: float = 0.5e-6
    bearing_friction_Nm: float = 0.0
    bearing_presliding_m: float = 7.5e-6
    current_bandwidth_hz: float = 1000.0
    control_period_s: float = 0.5e-3
    sim_step_s: float = 50e-6
    current_limit_A: float = 30.0
    initial_position_m: float = 0.0
    encoder: SensorParams = field(default_factory=lambda: SensorParams(resolution=_ENCODER_2_20))
    scale: SensorParams = field(default_factory=lambda: SensorParams(resolution=100e-9))

    def __post_init__(self) -> None:
        for name in (
            "torque_constant_Nm_per_A",
            "motor_inertia_kgm2",
            "table_mass_kg",
            "lead_m_per_rad",
            "axial_stiffness_N_per_m",
            "torsional_stiffness_Nm_per_rad",
            "nut_presliding_m",
            "guide_presliding_m",
            "contact_presliding_m",
            "bearing_presliding_m",
            "nut_preload_N",
            "current_limit_A",
        ):
            require_positive(name, getattr(self, name))
        for name in (
            "motor_damping_Nms_per_rad",
            "table_damping_Ns_per_m",
            "screw_damping_Ns_per_m",
            "contact_zone_m",
            "nut_friction_Nm",
            "guide_friction_N",
            "bearing_friction_Nm",
            "contact_travel_m",
            "current_bandwidth_hz",
        ):
            require_nonnegative(name, getattr(self, name))
        ratio = require_positive("contact_stiffness_ratio", self.contact_stiffness_ratio)
        if ratio > 1.0:
            raise ConfigError(f"contact_stiffness_ratio: expected a value in (0, 1], got {ratio!r}")
        if not isinstance(self.friction_elements, int) or not 1 <= self.friction_elements <= 200:
            raise ConfigError(
                f"friction_elements: expected an integer in 1..200, got {self.friction_elements!r}"
            )
        if self.nut_friction not in NUT_FRICTION_MODELS:
            raise ConfigError(
                f"nut_friction: expected one of {', '.join(NUT_FRICTION_MODELS)}, "
                f"got {self.nut_friction!r}"
            )
        if self.nut_friction == "displacement" and self.bearing_friction_Nm != 0.0:
            raise ConfigError(
                "bearing_friction_Nm: expected 0 with nut_friction displacement (nut_friction_Nm "
                f"holds nut and bearings), got {self.bearing_friction_Nm!r}"
            )
        if self.nut_friction == "contact":
            if self.contact_zone_m != 0.0:
                raise ConfigError(
                    "contact_zone_m: expected 0 with nut_friction contact (its contact law is "
                    f"contact_travel_m and nut_preload_N), got {self.contact_zone_m!r}"
                )
            if not self.contact_presliding_m < self.contact_travel_m:
                raise ConfigError(
                    "contact_presliding_m: expected below contact_travel_m = "
                    f"{self.contact_travel_m!r} m with nut_friction contact, "
                    f"got {self.contact_presliding_m!r}"
                )
        sim_steps(self.control_period_s, self.sim_step_s)
        if self.current_bandwidth_hz * self.sim_step_s > 0.4:
            raise ConfigError(
                "sim_step_s: expected at most 0.4 / current_bandwidth_hz = "
                f"{0.4 / self.current_bandwidth_hz!r} s, got {self.sim_step_s!r}"
            )
        require_finite("initial_position_m", self.initial_position_m)

    @property
    def stiffness_N_per_m(self) -> float:
        """``k_h = 1 / (1/k_a + R^2/k_t)``: the loaded stiffness at the table, N/m."""
        r = self.lead_m_per_rad
        return 1.0 / (
            1.0 / self.axial_stiffness_N_per_m + r * r / self.torsional_stiffness_Nm_per_rad
        )

    @property
    def rigid_inertia_kgm2(self) -> float:
        """``J_m + M R^2``: the rigid-body inertia at the motor, kg m^2 (``J_n`` of eq. (1))."""
        return self.motor_inertia_kgm2 + self.table_mass_kg * self.lead_m_per_rad**2

    @property
    def rigid_damping_Nms_per_rad(self) -> float:
        """``B_m + C_t R^2``, N m s/rad (``B_n`` of eq. (1))."""
        return self.motor_damping_Nms_per_rad + self.table_damping_Ns_per_m * self.lead_m_per_rad**2

    @property
    def first_axial_mode_hz(self) -> float:
        """Resonance of torque -> motor angle at the loaded stiffness, undamped, Hz."""
        r = self.lead_m_per_rad
        k = self.stiffness_N_per_m
        w2 = k * (1.0 / self.table_mass_kg + r * r / self.motor_inertia_kgm2)
        return math.sqrt(w2) / (2.0 * math.pi)

    def nominal(self) -> NominalModel:
        """The rigid model of 004 eq. (1) this plant reduces to at low frequency."""
        return NominalModel(
            inertia_kgm2=self.rigid_inertia_kgm2,
            damping_Nms_per_rad=self.rigid_damping_Nms_per_rad,
            torque_constant_Nm_per_A=self.torque_constant_Nm_per_A,
        )


def mode_warning(params: ElasticBallScrewParams) -> str | None:
    """A sentence when the first axial mode is outside 100-200 Hz (allowed: other screws)."""
    f = params.first_axial_mode_hz
    low, high = TYPICAL_MODE_HZ
    if low <= f <= high:
        return None
    return (
        f"the first axial mode is at {f:.4g} Hz, outside the {low:g}-{high:g} Hz of the "
        "ball screw of paper 004 (axial_stiffness_N_per_m, torsional_stiffness_Nm_per_rad)"
    )


def spring_force_N(delta_m: float, params: ElasticBallScrewParams) -> float:
    """Static force of the lumped spring at deformation ``delta_m`` (m), N."""
    k = params.stiffness_N_per_m
    g = params.contact_zone_m
    if g == 0.0:
        return k * delta_m
    return k * delta_m - (k - params.contact_stiffness_ratio * k) * g * math.tanh(delta_m / g)


def spring_energy_J(delta_m: float, params: ElasticBallScrewParams) -> float:
    """Potential energy of the lumped spring at deformation ``delta_m`` (m), J."""
    k = params.stiffness_N_per_m
    g = params.contact_zone_m
    energy = 0.5 * k * delta_m * delta_m
    if g > 0.0:
        x = abs(delta_m) / g
        # ln cosh x without overflow: x + ln(1 + e^-2x) - ln 2.
        log_cosh = x + math.log1p(math.exp(-2.0 * x)) - math.log(2.0)
        energy -= (k - params.contact_stiffness_ratio * k) * g * g * log_cosh
    return energy


def linearised_response(
    freq_hz: ArrayLike, params: ElasticBallScrewParams
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Torque (N m) to motor angle (rad) and to table position (m), linearised at load.

    The two-inertia model with the loaded stiffness ``k_h``, no friction, an
    ideal current loop: the responses whose resonance is
    :attr:`ElasticBallScrewParams.first_axial_mode_hz`.
    """
    s = 2j * np.pi * np.asarray(freq_hz, dtype=float)
    r = params.lead_m_per_rad
    spring = params.stiffness_N_per_m + params.screw_damping_Ns_per_m * s
    motor = params.motor_inertia_kgm2 * s**2 + params.motor_damping_Nms_per_rad * s
    table = params.table_mass_kg * s**2 + params.table_damping_Ns_per_m * s
    # [motor + R^2 K, -R K; -R K, table + K] [th; x] = [T; 0]
    det = (motor + r * r * spring) * (table + spring) - (r * spring) ** 2
    angle: NDArray[np.complex128] = (table + spring) / det
    position: NDArray[np.complex128] = r * spring / det
    return angle, position


class ElasticBallScrewPlant:
    """Simulator of the elastic ball-screw axis, advanced one control period per call.

    Parameters
    ----------
    params : ElasticBallScrewParams
        Physical parameters.
    rng : numpy.random.Generator or None
        Noise source of the sensors (needed only with sensor noise).
    """

    def __init__(
        self, params: ElasticBallScrewParams, *, rng: np.random.Generator | None = None
    ) -> None:
        self.params = params
        p = params
        self._n = sim_steps(p.control_period_s, p.sim_step_s)
        self._h = p.sim_step_s
        r = p.lead_m_per_rad
        self._contact = p.nut_friction == "contact"
        # The RK4 sub-steps and the friction sets, compiled (the plant's whole cost).
        from servo_axis.core.models.ball_screw_kernels import (
            ELASTIC_CONTACT_LAYOUT,
            ELASTIC_LAYOUT,
            elastic_ball_screw_contact_period,
            elastic_ball_screw_period,
        )

        # One work array for the kernel (its argument, see the kernel): the state, the
        # config, then the friction sets' elements (the nut's, with "contact" the
        # bearings', the guide's). The state: th, w, x, v, i, T_f, f_g (and with
        # "contact" the nut's and the bearings' shares of T_f and the contact's F / F_p),
        # stepped in place.
        n_state, n_config = ELASTIC_CONTACT_LAYOUT if self._contact else ELASTIC_LAYOUT
        n_el = p.friction_elements
        sets = 3 if self._contact else 2
        self._work = np.zeros(n_state + n_config + sets * 3 * n_el)
        self._state = self._work[:n_state]
        self._config = self._work[n_state : n_state + n_config]

        def storage(index: int) -> np.ndarray:
            start = n_state + n_config + index * 3 * n_el
            return self._work[start : start + 3 * n_el].reshape(3, n_el)

        # "contact": the nut's set works in m of contact deformation and N m.
        self._nut = MaxwellSlip(
            coulomb_Nm=p.nut_friction_Nm,
            width_rad=p.contact_presliding_m if self._contact else p.nut_presliding_m / r,
            elements=n_el,
            storage=storage(0),
        )
        # With "displacement" the bearings' set (level 0) is not the kernel's.
        self._bearing = MaxwellSlip(
            coulomb_Nm=p.bearing_friction_Nm,
            width_rad=p.bearing_presliding_m / r,
            elements=n_el,
            storage=storage(1) if self._contact else None,
        )
        # The guide's set works in m and N; MaxwellSlip is unit-agnostic.
        self._guide = MaxwellSlip(
            coulomb_Nm=p.guide_friction_N,
            width_rad=p.guide_presliding_m,
            elements=n_el,
            storage=storage(sets - 1),
        )
        self._encoder = PositionSensor(p.encoder, rng=rng)
        self._scale = PositionSensor(p.scale, rng=rng)
        wc = 2.0 * math.pi * p.current_bandwidth_hz
        h = self._h
        # i_a at a stage time tau into the sub-step: i_c + (i_0 - i_c) e^{-wc tau}.
        ideal = not wc > 0.0
        k = p.stiffness_N_per_m
        self._config[:] = [
            r,
            k,
            p.screw_damping_Ns_per_m,
            p.contact_zone_m,
            (k - p.contact_stiffness_ratio * k) * p.contact_zone_m,
            p.torque_constant_Nm_per_A,
            p.motor_damping_Nms_per_rad,
            p.motor_inertia_kgm2,
            p.table_damping_Ns_per_m,
            p.table_mass_kg,
            self._n,
            h,
            1.0 if ideal else math.exp(-wc * h / 2.0),
            1.0 if ideal else math.exp(-wc * h),
            1.0 if ideal else 0.0,
            *([p.contact_travel_m, p.nut_preload_N] if self._contact else []),
        ]
        self._advance = (
            elastic_ball_screw_contact_period if self._contact else elastic_ball_screw_period
        )
        # What every step reads, as plain attributes (the parameters are frozen).
        self._limit = p.current_limit_A
        self._kt = p.torque_constant_Nm_per_A
        self._lead = r
        self.reset()

    def reset(self) -> None:
        """Return to the initial state at step 0 (at rest, spring and friction relaxed)."""
        p = self.params
        self._state[:] = 0.0
        self._state[0] = p.initial_position_m / p.lead_m_per_rad
        self._state[2] = p.initial_position_m
        self._nut.reset()
        self._bearing.reset()
        self._guide.reset()
        self._step = 0
        self._sample()

    @property
    def step_index(self) -> int:
        """Index of the current control sample."""
        return self._step

    @property
    def deformation_m(self) -> float:
        """``delta = R th - x_t``: the elastic deformation now, m."""
        return self.params.lead_m_per_rad * float(self._state[0]) - float(self._state[2])

    @property
    def contact_deformation_m(self) -> float:
        """``delta_c = D tanh(F / F_p)``: the balls' contact deformation now, m.

        ``"contact"`` only; 0.0 with ``"displacement"`` (no contact element).
        """
        if not self._contact:
            return 0.0
        return self.params.contact_travel_m * math.tanh(float(self._state[9]))

    @property
    def spring_force_N(self) -> float:
        """The elastic force of the screw and nut now (without ``c_s``), N."""
        if self._contact:
            return self.params.nut_preload_N * float(self._state[9])
        return spring_force_N(self.deformation_m, self.params)

    @property
    def friction_torques_Nm(self) -> tuple[float, float, float]:
        """``(T_f, nut share, bearing share)`` at the motor now, N m (shares: ``"contact"`` only).

        With ``"displacement"`` the shares are ``(T_f, T_f, 0.0)``: one set.
        """
        tf = float(self._state[5])
        if self._contact:
            return tf, float(self._state[7]), float(self._state[8])
        return tf, tf, 0.0

    @property
    def guide_force_N(self) -> float:
        """``f_g``: the guide's friction on the table now, N."""
        return float(self._state[6])

    def output(self) -> PlantOutput:
        """Readings and true state at the current control sample."""
        return self._out

    def step(self, current_A: float) -> PlantOutput:
        """Hold ``current_A`` (A, saturated at ``+-current_limit_A``) over one control period."""
        limit = self._limit
        # Inside the limits the saturation is the current itself (what clipped_current
        # gives it, without the call); outside them, or not finite, clipped_current.
        if -limit <= current_A <= limit:
            cmd = float(current_A)
        else:
            cmd = clipped_current(current_A, limit)
        self._advance(self._work, cmd)
        self._step += 1
        self._sample()
        return self._out

    def _sample(self) -> None:
        # The whole state in one conversion (the contact's three extra values unused).
        th, w, x, v, i, tf, fg, *_ = self._state.tolist()
        self._out = _plant_output(
            self._step,
            self._encoder.measure(th),
            self._scale.measure(x),
            th,
            w,
            x,
            v,
            self._kt * i,
            fg + tf / self._lead,
        )
