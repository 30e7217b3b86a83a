"""Planetary roller screw stages (seed 004): description and validation."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.fields import Fields, require
from ..base import EFFICIENCY_RANGE, Element, Jet, Stage, check_fields, read_stroke, screw_backdrive_efficiency


@dataclass(frozen=True)
class RollerScrewStage:
    """One stage of a multi-stage planetary roller screw, SI units.

    Radii in m, masses in kg, inertias in kg*m^2, angles in rad. ``screw_spline_radius``
    (r_SS) and ``nut_screw_joint_radius`` (r_NS) belong to stages after the first.
    """

    screw_radius: float
    roller_radius: float
    nut_radius: float
    screw_starts: int
    lead: float
    flank_angle: float
    ring_gear_pressure_angle: float
    rollers: int
    roller_mass: float
    nut_mass: float
    screw_inertia: float
    roller_inertia: float
    carrier_inertia: float
    screw_mass: float = 0.0
    screw_spline_radius: float = 0.0
    nut_screw_joint_radius: float = 0.0

    @classmethod
    def from_table(cls, f: Fields, first: bool) -> "RollerScrewStage":
        """Build from one ``[[stages]]`` table."""
        q = f.quantity

        def joint(name):
            # joints to the previous stage: required on every stage after the first
            return q(name, "m", 0.0, rule="nonnegative") if first else q(name, "m", rule="positive")

        stage = cls(
            screw_radius=q("screw_radius", "m", rule="positive"),
            roller_radius=q("roller_radius", "m", rule="positive"),
            nut_radius=q("nut_radius", "m", rule="positive"),
            screw_starts=f.integer("screw_starts", minimum=1),
            lead=q("lead", "m/turn", rule="positive"),
            flank_angle=q("flank_angle", "rad", rule="positive"),
            ring_gear_pressure_angle=q("ring_gear_pressure_angle", "rad", rule="positive"),
            rollers=f.integer("rollers", minimum=1),
            roller_mass=q("roller_mass", "kg", rule="nonnegative"),
            nut_mass=q("nut_mass", "kg", rule="nonnegative"),
            screw_inertia=q("screw_inertia", "kg*m^2", rule="nonnegative"),
            roller_inertia=q("roller_inertia", "kg*m^2", rule="nonnegative"),
            carrier_inertia=q("carrier_inertia", "kg*m^2", rule="nonnegative"),
            screw_mass=q("screw_mass", "kg", 0.0, rule="nonnegative"),
            screw_spline_radius=joint("screw_spline_radius"),
            nut_screw_joint_radius=joint("nut_screw_joint_radius"),
        )
        require(abs(stage.nut_radius - stage.screw_radius - 2 * stage.roller_radius)
                <= 1e-3 * stage.nut_radius, f.key("nut_radius"),
                "nut pitch radius must equal screw radius + 2 * roller radius")
        f.check_unknown()
        return stage


@dataclass(frozen=True)
class RollerScrewOperating:
    """Operating point of a roller-screw scene (``[operating]``)."""

    screw_speed: float
    load: float
    roller_screw_friction: float
    screw_screw_friction: tuple
    nut_screw_friction: tuple

    @classmethod
    def from_table(cls, f: Fields) -> "RollerScrewOperating":
        """Build from an ``[operating]`` table."""
        def coefficients(name):
            raw = f.raw(name, [0.0])
            values = raw if isinstance(raw, list) else [raw]
            return tuple(_coefficient(v, f"{f.key(name)}[{i}]") for i, v in enumerate(values))
        op = cls(screw_speed=f.quantity("screw_speed", "rad/s", rule="finite"),
                 load=f.quantity("load", "N", rule="finite"),
                 roller_screw_friction=_coefficient(f.raw("roller_screw_friction", 0.0),
                                                    f.key("roller_screw_friction")),
                 screw_screw_friction=coefficients("screw_screw_friction"),
                 nut_screw_friction=coefficients("nut_screw_friction"))
        f.check_unknown()
        return op


def _coefficient(value, key: str) -> float:
    require(isinstance(value, (int, float)) and not isinstance(value, bool), key,
            f"friction coefficient must be a number (got {value!r})")
    require(0 <= value < 1, key, f"friction coefficient must be in [0, 1) (got {value})")
    return float(value)


# --- kinematics and steady-state efficiency shared by the drivetrain stage and the dynamics ---

def nut_travel_per_screw_radian(stages) -> np.ndarray:
    """|v_Nk| / theta_S' of every stage (m/rad): sum of the leads up to k over 2 pi (eq 3)."""
    return np.cumsum([s.lead for s in stages]) / (2 * math.pi)


