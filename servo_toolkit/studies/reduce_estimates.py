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
  (:func:`servo_toolkit.plant.chain_plant.chain_plant`); left out, the run uses the two-mass
  reduction;
- backlash of total lost motion b at the output: zero when the force through the
  compliance never reverses (the static load keeps the contact closed: the dynamic force
  amplitude, from the linear loop, stays below 80 % of the static one); otherwise the
  describing-function bound b / A_out (the backlash describing function deviates from 1 by
  about (2 / pi) b / A for b << A);
- inertia variation over the motion: loop with the motor-side inertia changed by
  max |J(q) - J(q0)| + max |dJ/dq| A / 2 (the velocity term J' q'^2 / 2 acts like an inertia
  error of J' A / 2);
- static friction (stick), where the full model has it (``friction="stick"``): the loop's
  response to the whole friction as a relay at its breakaway levels, through the response to
  a torque at the output (an upper estimate, :mod:`.reduce_friction`); left out, the run uses
  the smooth model;
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
import warnings
from dataclasses import dataclass, replace

import control as ct
import numpy as np

from ..drivetrain.operating_point import operating_point
from ..core.output_units import OutputUnit, output_unit
from ..plant.linear import (DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS, current_controller, plant_matrices,
                            plant_parameters, sample_delay, spring_damping)
from .reduce_friction import friction_effect, without_stick

#: compliance share below which a stage's compliance is negligible (seed 001)
SHARE_THRESHOLD = 1e-3
#: inertia share below which an element is called small
INERTIA_SHARE_THRESHOLD = 1e-3
#: default tolerance on the relative response difference (0.17 dB / 1.15 deg)
DEFAULT_TOLERANCE = 0.02
#: backlash has no effect while the dynamic force stays below this fraction of the static one
CONTACT_MARGIN = 0.8


@dataclass(frozen=True)
class Effect:
    """One effect of the model judged against a study.

    Attributes
    ----------
    effect : str
        What it is (``"armature inductance"``, ``"compliance of <stage>"``, ...).
    switch : str or None
        The :class:`~servo_toolkit.sim.ModelOptions` field leaving it out (None: no switch).
    quantity : str
        The numbers compared, in words.
    estimate : float
        A-priori relative response error if left out (see the module docstring).
    omitted : bool
    reason : str
    """

    effect: str
    switch: str | None
    quantity: str
    estimate: float
    omitted: bool = False
    reason: str = ""

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"effect": self.effect, "switch": self.switch, "quantity": self.quantity,
                "estimate_relative": self.estimate, "estimate_dB": _db(self.estimate),
                "estimate_deg": _deg(self.estimate), "left_out": self.omitted, "reason": self.reason}


@dataclass(frozen=True)
class ReductionPlan:
    """The a-priori part of a reduction: effects, the reduced options and the bound.

    Attributes
    ----------
    effects : tuple of Effect
    options : ModelOptions
        The reduced model's options.
    tolerance : float
        A-priori bound on the relative full/reduced response difference.
    predicted : float
        Sum of the estimates of the effects left out (<= tolerance / 2).
    frequencies_hz : numpy.ndarray
    amplitudes_rad : tuple
        Command amplitudes in SI (rad, or m for an output travel; see ``output_unit``).
    notes : tuple of str
    output_unit : {"rad", "m"}
    """

    effects: tuple
    options: object
    tolerance: float
    predicted: float
    frequencies_hz: np.ndarray
    amplitudes_rad: tuple
    notes: tuple = ()
    output_unit: str = "rad"

    @property
    def omitted(self) -> tuple:
        """The effects left out."""
        return tuple(e for e in self.effects if e.omitted)

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"effects": [e.to_dict() for e in self.effects],
                "left_out": [e.effect for e in self.omitted],
                "tolerance_relative": self.tolerance, "tolerance_dB": _db(self.tolerance),
                "tolerance_deg": _deg(self.tolerance), "predicted_relative": self.predicted,
                "frequencies_hz": self.frequencies_hz.tolist(),
                OutputUnit(self.output_unit).key("amplitudes"):
                    [float(OutputUnit(self.output_unit).show(a)) for a in self.amplitudes_rad],
                "notes": list(self.notes)}


def _db(e):
    return 20 * math.log10(1 + e) if math.isfinite(e) else math.inf


