"""The a-priori cost of smoothing or leaving out friction (``ModelOptions(friction="stick")``
against ``"smooth"``), node by node.

Friction acts at three kinds of node: the motor (its own Coulomb level Tc and breakaway level
Ts), each stage that gives friction at its output (``[[drivetrain]]`` ``coulomb_friction``,
``static_friction``: reflected to the output by du_k/dq at q0) and the load (``[load]``
``coulomb_friction``, ``static_friction``). The smooth model keeps the motor's Coulomb friction
as ``Tc tanh(w / w_s)`` (``ModelOptions.friction_speed`` w_s) and leaves out the rest: no stick
at the reversals or at rest, no breakaway excess Ts - Tc, none of the stages' friction (a stage
lumped onto the motor side is smoothed with the motor's; counted here as left out, an upper
estimate) and none of the load's. Each node gets the largest of two relative errors over the
study's frequencies and amplitudes, both of a relay F1 = (4 / pi) F at the node's level F
reflected to the output, against the sine's output amplitude ``|T(jw)| A``:

- the output's response: ``|S_d(jw)| F1 / (|T| A)``, ``S_d`` the closed loop's response from a
  torque at the output to the output (the cost on the position);
- the force the motion needs: ``F1 / |(-J w^2 + j w b + k_h) T A|`` with J and b the inertia and
  viscous friction the node drives (the whole chain's for the motor side, the load side of the
  two-mass split for a node beyond the compliance): the cost on the current, and on whether the
  node beyond a compliance or a backlash moves with the motor at all. A friction that exceeds a
  fraction of the force its node's motion needs decides that motion and cannot be smoothed or
  left out.

The level F of a node left out is its breakaway level Ts. The motor's smoothed friction is
right while it slides fast, and wrong at each reversal of the sine (every half period): there
friction that holds sticks the motor until the loop's torque passes the breakaway level, where
the smooth model lets it turn through at a fraction of Tc. That stick phase is counted as the
breakaway excess Ts - Tc plus the whole swing Ts + Tc over the part of each half period in which
the motor turns slower than w_s, (2 / pi) asin(w_s / Omega) with Omega = N w |T| A the motor's
speed amplitude: F = Ts - Tc + (Ts + Tc) (2 / pi) asin(min(1, w_s / Omega)). Where the drive at
rest holds within a band (:func:`~.hunting.holding_band`: the breakaway levels, widened by a
lossy chain's efficiencies) that the loop's torque at the command's whole amplitude as error,
Kt |C(jw)| A with C the motion controller's current per unit of output, does not leave, the
output stays still with friction that holds and the smooth model would creep: the motor's
cost is then at least 1 (the output's whole motion).

The position term alone, at the breakaway levels, is the estimate as an upper one of the smooth
model's cost on the output: on the reference EMA at 8 Hz (two-mass model) 0.23 where leaving
stick out costs 0.14 at 0.05 deg and 0.0058 where it costs 2e-5 at 2 deg; with a 0.2 N*m
breakaway, 2.3 against 0.25 at 0.05 deg and 0.058 against 2e-5 at 2 deg. On a DC gearmotor
moving a 20 kg carriage with 10 N of Coulomb friction through a 50:1 gearhead and a 10 mm screw
at 0.5 mm, 2 Hz the force term of the load's friction is 15 (10 N against the 0.85 N the
carriage's own motion needs): the smooth model, which drops it, draws 2.5 times the current of
the full model. ``reduce`` measures the cost by running the study with and without stick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...drivetrain.stage_friction import stage_nodes, stage_output_slope
from ...lti.system import ss
from ...plant.linear import PLANT_OUTPUTS, plant_matrices
from ..hunting import holding_band


@dataclass(frozen=True)
class FrictionNode:
    """One node's friction, reflected to the output, and what the smooth model does with it.

    Attributes
    ----------
    label : str
        ``"motor"``, ``"drivetrain[k] (name)"`` or ``"load"``.
    coulomb, breakaway : float
        Tc and Ts at the output (N*m, or N for an output travel).
    side : {"motor", "load"}
        The side of the two-mass split the node moves with.
    smoothed : bool
        The smooth model keeps its Coulomb level (the motor's own); else it leaves it out.
    estimate : float
        The a-priori relative cost of smoothing or leaving it out (module docstring).
    where : str
        The frequency and amplitude of the worst case, and whether the drive held.
    """

    label: str
    coulomb: float
    breakaway: float
    side: str
    smoothed: bool
    estimate: float = 0.0
    where: str = ""

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"node": self.label, "coulomb_at_output": self.coulomb, "breakaway_at_output": self.breakaway,
                "side": self.side, "without_stick": "smoothed" if self.smoothed else "left out",
                "estimate_relative": self.estimate, "worst": self.where}


def friction_nodes(scene, q0: float, rigid: bool) -> list:
    """Every node of the scene that carries Coulomb or static friction, its levels reflected to
    the output at q0 (a stage's by du_k/dq, the motor's by the ratio N), on the side of the
    two-mass split its node goes to (:func:`~servo_toolkit.drivetrain.stage_friction.lumped_friction`'s
    rule; a rigid chain has one side)."""
    drive, motor, load = scene.drivetrain, scene.motor, scene.load
    n = abs(float(drive.ratio([q0])[0][0]))
    out = []
    if max(motor.coulomb_friction, motor.breakaway_torque) > 0:
        out.append(FrictionNode("motor", motor.coulomb_friction * n, motor.breakaway_torque * n, "motor", True))
    frictions = scene.stage_friction or ()
    if any(f is not None for f in frictions):
        last = -1 if rigid else int(drive.chain.node_split([q0]).last_motor_node[0])
        nodes = stage_nodes(drive.chain)
        for k, fr in enumerate(frictions):
            if fr is None or max(fr.coulomb_friction, fr.breakaway) == 0:
                continue
            u = abs(stage_output_slope(drive, k, q0))
            name = getattr(drive.stages[k], "name", "") or type(drive.stages[k]).__name__
            side = "motor" if rigid or nodes[k] <= last else "load"
            out.append(FrictionNode(f"drivetrain[{k}] ({name})", fr.coulomb_friction * u, fr.breakaway * u, side, False))
    if max(load.coulomb_friction, load.breakaway) > 0:
        out.append(FrictionNode("load", load.coulomb_friction, load.breakaway, "motor" if rigid else "load", False))
    return out


def disturbance_response(p, controller, motor, w) -> np.ndarray:
    """Closed-loop response of the output angle to a torque at the output (rad per N*m, or
    m per N), at the angular frequencies ``w``, assembled as the reduction's loops are."""
    from ...loop.closed_loop import closed_loop_of
    a, b, c, d, states = plant_matrices(p, True)
    g = ss(a, b, c, d, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states, name="plant")
    cl = closed_loop_of(g, controller, motor, ("theta_ref", "tau_ext"), ("theta",))
    return np.asarray(cl[0, 1](1j * np.asarray(w, float))).reshape(-1)


def position_gain(controller, w) -> np.ndarray:
    """The motion controller's current command per unit of output angle (A/rad, or A/m) at the
    angular frequencies ``w``: with the output held still the loop is open there, and this is
    the current the command's error asks for."""
    return np.asarray(controller.motion_block[0, "theta"](1j * np.asarray(w, float))).reshape(-1)


def motion_force(p, w, side: str) -> np.ndarray:
    """|-J w^2 + j w b + k_h| per unit of output amplitude: the force (N*m, or N) the motion of
    the side of the two-mass plant ``p`` a node drives needs, at the angular frequencies ``w``
    (the motor side drives the whole chain)."""
    if side == "load" and p.J2 > 0 and math.isfinite(p.K):
        return np.abs(-p.J2 * w**2 + 1j * w * p.b2 + p.kh)
    return np.abs(-(p.J1 + p.J2) * w**2 + 1j * w * (p.b1 + p.b2) + p.kh)


def judge_nodes(scene, controller, p, w, t_full, amplitudes, options):
    """Each node of :func:`friction_nodes` with its estimate (module docstring).

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    p : PlantParameters
        The design plant at the operating point.
    w : numpy.ndarray
        The study's angular frequencies (rad/s).
    t_full : numpy.ndarray
        Closed-loop response theta / theta_ref at ``w``.
    amplitudes : sequence of float
        Command amplitudes (rad, or m).
    options : ModelOptions
        The full model's (its ``friction_speed`` and ``efficiency``).

    Returns
    -------
    list of FrictionNode
    """
    from ...core.output_units import output_unit
    nodes = friction_nodes(scene, p.q0, p.rigid)
    if not nodes:
        return []
    u = output_unit(scene)
    n = p.N
    s_d = np.abs(disturbance_response(p, controller, scene.motor, w))
    t = np.abs(t_full)
    hold = holding_band(scene, p.q0, options.efficiency)  # N*m at the motor shaft
    swing = scene.motor.torque_constant * np.abs(position_gain(controller, w))  # N*m per unit of error
    out = []
    for node in nodes:
        need = motion_force(p, w, node.side)
        worst, where = 0.0, ""
        for a in amplitudes:
            for k, wk in enumerate(w):
                out_amp = t[k] * a
                level = node.breakaway
                if node.smoothed:
                    omega = n * wk * out_amp
                    slow = 2 / math.pi * math.asin(min(1.0, options.friction_speed / omega)) if omega > 0 else 1.0
                    level = node.breakaway - node.coulomb + (node.breakaway + node.coulomb) * slow
                on_output = s_d[k] * 4 / math.pi * node.breakaway / out_amp
                on_force = 4 / math.pi * level / (need[k] * out_amp)
                e, held = max(on_output, on_force), False
                if node.label == "motor" and swing[k] * a < hold:
                    e, held = max(e, 1.0), True
                if e > worst:
                    worst = float(e)
                    where = (f"worst at {wk / (2 * math.pi):.3g} Hz, {u.text(a, 3)}: relay on the output "
                             f"{on_output:.2g}, {4 / math.pi * level:.3g} {u.moment} against the "
                             f"{need[k] * out_amp:.3g} {u.moment} the {node.side} side's motion needs {on_force:.2g}"
                             + (f"; the drive at rest holds within +-{hold:.4g} N*m at the motor, which the "
                                "loop's torque at the command's amplitude does not leave (the output stays "
                                "still: the smooth model would creep)" if held else ""))
        out.append(replace(node, estimate=worst, where=where))
    return out


def friction_effect(scene, controller, p, w, t_full, amplitudes, base):
    """The numbers of the effect "friction that holds (stick)" of a reduction, or None when the
    full model runs the smooth friction (``base.friction != "stick"``) or the scene has no
    Coulomb or static friction at any node.

    Returns
    -------
    (str, float, tuple of FrictionNode) or None
        The quantity compared, in words, the estimate (the sum of the nodes') and the nodes.
    """
    if base.friction != "stick":
        return None
    nodes = judge_nodes(scene, controller, p, w, t_full, amplitudes, base)
    if not nodes:
        return None
    from ...core.output_units import output_unit
    u = output_unit(scene)
    def level(x):
        if x.label == "motor":  # at its own shaft
            return (f"motor breakaway {x.breakaway / p.N:.4g} N*m (Coulomb {x.coulomb / p.N:.4g} N*m, smoothed "
                    f"over {base.friction_speed:g} rad/s without stick)")
        return (f"{x.label} breakaway {x.breakaway:.4g} {u.moment} at the output (Coulomb {x.coulomb:.4g} "
                f"{u.moment}, left out without stick)")
    quantity = "; ".join(f"{level(x)}: {x.estimate:.2g}" for x in nodes)
    return quantity, float(sum(x.estimate for x in nodes)), tuple(nodes)


def friction_note(nodes, left_out: bool) -> str:
    """One line naming each node's friction, what the run did with it and its estimate."""
    what = (lambda x: "smoothed, no stick" if x.smoothed else "left out") if left_out else (lambda x: "holds")
    return ("friction " + ("without stick" if left_out else "that holds (stick) kept") + ": "
            + ", ".join(f"{x.label} {what(x)} (estimate {x.estimate:.2g})" for x in nodes))


def without_stick(options):
    """The reduced options with the smooth friction model."""
    return replace(options, friction="smooth")


__all__ = ["FrictionNode", "disturbance_response", "friction_effect", "friction_nodes", "friction_note",
           "judge_nodes", "motion_force", "position_gain", "without_stick"]