def carrier_ratio(stage: RollerScrewStage) -> float:
    """Steady carrier/screw speed ratio with rolling at the pitch circles, r_S / (2 (r_S + r_R))."""
    return stage.screw_radius / (2 * (stage.screw_radius + stage.roller_radius))


def roller_spin_ratio(stage: RollerScrewStage) -> float:
    """theta_R' / theta_P' of eq 8, -(n_S - 1)."""
    return -(stage.screw_starts - 1.0)


def carrier_inertia_total(stage: RollerScrewStage) -> float:
    """Inertia of carrier plus rollers (orbit and spin) about the screw axis, per carrier rad."""
    orbit = stage.roller_mass * (stage.screw_radius + stage.roller_radius) ** 2
    spin = stage.roller_inertia * roller_spin_ratio(stage) ** 2
    return stage.carrier_inertia + stage.rollers * (orbit + spin)


def thread_normal_norm(stage: RollerScrewStage) -> float:
    """|n| / n_z of the screw/roller contact normal (eq 9 at zero offset angle)."""
    helix = stage.lead / (2 * math.pi * stage.screw_radius)
    return math.sqrt(1.0 + math.tan(stage.flank_angle) ** 2 + helix**2)


def spline_friction(mu_ss: float, screw_torque: float, spline_radius: float, axial_speed: float) -> float:
    """f_Sk of seed 004 eq 4 (N): ``-mu_SS |M_Sk| / r_SSk sign(v_Sk)`` on a splined screw."""
    return -mu_ss * abs(screw_torque) / spline_radius * float(np.sign(axial_speed))


def bearing_friction(mu_ns: float, nut_load: float, joint_radius: float, screw_speed: float) -> float:
    """M_Nk of seed 004 eq 5 (N*m): ``mu_NS |F_Nk| r_NSk sign(theta_S')`` in the thrust
    bearing between a nut and the next stage's screw."""
    return mu_ns * abs(nut_load) * joint_radius * float(np.sign(screw_speed))


def joint_loads(stages, load: float, thread_torque, thread_torques, mu_ss: float, mu_ns: float,
                spline=None, bearing=None):
    """Walk the stages from the last to the first (seed 004, section 2.3).

    Parameters
    ----------
    stages : sequence of RollerScrewStage
    load : float
        F_N of the last nut (N), resisting its travel.
    thread_torque : callable
        ``thread_torque(k, nut_load)`` -> torque on screw k (N*m) of stage k's threads carrying
        ``nut_load``. (The axial thread force on the screw is the nut load itself: the rise
        of the normal force due to the axial friction is cancelled, on the screw, by that
        friction's reaction.)
    thread_torques : list
        Filled with each stage's own thread torque (N*m).
    mu_ss, mu_ns : float
        Spline and thrust-bearing friction coefficients (eqs 4-5), used by the default laws.
    spline, bearing : callable, optional
        The joint friction laws ``spline(k, screw_torque)`` -> f_Sk (N) and
        ``bearing(k, nut_load)`` -> M_Nk (N*m) of stage k >= 1 (0-based); by default
        :func:`spline_friction` and :func:`bearing_friction` with forward motion. Only their
        magnitudes enter: both resist the motion.

    Returns
    -------
    screw_torque : float
        M_S1, the torque at the first screw (N*m).
    nut_loads : list of float
        F_Nk of every nut (N).

    Raises
    ------
    SceneError
        When the joint friction locks a joint (the coupled spline/bearing loop gain
        mu_SS mu_NS r_NS / r_SS reaches 1).
    """
    if spline is None:
        def spline(k, torque):
            return spline_friction(mu_ss, torque, stages[k].screw_spline_radius, 1.0)
    if bearing is None:
        def bearing(k, nut_load):
            return bearing_friction(mu_ns, nut_load, stages[k].nut_screw_joint_radius, 1.0)
    n = len(stages)
    nut_loads = [0.0] * n
    nut_loads[-1] = load
    spline_torque = 0.0  # torque screw k + 1 takes through its spline, M_S(k+1)
    for k in reversed(range(n)):
        torque = thread_torque(k, nut_loads[k])
        thread_torques.insert(0, torque)
        x = torque + spline_torque  # screw k's torque before its own thrust-bearing friction
        if k == 0:
            return x, nut_loads
        # M_Sk = x + |M_N(k-1)| (eq 5), F_N(k-1) = F_Nk + |f_Sk(M_Sk)| (eqs 4, 21): a fixed point
        # with loop gain mu_ss mu_ns r_NS / r_SS, iterated on the laws themselves
        gain = abs(spline(k, 1.0)) * abs(bearing(k, 1.0))
        require(gain < 1, f"stages[{k}]", f"spline and thrust-bearing friction lock the joint "
                f"(mu_SS mu_NS r_NS / r_SS = {gain:.3g} >= 1)")
        f_prev = nut_loads[k] + abs(spline(k, x))
        for _ in range(200):
            f_new = nut_loads[k] + abs(spline(k, x + abs(bearing(k, f_prev))))
            if abs(f_new - f_prev) <= 1e-15 * abs(f_new):
                break
            f_prev = f_new
        nut_loads[k - 1] = f_new
        spline_torque = x + abs(bearing(k, f_new))
    return spline_torque, nut_loads