def _deg(e):
    return math.degrees(math.asin(min(e, 1.0))) if math.isfinite(e) else math.inf


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
    if plant_ss is None:
        a, b, c, d, states = plant_matrices(p, inductance)
        g = ct.ss(a, b, c, d, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states, name="plant")
    else:
        g = plant_ss
    mot = motor if inductance else replace(motor, inductance=0.0)
    cur = current_controller(controller.current_kp, controller.current_ki, mot)
    from ..loop.closed_loop import DELAY_SAMPLES
    dly = sample_delay(controller.sample_time, DELAY_SAMPLES)
    outs = ["theta", "i", "u", "omega"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cl = ct.interconnect([g, cur, dly, controller.motion], inplist=["theta_ref"], outlist=outs,
                             inputs=["theta_ref"], outputs=outs, check_unused=False)
    resp = np.asarray(ct.frequency_response(cl, w).complex).reshape(len(outs), -1)
    out = {k: resp[j] for j, k in enumerate(outs)}
    out["stable"] = bool(np.all(np.real(cl.poles()) < 0))
    return out


def _rel(t_var, t_ref):
    return float(np.max(np.abs(t_var / t_ref - 1.0)))


def _load_side_inertia(drive, q0):
    """Inertia turning with the output itself (the simulation model's load side)."""
    labels, masses, t, t2 = drive.jacobians([q0])
    keep = [(lab != "motor rotor" and abs(ti[0] - 1) < 1e-12 and abs(t2i[0]) < 1e-12)
            for lab, ti, t2i in zip(labels, t, t2)]
    return float(np.sum(masses[keep]))


def plan_reduction(scene, controller, frequencies_hz, amplitudes, *, base=None,
                   tolerance: float = DEFAULT_TOLERANCE) -> ReductionPlan:
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

    Returns
    -------
    ReductionPlan
    """
    from ..sim import ModelOptions
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
                                      f"compliance share {smax:.2e} < {SHARE_THRESHOLD:g} over the motion", e))
        e = _rel(loop_response(replace(p, J1=p.J1 + p.J2, J2=0.0, K=math.inf, c=0.0), controller, motor,
                               w)["theta"], t_full)
        rigid_effect = Effect("drivetrain compliance", "compliance",
                              f"resonance {p.resonance_hz:.3g} Hz vs study up to {freqs[-1]:.3g} Hz", e)

    # the chain's modes above the first (the two-mass reduction lumps them)
    if base.chain != "two_mass" and math.isfinite(p.K) and drive.chain.condensed(q0)[2].size > 2:
        from ..plant.chain_plant import chain_plant
        modes = drive.chain.eigenfrequencies(q0, driving=True)[1:] / (2 * math.pi)
        t_chain = loop_response(p, controller, motor, w, plant_ss=chain_plant(scene, q0, structural_damping=zeta))
        effects.append(Effect("drivetrain modes above the first", "chain",
                              f"modes {', '.join(f'{m:.4g}' for m in modes)} Hz vs study up to {freqs[-1]:.3g} Hz "
                              "(full chain against its two-mass reduction)", _rel(t_full, t_chain["theta"])))

    # backlash
    play = float(drive.backlash([q0])[0])
    if play > 0 and math.isfinite(p.K):
        jl = _load_side_inertia(drive, q0)
        static = abs(scene.load.hinge_moment + scene.load.hinge_stiffness * q0)
        dyn_tf = np.abs((-jl * w**2 + 1j * w * scene.load.damping + scene.load.hinge_stiffness) * t_full)
        dynamic = float(np.max(dyn_tf)) * a_max
        lsb = 2 * math.pi / 2**scene.sensors.output_encoder_bits if scene.sensors.output_encoder_bits else 0.0
        res = f", {play / lsb:.3g} encoder counts" if lsb else ""
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

    # friction that holds (the smooth model without it)
    fric = friction_effect(scene, controller, p, w, t_full, amps, base)
    if fric is not None:
        effects.append(Effect("static friction (stick)", "friction", *fric))

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

    plan = _choose(effects, rigid_effect, base, tolerance, limited.any(), chain, freqs, amps, notes)
    return replace(plan, output_unit=output_unit(scene).si)


def _choose(effects, rigid_effect, base, tol, limited, chain, freqs, amps, notes):
    budget = tol / 2
    used = 0.0
    chosen = set()
    by_switch = [e for e in effects if e.switch is not None]
    backlash = [e for e in by_switch if e.switch == "backlash"]
    if rigid_effect is not None:
        bl = backlash[0].estimate if backlash else 0.0
        if rigid_effect.estimate + bl <= budget:
            chosen.add(rigid_effect.effect)
            used += rigid_effect.estimate + bl
    for e in sorted(by_switch, key=lambda x: x.estimate):
        if rigid_effect is not None and rigid_effect.effect in chosen and e.switch in ("backlash", "stiffness_scale",
                                                                                         "chain"):
            continue
        if e.switch == "inductance" and limited:
            continue
        if used + e.estimate <= budget:
            chosen.add(e.effect)
            used += e.estimate
    out = []
    for e in effects + ([rigid_effect] if rigid_effect is not None else []):
        if e.switch is None:
            out.append(e)
        elif e.effect in chosen:
            out.append(replace(e, omitted=True, reason=f"left out: {e.estimate:.2g} within the budget "
                                                       f"(sum of omissions <= {budget:.2g})"))
        elif rigid_effect is not None and rigid_effect.effect in chosen and e.switch in ("backlash", "stiffness_scale",
                                                                                           "chain"):
            out.append(replace(e, omitted=True, reason="left out with the whole compliance"))
        elif e.switch == "inductance" and limited:
            out.append(replace(e, reason="kept: limits reached, where the inductive voltage matters"))
        else:
            out.append(replace(e, reason=f"kept: {e.estimate:.2g} exceeds the remaining budget "
                                         f"{max(budget - used, 0):.2g}"))
    omitted = {e.switch for e in out if e.omitted}
    opts = base
    if "chain" in omitted:
        opts = replace(opts, chain="two_mass")
    elif any(e.switch == "chain" for e in out):
        opts = replace(opts, chain="full")  # kept: every mode, whatever "auto" would choose
    if "compliance" in omitted:
        opts = replace(opts, compliance=False)
    else:
        if "backlash" in omitted:
            opts = replace(opts, backlash=False)
        stage_shares = [float(np.max(s)) for name, s in zip(chain.names, chain.shares)
                        if f"compliance of {name}" in chosen]
        if stage_shares:
            opts = replace(opts, stiffness_scale=opts.stiffness_scale / (1 - sum(stage_shares)))
    if "inductance" in omitted:
        opts = replace(opts, inductance=False)
    if "variable_inertia" in omitted:
        opts = replace(opts, variable_inertia=False)
    if "friction" in omitted:
        opts = without_stick(opts)
    return ReductionPlan(effects=tuple(out), options=opts, tolerance=tol, predicted=used,
                         frequencies_hz=freqs, amplitudes_rad=amps, notes=tuple(notes))
