"""A-priori influence of each modelled effect on a study, and the reduced model it allows.

Every estimate is a relative error of the closed-loop response theta/theta_ref,
``e = max_f |T_without(j w) / T(j w) - 1|`` over the study's frequencies (e bounds the gain
error by 20 log10(1 + e) dB and the phase error by asin(e)). Linear effects are estimated
with the design's linear closed loop of :mod:`servo_toolkit.plant.linear` assembled twice, with and without the effect; nonlinear ones from their physics:

- armature inductance: loop without inductance (ideal current loop);
- a stage's compliance (candidates: compliance share below 1e-3 over the motion, the seed
  001 criterion): loop with the series stiffness raised by 1 / (1 - share);
- the whole drivetrain compliance: rigid loop against the two-mass loop (resonance vs the
  study's highest frequency);
- the drivetrain chain's modes above the first: the two-mass loop against the full chain's
  (:func:`servo_toolkit.sim.chain_choice.lumping_cost`); kept or left out by the rule
  ``simulate`` follows (:func:`servo_toolkit.sim.chain_choice.choose_chain`: lumped when the
  cost is within half the tolerance), not by the budget; left out, the run uses the two-mass
  reduction;
- backlash of total lost motion b at the output: zero when the force through the
  compliance never reverses (the static load keeps the contact closed: the dynamic force
  amplitude, from the linear loop, stays below 80 % of the static one); otherwise the
  describing-function bound b / A_out (the backlash describing function deviates from 1 by
  about (2 / pi) b / A for b << A);
- inertia variation over the motion: loop with the motor-side inertia changed by
  max |J(q) - J(q0)| + max |dJ/dq| A / 2 (the velocity term J' q'^2 / 2 acts like an inertia
  error of J' A / 2);
- friction that holds (stick), where the full model has it (``friction="stick"``): node by
  node (the motor, each stage's friction, the load's), the relay of its level against the
  output's motion through the loop and against the force its node's motion needs, the stick
  phases at the sine's reversals and a drive held at rest counted (:mod:`.friction`);
  left out, the run uses the smooth model (the motor's Coulomb friction smoothed, the rest
  left out);
- the current and voltage limits: reported, never left out (the model always clamps); the
  estimate is how far the linear prediction's peak exceeds the limit, 0 within it;
- ratio variation and small inertias are reported: the tabulated model has no switch for
  them and they cost nothing (they add no state).

The reduced model leaves out effects, smallest estimate first, while the sum of their
estimates stays within half the tolerance; the tolerance itself is the a-priori bound on
the full/reduced difference (the other half covers second-order and nonlinear terms that
first-order estimates leave out). Limits reached in the linear prediction invalidate the
linear estimates at those frequencies: the electrical path (inductance) is then kept.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...drivetrain.operating_point import operating_point
from ...core.output_units import output_unit
from ...lti.system import ss
from ...plant.linear import DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS, plant_matrices, plant_parameters, spring_damping
from ...sim.chain_choice import choose_chain, has_upper_modes
from .choice import Effect, ReductionPlan, choose
from .friction import friction_effect

#: the effect of friction that holds (the smooth model without it)
FRICTION_EFFECT = "friction that holds (stick)"

#: compliance share below which a stage's compliance is negligible (seed 001)
SHARE_THRESHOLD = 1e-3
#: inertia share below which an element is called small
INERTIA_SHARE_THRESHOLD = 1e-3
#: default tolerance on the relative response difference (0.17 dB / 1.15 deg)
DEFAULT_TOLERANCE = 0.02
#: backlash has no effect while the dynamic force stays below this fraction of the static one
CONTACT_MARGIN = 0.8


def loop_response(p, controller, motor, w, inductance: bool = True, plant_ss=None):
    """Closed-loop responses theta, i, u, omega per theta_ref (rad) of plant parameters ``p``
    (or of the plant block ``plant_ss``, e.g. the full chain's) with ``controller``,
    assembled as :func:`servo_toolkit.loop.linear_closed_loop` does.

    Returns
    -------
    dict of str to numpy.ndarray
        Complex responses at the angular frequencies ``w`` (keys ``theta``, ``i``, ``u``,
        ``omega``) and ``stable`` (bool).
    """
    from ...loop.closed_loop import closed_loop_of
    if plant_ss is None:
        a, b, c, d, states = plant_matrices(p, inductance)
        g = ss(a, b, c, d, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states, name="plant")
    else:
        g = plant_ss
    mot = motor if inductance else replace(motor, inductance=0.0)
    outs = ["theta", "i", "u", "omega"]
    cl = closed_loop_of(g, controller, mot, ("theta_ref",), outs)
    resp = np.asarray(cl(1j * np.asarray(w, float))).reshape(len(outs), -1)
    out = {k: resp[j] for j, k in enumerate(outs)}
    out["stable"] = bool(np.all(np.real(cl.poles()) < 0))
    return out


def _rel(t_var, t_ref):
    return float(np.max(np.abs(t_var / t_ref - 1.0)))


def load_side_inertia(drive, q0: float) -> float:
    """The inertia beyond the drivetrain's compliance at q0: the load side of the chain's
    two-mass reduction (:meth:`servo_toolkit.drivetrain.chain.Chain.two_mass`), as the plant and
    the simulation have it; 0 for a rigid chain."""
    return float(drive.chain.two_mass([q0]).load_side[0])


def plan_reduction(scene, controller, frequencies_hz, amplitudes, *, base=None,
                   tolerance: float = DEFAULT_TOLERANCE, stiffness=None) -> ReductionPlan:
    """Judge each effect against a study's frequencies and amplitudes; choose what to leave out.

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    frequencies_hz : sequence of float
    amplitudes : sequence of float
        Command amplitudes (rad).
    base : ModelOptions, optional
        The full model's options (its damping ratio is used for the linear loops).
    tolerance : float
        Bound on the relative response difference full/reduced.
    stiffness : (float, float), optional
        The smallest and largest factor on the series stiffness the study varies
        (:func:`varied_stiffness`): the drivetrain compliance it acts on is kept whatever its
        estimate, and so are the chain's modes above the first when lumping them costs more
        than simulate's rule allows at the smallest factor.

    Returns
    -------
    ReductionPlan
    """
    from ...sim import ModelOptions
    base = base or ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING)
    if not tolerance > 0:
        raise ValueError("tolerance must be positive")
    freqs = np.asarray(sorted(frequencies_hz), dtype=float)
    amps = tuple(float(a) for a in amplitudes)
    w = 2 * np.pi * freqs
    drive, motor = scene.drivetrain, scene.motor
    q0 = operating_point(scene)[0]  # where the simulation starts
    zeta = base.damping_ratio
    p = plant_parameters(scene, q0, structural_damping=zeta)
    ref = loop_response(p, controller, motor, w)
    t_full = ref["theta"]
    a_min, a_max = min(amps), max(amps)
    reach = a_max * max(1.0, float(np.max(np.abs(t_full))))
    lo_, hi = drive.stroke
    qs = np.linspace(max(lo_, q0 - reach), min(hi, q0 + reach), 41)
    effects, notes = [], []
    u = output_unit(scene)

    # limits in the linear prediction
    n0 = p.N
    i0 = (scene.load.hinge_moment + scene.load.hinge_stiffness * q0) / (p.torque_gain or 1.0)
    i_peak = np.abs(ref["i"]) * a_max + abs(i0)
    v_peak = np.abs(ref["u"]) * a_max + abs(motor.resistance * i0)
    limited = (i_peak > motor.current_limit) | (v_peak > motor.voltage_limit)
    over = max(float(np.max(i_peak)) / motor.current_limit, float(np.max(v_peak)) / motor.voltage_limit)
    effects.append(Effect("current and voltage limits", None,
                          f"linear prediction's peaks {i_peak.max():.3g} A of {motor.current_limit:.3g} A, "
                          f"{v_peak.max():.3g} V of {motor.voltage_limit:.3g} V", max(over - 1.0, 0.0),
                          reason="kept: the model always clamps the current and the voltage (no switch)"))
    if limited.any():
        notes.append(f"the linear loop predicts the current or voltage limit from {freqs[limited][0]:.3g} Hz "
                     f"at {u.text(a_max, 3)} (peak {i_peak.max():.3g} A, {v_peak.max():.3g} V): "
                     "linear estimates do not hold there")

    # armature inductance
    if motor.inductance > 0:
        e = _rel(loop_response(p, controller, motor, w, inductance=False)["theta"], t_full)
        tau_e = motor.inductance / motor.resistance
        wc = controller.current_kp / motor.inductance if controller.current_kp > 0 else math.nan
        effects.append(Effect("armature inductance", "inductance",
                              f"L/R = {tau_e * 1e3:.3g} ms, current loop {wc / 2 / math.pi:.4g} Hz vs study up to "
                              f"{freqs[-1]:.3g} Hz", e))

    # compliance: per stage and whole
    chain = drive.stiffness(qs)
    rigid_effect = None
    if chain.names and math.isfinite(p.K):
        shares = chain.shares
        for name, s in zip(chain.names, shares):
            smax = float(np.max(s))
            if smax < SHARE_THRESHOLD:
                k_new = p.K / (1 - smax)
                pv = replace(p, K=k_new, c=float(spring_damping(p.J1, p.J2, k_new, zeta)))
                e = _rel(loop_response(pv, controller, motor, w)["theta"], t_full)
                effects.append(Effect(f"compliance of {name}", "stiffness_scale",
                                      f"compliance share {smax:.2e} < {SHARE_THRESHOLD:g} over the motion", e,
                                      share=smax))
        e = _rel(loop_response(replace(p, J1=p.J1 + p.J2, J2=0.0, K=math.inf, c=0.0), controller, motor,
                               w)["theta"], t_full)
        rigid_effect = Effect("drivetrain compliance", "compliance",
                              f"resonance {p.resonance_hz:.3g} Hz vs study up to {freqs[-1]:.3g} Hz", e)

    # the chain's modes above the first (the two-mass reduction lumps them), by simulate's rule
    choice = None
    if base.chain != "two_mass" and math.isfinite(p.K) and has_upper_modes(drive.chain, q0):
        choice = choose_chain(scene, controller, q0, freqs, zeta, "the study's frequencies", tolerance / 2)
        effects.append(Effect("drivetrain modes above the first", "chain",
                              f"modes {', '.join(f'{m:.4g}' for m in choice.modes_hz)} Hz vs study up to "
                              f"{freqs[-1]:.3g} Hz (full chain against its two-mass reduction); "
                              f"{choice.steps_text()}", choice.cost))

    # backlash
    play = float(drive.backlash([q0])[0])
    if play > 0 and math.isfinite(p.K):
        jl = load_side_inertia(drive, q0)
        static = abs(scene.load.hinge_moment + scene.load.hinge_stiffness * q0)
        dyn_tf = np.abs((-jl * w**2 + 1j * w * scene.load.damping + scene.load.hinge_stiffness) * t_full)
        dynamic = float(np.max(dyn_tf)) * a_max
        lsb = scene.sensors.output_count(drive.output_is_linear)
        res = f", {play / lsb:.3g} {'scale' if drive.output_is_linear else 'encoder'} counts" if lsb else ""
        if dynamic < CONTACT_MARGIN * static:
            e = 0.0
            why = (f"lost motion {u.text(play, 3)}{res}; force through the compliance "
                   f"{static:.4g} {u.moment} static, at most {dynamic:.4g} {u.moment} dynamic: contact never opens")
        else:
            a_out = np.abs(t_full) * a_min
            e = float(np.max(play / a_out))
            why = (f"lost motion {u.text(play, 3)}{res} vs output amplitude down to "
                   f"{u.text(a_out.min(), 3)} (force reverses: {dynamic:.4g} {u.moment} dynamic, "
                   f"{static:.4g} static)")
        effects.append(Effect("backlash", "backlash", why, e))

    # friction that holds, node by node (the smooth model without it)
    fric = friction_effect(scene, controller, p, w, t_full, amps, base)
    if fric is not None:
        effects.append(Effect(FRICTION_EFFECT, "friction", fric[0], fric[1], parts=fric[2]))

    # inertia variation over the motion
    j, dj = drive.inertia(qs)
    j0 = float(drive.inertia([q0])[0][0])
    dj_eff = float(np.max(np.abs(j - j0)) + np.max(np.abs(dj)) * reach / 2)
    if dj_eff > 0:
        e = max(_rel(loop_response(replace(p, J1=p.J1 + s * dj_eff), controller, motor, w)["theta"], t_full)
                for s in (1, -1) if p.J1 + s * dj_eff > 0)
        effects.append(Effect("inertia variation", "variable_inertia",
                              f"J varies by {dj_eff / j0:.2%} over +-{u.text(reach, 3)} "
                              f"(incl. the velocity term)", e))

    # reported, no switch
    n, _ = drive.ratio(qs)
    dn = float(np.max(np.abs(np.abs(n) - n0)) / n0)
    e = max(_rel(loop_response(replace(p, N=n0 * (1 + s * dn)), controller, motor, w)["theta"], t_full)
            for s in (1, -1))
    effects.append(Effect("ratio variation", None, f"N varies by {dn:.3%} over +-{u.text(reach, 3)}",
                          e, reason="kept: the model tabulates N(q) at no cost (no switch)"))
    labels, masses, tt, _ = drive.jacobians([q0])
    shares = masses * tt[:, 0] ** 2 / j0
    small = [(lab, s) for lab, s in zip(labels, shares) if 0 < s < INERTIA_SHARE_THRESHOLD]
    if small:
        total = sum(s for _, s in small)
        e = _rel(loop_response(replace(p, J1=max(p.J1 - total * j0, 1e-12)), controller, motor, w)["theta"], t_full)
        effects.append(Effect("small inertias", None, ", ".join(f"{lab} {s:.1e}" for lab, s in small) +
                              " of J", e, reason="kept: they add no state (J(q) is one table), nothing to gain"))

    keep = {} if stiffness is None else varied_stiffness(stiffness, rigid_effect, choice, tolerance / 2)
    plan = choose(effects, rigid_effect, base, tolerance, limited.any(), freqs, amps, notes, choice, keep=keep)
    return replace(plan, output_unit=output_unit(scene).si)


def varied_stiffness(factors, rigid_effect, choice, budget: float) -> dict:
    """The effects a study varying the series stiffness by ``factors`` (its smallest and
    largest factor) keeps whatever their estimates (switch -> why, :func:`~.choice.choose`).

    The factor acts on the drivetrain compliance only: a model without it gives every factor
    the same figures, so the compliance is kept (``rigid_effect``, None for a rigid chain).
    The factor scales every spring of the chain, so the two-mass reduction of a scaled chain
    is the scaled reduction; what lumping costs grows as the modes above the first fall, with
    the square root of the factor. To first order in (study frequency / mode)^2 that cost
    grows with the inverse of the factor: the modes are kept when ``choice.cost`` over the
    smallest factor exceeds ``budget`` (simulate's rule for the nominal chain).
    """
    low, high = (float(min(factors)), float(max(factors)))
    keep = {}
    rng = f"{low:.4g}..{high:.4g} x nominal" if high > low else f"{low:.4g} x nominal"
    if rigid_effect is not None:
        keep[rigid_effect.switch] = f"the study varies the stiffness ({rng}), which acts on it alone"
    if choice is not None and choice.chain == "two_mass" and low < 1 and choice.cost / low > budget:
        keep["chain"] = (f"the study varies the stiffness ({rng}): lumping the modes costs ~{choice.cost / low:.2g} "
                         f"at {low:.4g} x nominal (the nominal {choice.cost:.2g} over the factor: the modes fall "
                         f"with its square root), more than {budget:g}")
    return keep


def friction_cost_note(scene, controller, frequencies_hz, amplitudes, options,
                       tolerance: float = DEFAULT_TOLERANCE) -> str | None:
    """The note of a study that runs without friction that holds (``options.friction`` other
    than ``"stick"``): each node's friction smoothed or left out, with its estimate
    (:func:`~.friction.judge_nodes`), and whether their sum exceeds half the tolerance;
    None when the model holds or the scene has no Coulomb or static friction."""
    from .friction import friction_note, judge_nodes
    if options.friction == "stick":
        return None
    q0 = operating_point(scene)[0]
    p = plant_parameters(scene, q0, structural_damping=options.damping_ratio)
    w = 2 * np.pi * np.asarray(sorted(frequencies_hz), dtype=float)
    t_full = loop_response(p, controller, scene.motor, w)["theta"]
    nodes = judge_nodes(scene, controller, p, w, t_full, [float(a) for a in amplitudes], options)
    if not nodes:
        return None
    total = sum(x.estimate for x in nodes)
    verdict = (f"within the budget {tolerance / 2:g}" if total <= tolerance / 2 else
               f"over the budget {tolerance / 2:g}: the study's figures do not hold where friction decides them "
               "(ModelOptions(friction=\"stick\") runs friction that holds)")
    if options.friction == "off":
        return (f"friction left out (friction model 'off'), estimates: "
                + ", ".join(f"{x.label} {x.estimate:.2g}" for x in nodes) + f"; sum {total:.2g} {verdict}")
    return f"{friction_note(nodes, True)}; sum {total:.2g} {verdict}"