def steady_efficiency(stages, mu_rs: float, mu_ss: float, mu_ns: float) -> float:
    """Efficiency of eq 32 at steady carrier speed (rolling at the pitch circles).

    With the carriers at their steady ratio the thread slip is purely axial, so the
    screw/roller Coulomb friction adds ``n mu F_RS`` to each thread's axial load with
    ``F_RS = (F_N / n) / (1/|n| - mu)``. Load-independent (all losses scale with the load).
    With ``mu_rs = mu_ns = 0`` this is eq 35.
    """
    def thread(k, nut_load):
        st = stages[k]
        extra = nut_load * mu_rs / (1.0 / thread_normal_norm(st) - mu_rs)
        return (nut_load + extra) * st.lead / (2 * math.pi)
    torque, _ = joint_loads(stages, 1.0, thread, [], mu_ss, mu_ns)
    return sum(s.lead for s in stages) / (2 * math.pi * torque)


def efficiency_eq35(stages, mu_ss: float) -> float:
    """Seed 004 eq 35 (two stages, spline friction only)."""
    l1, l2 = stages[0].lead, stages[1].lead
    return 1.0 / (1.0 + mu_ss * l1 * l2 / (2 * math.pi * stages[1].screw_spline_radius * (l1 + l2)))


@dataclass(frozen=True)
class RollerScrew(Stage):
    """Multi-stage planetary roller screw as a drivetrain stage (backward, like BallScrew).

    Input = screw angle (rad), output = travel of the last nut (m); every screw turns with
    the first (eq 1) and nut k travels ``sum(L_1..L_k) / (2 pi)`` per screw radian (eq 3,
    magnitudes). The carriers turn at their steady rolling ratio, so each adds its carrier
    and roller inertia at that ratio; nuts, rollers and the riding screws add their masses at
    their own travel ratios.

    Parameters
    ----------
    name : str
    stages : tuple of RollerScrewStage
    roller_screw_friction, screw_screw_friction, nut_screw_friction : float
        mu_RS, mu_SS, mu_NS.
    efficiency : float
        Forward efficiency; by default the steady-state value of :func:`steady_efficiency`.
    stroke_range : tuple of float or None
        Admissible travel of the last nut (m), scene key ``stroke``; None when not given.
    dynamic_load_rating : float or None
        Basic dynamic axial load rating C_a of the screw (N): the thrust on the last nut for
        an L10 life of 10**6 screw revolutions (life exponent 3, as ISO 3408-5 rates ball
        screws and roller-screw makers rate theirs); None: no screw life computed.
    static_load_rating : float or None
        Basic static axial load rating C_0a (N): the peak thrust on the last nut is sized
        against it; None when not given.
    bearing_dynamic_load_rating : float or None
        Basic dynamic axial load rating of the first screw's axial support bearing (N,
        ISO 281); it carries the thrust.
    bearing_kind : str
        ``"ball"`` (life exponent 3) or ``"roller"`` (10/3) bearing.
    """

    KIND = "roller_screw"
    IO = ("rotary", "travel")
    UNITS = ("rad", "m", "m")
    RATIO_KEYS = "stages[].lead"
    DISPLAY_UNITS = (("stroke_range", "mm", 1e3),)

    name: str
    stages: tuple
    roller_screw_friction: float = 0.0
    screw_screw_friction: float = 0.0
    nut_screw_friction: float = 0.0
    efficiency: float = 1.0
    stroke_range: tuple | None = None
    dynamic_load_rating: float | None = None
    static_load_rating: float | None = None
    bearing_dynamic_load_rating: float | None = None
    bearing_kind: str = "ball"

    #: each field's SI unit and rule (:func:`~servo_toolkit.components.base.check_fields`),
    #: checked however the screw is made
    FIELD_RULES = {"efficiency": ("dimensionless", "efficiency"), "stroke_range": ("m", "stroke"),
                   "dynamic_load_rating": ("N", "positive"), "static_load_rating": ("N", "positive"),
                   "bearing_dynamic_load_rating": ("N", "positive")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "RollerScrew")
        for name in ("roller_screw_friction", "screw_screw_friction", "nut_screw_friction"):
            _coefficient(getattr(self, name), f"RollerScrew.{name}")
        require(self.bearing_kind in ("ball", "roller"), "RollerScrew.bearing_kind",
                f"must be 'ball' or 'roller' (got {self.bearing_kind!r})")

    @property
    def nut_mass(self) -> float:
        """Mass carried by the last nut's thread (kg): the last nut and its rollers."""
        last = self.stages[-1]
        return last.nut_mass + last.rollers * last.roller_mass

    @property
    def backdrive_efficiency(self) -> float:
        """Back-drive efficiency (:func:`~.base.screw_backdrive_efficiency`)."""
        return screw_backdrive_efficiency(self.efficiency)

    @property
    def stroke(self):
        return self.stroke_range

    @property
    def ratio(self) -> float:
        """Screw rad per m of last-nut travel."""
        return 1.0 / float(nut_travel_per_screw_radian(self.stages)[-1])

    def map(self, z) -> Jet:
        return Jet.linear(z, self.ratio)

    def elements(self, z) -> list[Element]:
        lam = nut_travel_per_screw_radian(self.stages) * self.ratio  # nut travel per last-nut travel
        out = []
        for k, st in enumerate(self.stages):
            out.append(Element(f"{self.name}: screw {k + 1}", st.screw_inertia, Jet.linear(z, self.ratio),
                               "input"))
            out.append(Element(f"{self.name}: carrier and rollers {k + 1}", carrier_inertia_total(st),
                               Jet.linear(z, self.ratio * carrier_ratio(st))))
            out.append(Element(f"{self.name}: nut and rollers {k + 1}", st.nut_mass + st.rollers * st.roller_mass,
                               Jet.linear(z, lam[k])))
            if k > 0:
                out.append(Element(f"{self.name}: screw {k + 1} travel", st.screw_mass, Jet.linear(z, lam[k - 1])))
        return out

    @classmethod
    def from_table(cls, f: Fields) -> "RollerScrew":
        """Build from a ``[[drivetrain]]`` table of kind ``roller_screw`` with ``[[drivetrain.stages]]``."""
        raw = f.raw("stages")
        require(isinstance(raw, list) and raw, f.key("stages"),
                "must be a non-empty array of tables [[drivetrain.stages]]")
        stages = tuple(RollerScrewStage.from_table(Fields(t, f"{f.key('stages')}[{i}]"), i == 0)
                       for i, t in enumerate(raw))
        mus = {name: _coefficient(f.raw(name, 0.0), f.key(name))
               for name in ("roller_screw_friction", "screw_screw_friction", "nut_screw_friction")}
        eta = steady_efficiency(stages, mus["roller_screw_friction"], mus["screw_screw_friction"],
                                mus["nut_screw_friction"])
        require(eta > 0, f.key("roller_screw_friction"), "the friction coefficients leave no positive efficiency")
        efficiency = f.number("efficiency", eta, rule="positive", bounds=EFFICIENCY_RANGE)
        require(efficiency <= 1, f.key("efficiency"), "must be in (0, 1]")
        travel = read_stroke(f, "m", "nut travel")
        ratings = {name: f.quantity(name, "N", rule="positive") if f.has(name) else None
                   for name in ("dynamic_load_rating", "static_load_rating", "bearing_dynamic_load_rating")}
        bearing_kind = f.text("bearing_kind", "ball", choices=("ball", "roller"))
        f.check_unknown()
        return cls(name=f.text("name", "roller screw"), stages=stages, efficiency=efficiency,
                   stroke_range=travel, bearing_kind=bearing_kind, **ratings, **mus)
