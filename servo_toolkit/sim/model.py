"""Model assembly: a scene and a controller -> an immutable :class:`Model` of flat arrays.

The drivetrain is the lumped chain (:mod:`servo_toolkit.drivetrain.chain`) in one of two
forms (``ModelOptions.chain``; ``"auto"`` chooses by :func:`~.chain_choice.choose_chain`, the
cost of lumping the upper modes at the scene's working frequencies, and the notes say which):

- the **full chain** (:mod:`.chain_model`): every node with inertia, each with its inertia
  J_j(p) tabulated along the stroke at the motor-side position (Lagrange's velocity terms
  keep the undamped chain's energy), every compliance with its stiffness along the stroke,
  its own play and its own damper;
- the **two-mass reduction** (:meth:`servo_toolkit.drivetrain.chain.Chain.two_mass` at q0,
  the chain's lowest resonance and antiresonance), as the linear design plant has it: its
  load-side inertia J2 is held at its q0 value, the motor side is J(q) - J2, and the series
  stiffness K(q) (scaled to the reduction's stiffness at q0) and the lost motion of every
  stage are lumped between them at the output; for one compliance these are the nodes on
  either side of it (rotor, pinion, ... each member at its node).

A lost motion in a chain without a compliance is refused (:class:`SceneError` naming its key),
never dropped.

Position-dependent data are tabulated along the stroke and interpolated with cubic Hermite
polynomials on exact values and derivatives (J, dJ/dq and N, dN/dq from the drivetrain's
jets; K and dK/dq from a cubic spline). The interpolation error at the cell midpoints is
measured on assembly and stored in :attr:`Model.table_error`; with the default 1025 points
on the EMA stroke it is below 1e-9 relative.

Simplifications (documented, switchable where a reduction study needs it):

- the backlash is the total lost motion at the operating point q0 (its variation along the
  stroke is a few per cent and is not tabulated);
- Coulomb friction is smoothed by default, ``Tc tanh(omega_m / w_s)``, so that the
  right-hand side is continuous for RK4; ``ModelOptions(friction="stick")`` sticks exactly
  (``servo_toolkit/_physics/friction.h``, switches located within the step by
  ``split_step.h``);
- the stages' efficiencies are lumped into one loss on the torque transmitted past the rotor
  and the members before the losses (inertia J_w = JW n(p)^2: they turn at a fixed ratio to
  the motor, as a rotor and its pinion do), as Modelica's
  ``LossyGear`` models a gear: with T = n tau_shaft - J_w p'' - J_w' p'^2 / 2, driving (T and
  speed of the same sign) the chain beyond receives eta T, back-driven T / eta_b
  (eta the product of the stages' efficiencies, eta_b of their back-drive efficiencies:
  screws ``2 - 1/eta``, gears and linkages eta; a self-locking chain is modelled with
  eta_b = :data:`~.chain_split.MIN_BACKDRIVE`). The loss c |T| (c = 1 - eta driving, 1/eta_b - 1
  back-driven) acts against the motion with smooth signs of the torque (scale
  :data:`~.chain_split.LOSS_TORQUE_SCALE` of the peak motor torque at the output) and of the speed (the
  friction speed), so RK4 keeps its order and the loss power is never negative. The linear
  design plant (:mod:`servo_toolkit.plant.linear`) is the driving-mode linearization (eta on the
  motor torque, the motor side's inertia less (1 - eta) J_w): it is the small-signal model
  wherever the motor drives the load (the tests compare the
  model's Jacobian with it); a motion that reverses the power flow (a free sine, where
  torque and speed are in quadrature) sees eta on half the cycle and 1/eta_b on the other,
  and the sweep measures what that changes. The other losses are the motor's viscous and
  Coulomb friction, the structural damping of the compliance and the load's damping;
- the drivetrain's structural damping is a damper per compliance, stiffness-proportional
  along the stroke, set by the damping ratio of the mode it dominates
  (:mod:`servo_toolkit.drivetrain.chain_damping`; the stage's ``damping_ratio``, else
  ``options.damping_ratio``); the two-mass reduction's damper, ``beta K`` with
  ``beta = 2 zeta_1 / omega_n`` at q0, keeps the chain's lowest mode's ratio zeta_1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ..errors import SceneError
from ..core.output_units import OutputUnit
from ..drivetrain.operating_point import operating_point
from . import speed_estimator as estimator, layout as lo
from ..plant.linear import two_mass_damping
from .tables import frozen_tables
from .chain_model import (chain_damping_facts, chain_model, chain_state_names, damping_note,
                          held_inertia_error,
                          resolve as resolve_chain)
from ..drivetrain.stage_friction import lumped_friction
from .node_friction import with_node_friction
from .chain_split import load_split, loss_slots, refuse_rigid_lash
from .command_slots import pack_feedforward, pack_shaper, with_back_calculation, with_schedule
from .model_options import ModelOptions  # noqa: F401 - re-exported
from .model_slots import (drivetrain_slots, friction_slots, pack_controller,
                          with_cam, with_full_chain, with_table_error)


@dataclass(frozen=True)
class Model:
    """An assembled closed-loop model: immutable description, flat arrays for the kernels.

    Attributes
    ----------
    name : str
        Scene name.
    options : ModelOptions
    P : numpy.ndarray
        Parameters (read-only); the reference slots are filled per run.
    T : numpy.ndarray
        Stroke tables (rows in :mod:`layout`).
    nx : int
        State length (7 physical + controller states).
    state_names : tuple of str
    sample_time : float
        Controller sample time (0: continuous or open loop).
    closed_loop : bool
    q0 : float
        Operating point (mid-stroke), rad.
    stroke : tuple of float
    rigid : bool
    table_error : dict
        Relative interpolation error of J, N and K at the cell midpoints.
    load_side : tuple of str
        Inertial elements on the load side of the compliance.
    controller : str
        Description of the controller.
    notes : tuple of str
        What was simplified or switched, in words.
    speed_estimator : str
        The motor speed the speed loop used: ``"ideal"``, ``"difference"`` or ``"kalman"``.
    estimator : dict
        The estimator's data (quantum, jerk, gain, state names); empty for ``"ideal"``.
    output_unit : {"rad", "m"}
        Unit of the output coordinate q (an angle, or a travel for a chain ending in a screw).
    damping : dict
        The drivetrain's structural damping: ``two_mass_ratio`` (the damping ratio of the
        two-mass reduction's mode, the chain's lowest mode's), and for the full chain each
        segment's ``segment_ratios`` and ``beta_s``, each mode's ``modes_hz`` and its
        ``mode_ratios`` (modal); empty for a rigid chain.
    """

    name: str
    options: ModelOptions
    P: np.ndarray
    T: np.ndarray
    nx: int
    state_names: tuple
    sample_time: float
    closed_loop: bool
    q0: float
    stroke: tuple
    rigid: bool
    table_error: dict = field(default_factory=dict)
    load_side: tuple = ()
    controller: str = ""
    notes: tuple = ()
    speed_estimator: str = "ideal"
    estimator: dict = field(default_factory=dict)
    output_unit: str = "rad"
    damping: dict = field(default_factory=dict)

    def __post_init__(self):
        # read-only C-contiguous tables, as every kernel reads them (a run never writes its tables)
        object.__setattr__(self, "T", frozen_tables(self.T))

    def parameters(self) -> np.ndarray:
        """A writable copy of ``P`` (fill the reference slots, then run)."""
        return self.P.copy()


def _grid(drive, n):
    lo_, hi = drive.stroke
    if drive.ends_in_cam:
        return np.linspace(lo_, hi, n), True
    margin = 0.1 * (hi - lo_)
    q = np.linspace(lo_ - margin, hi + margin, n)
    try:
        with np.errstate(all="ignore"):
            ok = np.all(np.isfinite(drive.ratio(q)[0])) and np.all(np.isfinite(drive.inertia(q)[0]))
    except (ValueError, SceneError):
        ok = False
    return (q, False) if ok else (np.linspace(lo_, hi, n), False)


def build_model(scene, controller=None, options: ModelOptions | None = None) -> Model:
    """Assemble the compiled model of ``scene`` driven by ``controller``.

    Parameters
    ----------
    scene : Scene
        A scene with a motor-driven drivetrain.
    controller : CascadeController or None
        None builds an open-loop model (constant voltage, set per run).
    options : ModelOptions, optional

    Returns
    -------
    Model
    """
    options = options or ModelOptions()
    drive = scene.drivetrain
    drive.check()
    motor, load = scene.motor, scene.load
    notes = []
    q, periodic = _grid(drive, options.table_points)
    q0, why = operating_point(scene)  # where the design puts it: runs start where the loop was designed
    if why:
        notes.append(f"starts at the design's {why.split(',')[0]} (largest motor-side inertia)")
    j_tot, dj_tot = drive.inertia(q)
    n_tab, dn_tab = drive.ratio(q)
    m_tab = drive.kinematics(q).motor.value - drive.kinematics([q0]).motor.value[0]
    if np.any(n_tab <= 0):
        # sign convention: positive motor rotation moves q up
        n_tab, dn_tab, m_tab = -n_tab, -dn_tab, -m_tab
        notes.append("ratio sign flipped so that N(q) > 0")
    if not options.variable_inertia:
        j0 = float(drive.inertia([q0])[0][0])
        j_tot, dj_tot = np.full_like(q, j0), np.zeros_like(q)
        notes.append(f"constant inertia J(q0) = {j0:.4g} {OutputUnit(drive.output_unit).inertia}")
    k_tot = drive.stiffness(q).total
    rigid = not options.compliance or not np.all(np.isfinite(k_tot))
    jl, load_side, last_motor_node, k_factor = load_split(drive, q0)
    full = None
    damping = {}
    if not rigid:
        zeta = two_mass_damping(drive.chain, q0, options.damping_ratio)
        damping = {"two_mass_ratio": zeta}
    if not rigid and resolve_chain(scene, controller, options, q0, notes) == "full":
        full = chain_model(drive, q, q0, options, j_tot, dj_tot, options.damping_ratio)
        jl, load_side, last_motor_node, k_factor = full["j_load"], full["load_side"], 0, 1.0
        damping.update(chain_damping_facts(full["damping"]))
        notes.append(damping_note(full["damping"]))
    if not rigid and full is None:
        k_tot = k_tot * k_factor
        if abs(k_factor - 1.0) > 1e-3:
            notes.append(f"series stiffness scaled by {k_factor:.4g}: the two-mass reduction keeps the "
                         "chain's lowest mode at q0")
    if not rigid and jl <= 0:
        rigid = True
        notes.append("no inertia on the load side of the compliance: rigid chain")
        refuse_rigid_lash(drive.chain.lashes, options)
    if rigid and options.compliance and not np.all(np.isfinite(k_tot)):
        notes.append("no compliance in the scene: rigid chain")
        refuse_rigid_lash(drive.chain.rigid_lashes, options)
    dj_row = dj_tot
    if rigid:
        last_motor_node = None
        j_row, k_row, dk_row, jl = j_tot, np.zeros_like(q), np.zeros_like(q), 0.0
    elif full is not None:
        j_row, dj_row, (k_row, dk_row) = full["j_row"], full["dj_row"], full["k_rows"][:2]
        varies = {j: v for j, v in full["variation"].items() if v > 1e-3}
        if varies and options.variable_inertia:
            notes.append("every node's inertia along the stroke (" + ", ".join(
                f"node {j} varies by {v:.1%}" for j, v in varies.items()) + ")")
    else:
        moving = drive.chain.node_inertias(q)[last_motor_node + 1:].sum(axis=0)
        if np.ptp(moving) > 1e-3 * jl and options.variable_inertia:
            notes.append(f"two-mass reduction: load-side inertia held at its q0 value {jl:.4g} (it varies by "
                         f"{np.ptp(moving) / jl:.1%} along the stroke; the rest moves with the motor side)")
        j_row = j_tot - jl
        if np.any(j_row <= 0):
            raise held_inertia_error(drive, q, j_row)
        spline = CubicSpline(q, k_tot)
        k_row, dk_row = k_tot, spline(q, 1)
    table = np.vstack([j_row, dj_row, n_tab, dn_tab, k_row, dk_row, m_tab, n_tab]
                      + ([] if full is None else [full["k_rows"][2:], full["node_rows"]])).astype(float)

    motor, load = lumped_friction(scene, q0, rigid, notes, own=() if full is None else full["nodes"][1:-1])
    P = np.zeros(lo.NP_HEADER)
    P[[lo.R, lo.KT, lo.KE, lo.BM, lo.TC]] = (motor.resistance, motor.torque_constant,
                                             motor.back_emf_constant, motor.viscous_friction,
                                             motor.coulomb_friction)
    P[lo.L] = motor.inductance if options.inductance else 0.0
    P[lo.INV_L] = 1.0 / P[lo.L] if P[lo.L] > 0 else 0.0
    if motor.inductance > 0 and not options.inductance:
        notes.append("armature inductance left out (ideal current loop)")
    P[lo.WS] = 1.0 / options.friction_speed  # stored as its reciprocal
    friction_slots(P, motor, load, options, notes)
    loss_slots(P, drive, motor, q0, options, notes, last_motor_node)
    P[lo.VLIM], P[lo.ILIM] = motor.voltage_limit, motor.current_limit
    P[lo.TAB_LO], P[lo.TAB_H], P[lo.TAB_N] = q[0], q[1] - q[0], q.size
    P[lo.INV_H] = 1.0 / P[lo.TAB_H]
    P[lo.PERIODIC] = 1.0 if periodic else 0.0
    P[lo.RIGID] = 1.0 if rigid else 0.0
    P[[lo.HINGE_M, lo.HINGE_K, lo.HINGE_D]] = (load.hinge_moment, load.hinge_stiffness, load.damping)
    lo_s, hi_s = drive.stroke
    P[lo.STROKE_LO], P[lo.STROKE_HI] = lo_s, hi_s
    P[lo.STROKE_MODE] = (lo.STROKE_NONE if periodic else
                         lo.STROKE_STOP if options.stroke_end == "stop" else lo.STROKE_ERROR)
    play = 0.0
    if not rigid and options.backlash:
        play = float(drive.backlash([q0])[0]) if options.play is None else options.play
    drivetrain_slots(P, rigid=rigid, j0_tot=float(np.interp(q0, q, j_tot)), jl=jl,
                     k0=0.0 if rigid else float(np.interp(q0, q, k_tot)), options=options, play=play,
                     zeta=damping.get("two_mass_ratio"))
    if full is not None:
        P = with_full_chain(P, full, options)
        P = with_node_friction(P, scene, q0, full["nodes"], options,
                               "N" if drive.output_unit == "m" else "N*m", notes)

    P = with_cam(P, drive, rigid, notes)
    names = list(lo.STATE_NAMES)
    desc, ts, closed = "open loop (constant voltage)", 0.0, controller is not None
    est_kind, est_info = "ideal", {}
    if closed:
        mode = lo.SAMPLED if (options.controller_mode == "sampled" and controller.sample_time > 0) \
            else lo.CONTINUOUS
        a, b, c, d = pack_controller(controller, mode)
        nc = a.shape[0]
        P[lo.CMODE], P[lo.NC] = mode, nc
        pack_feedforward(P, controller, scene, controller.sample_time if mode == lo.SAMPLED else 0.0, notes)
        pack_shaper(P, controller, notes)
        P[lo.KPI], P[lo.KII] = controller.current_kp, controller.current_ki
        # back-calculation tracking time = the PI's integral time Kpi / Kii
        P[lo.KAW] = (P[lo.KII] / P[lo.KPI] if P[lo.KPI] > 0 else
                     P[lo.R] * P[lo.INV_L] if P[lo.L] > 0 else 0.0)
        if P[lo.L] > 0 and controller.current_kp <= 0 and controller.current_ki <= 0:
            raise SceneError("controller", "current loop gains are zero but the motor has inductance")
        if mode == lo.SAMPLED:
            ts = controller.sample_time
            count = scene.sensors.output_count(drive.output_is_linear)
            if options.quantization and count > 0:
                P[lo.LSB] = count
                unit = OutputUnit(drive.output_unit)
                notes.append(f"the controller reads the output in counts of {unit.text(count, 3)} (its "
                             + ("linear scale's resolution)" if unit.linear else
                                f"encoder's {scene.sensors.output_encoder_bits} bits per revolution)"))
        base = P.size
        P[lo.OFF_A], P[lo.OFF_B] = base, base + nc * nc
        P[lo.OFF_C], P[lo.OFF_D] = base + nc * nc + 3 * nc, base + nc * nc + 4 * nc
        P = np.concatenate([P, a.ravel(), b.ravel(), c.ravel(), d.ravel()])
        names += [f"controller[{j}]" for j in range(nc)]
        desc = controller.description or "cascade controller"
        est_kind = options.speed_estimator or scene.sensors.speed_estimator
        if est_kind != "ideal" and mode != lo.SAMPLED:
            notes.append(f"speed estimator {est_kind!r} needs a sampled controller: the continuous "
                         "loop uses the true motor speed")
            est_kind = "ideal"
        if est_kind != "ideal":
            slots, extra, est_names, est_info, note = estimator.pack(
                scene, controller, options, est_kind, options.quantization, len(names), P.size)
            for slot, value in slots.items():
                P[slot] = value
            P = np.concatenate([P, extra])
            names += est_names
            notes.append(note)
        P = with_schedule(P, controller, mode, notes)
        P = with_back_calculation(P, a, b, c, d, mode, notes)
    else:
        P[lo.CMODE] = lo.OPEN_LOOP
    if full is not None:
        P[lo.OFF_NODE] = len(names)
        names += chain_state_names(full["nodes"])
        notes.append(f"{len(full['nodes'])} masses, {len(full['nodes']) - 1} compliances (nodes "
                     f"{', '.join(map(str, full['nodes']))} of the chain)")
    P.setflags(write=False)
    table.setflags(write=False)
    model = Model(name=scene.name, options=options, P=P, T=table, nx=len(names),
                  state_names=tuple(names), sample_time=ts, closed_loop=closed, q0=q0,
                  stroke=(lo_s, hi_s), rigid=rigid, load_side=load_side if not rigid else (),
                  controller=desc, notes=tuple(notes), speed_estimator=est_kind, estimator=est_info,
                  output_unit=drive.output_unit, damping=damping)
    return with_table_error(model, drive, q)
