"""The compiled model of the full drivetrain chain, and the choice between it and the two-mass
reduction.

The full chain keeps every node of :class:`~servo_toolkit.drivetrain.chain.Chain` that has
inertia (nodes without inertia are condensed: the springs on either side act in series,
their plays add up): the motor side p (node 0), the intermediate nodes (states after the
controller's in x) and the load q. Every node's inertia J_j(p) and its derivative are
tabulated along the stroke at the motor-side position (the motor node's is the chain's total
less the others'), so the velocity terms of Lagrange's equations keep the undamped chain's
energy; each segment between two kept nodes has its stiffness tabulated along the stroke at
p, its own play and its own damper, beta_s times its stiffness, with beta_s from the damping
ratio of the mode it dominates (:mod:`servo_toolkit.drivetrain.chain_damping`, as
:func:`servo_toolkit.plant.chain_plant.chain_plant` has it). The losses sit where the chain
has them: node j's inertia before the losses J_w,j(p) (tabulated like J_j) and segment s's
loss fraction l_s = (1 - eta / Pi_s) / (1 - eta), scaled in the kernel by one loss
coefficient c for the whole chain (:func:`servo_toolkit.sim.kernel.chain_accelerations`):
driving, the model is the chain's driving-mode form and its Jacobian is the chain plant's.
A stage's friction acts at its node: an intermediate node carries the friction of the stages
whose output members it holds (:mod:`.node_friction`: reflected to the node's coordinate,
sliding with the motor's law, sticking by its own breakaway level), the motor side and the
load theirs and those of stages on condensed nodes (lumped by the two-mass split's rule,
:mod:`servo_toolkit.drivetrain.stage_friction`); the notes say which sits where.

Which one a run uses (``ModelOptions.chain``): ``"full"``, ``"two_mass"``, or ``"auto"``,
decided by :func:`~servo_toolkit.sim.chain_choice.choose_chain` (the cost of lumping the upper
modes at the scene's working frequencies against the RK4 step the reduction gains), the
choice and its figures in the model's notes. ``servo-toolkit reduce`` measures what lumping
them costs.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline

from ..drivetrain.chain_damping import chain_damping, kept_nodes, segment_stiffness, segments
from ..errors import SceneError
from . import layout as lo
from .chain_choice import choose_chain, has_upper_modes, working_frequencies

CHAIN_CHOICES = ("auto", "full", "two_mass")


def resolve(scene, controller, options, q0: float, notes: list) -> str:
    """``"full"`` or ``"two_mass"`` for ``options.chain``: ``"auto"`` decided by
    :func:`~servo_toolkit.sim.chain_choice.choose_chain` at the scene's working frequencies
    (the requirement sine, the required bandwidth, the loop's crossover, the scene's study
    frequencies), and said in ``notes``. A chain a study chose for its run carries that
    choice (``options.chain_note``, the study's note of it): the lumping is not noted again."""
    chain = scene.drivetrain.chain
    if not has_upper_modes(chain, q0):
        return "two_mass"  # one compliance: the two-mass model is the chain
    if options.chain != "auto":
        if options.chain == "two_mass" and not options.chain_note:  # a study that chose it has noted it
            modes = chain.eigenfrequencies(q0, driving=True)[1:] / (2 * math.pi)
            notes.append(f"drivetrain modes {_hz(modes)} lumped into the two-mass reduction (chain='two_mass')")
        return options.chain
    freqs, what = working_frequencies(scene, controller)
    choice = choose_chain(scene, controller, q0, freqs, options.damping_ratio, what)
    notes.append(choice.note)
    return choice.chain


def _hz(values) -> str:
    return ", ".join(f"{v:.4g}" for v in values) + " Hz"


def segment_plays(drive, segs, q0: float, options) -> np.ndarray:
    """Total play of each segment at the output (rad or m): each lash reflected to q0 and
    placed in the segment holding its compliance (a lash in a rigid stage: the next segment
    beyond it, else the last)."""
    chain = drive.chain
    plays = np.zeros(len(segs))
    if not options.backlash:
        return plays
    kin = drive.kinematics([q0])
    for lash, jet in zip(chain.lashes, kin.lashes):
        size = float(lash.lash / abs(jet.u.d1[0]))
        if lash.spring is not None:
            spring = lash.spring
        else:
            later = [i for i, s in enumerate(chain.springs) if s.stage > lash.stage]
            spring = later[0] if later else len(chain.springs) - 1
        seg = next(i for i, (a, b) in enumerate(segs) if a <= spring < b)
        plays[seg] += size
    if options.play is not None:
        total = plays.sum()
        plays = plays * (options.play / total) if total > 0 else np.r_[options.play, np.zeros(len(segs) - 1)]
    return plays


def held_inertia_error(drive, q, j_row) -> SceneError:
    """The error of a model whose motor side would get a negative inertia somewhere along the
    stroke: the load side is held at its q0 inertia and the chain's variation along the
    stroke goes to the motor side (``j_row``), so a member whose inertia at the output varies
    by more than the motor side has cannot be modelled. It names the stage of the member
    that varies most (e.g. a nut of 1e4 kg behind a rocker)."""
    chain = drive.chain
    elem = chain.element_inertias(q)
    k = max(range(len(chain.elements)), key=lambda i: float(np.ptp(elem[i])))
    e = chain.elements[k]
    n_stages = len(drive.stages)
    key = f"drivetrain[{e.stage}]" if 0 <= e.stage < n_stages else ("load.inertia" if e.stage >= n_stages else "motor")
    unit = "kg" if getattr(drive, "output_is_linear", False) else "kg*m^2"
    return SceneError(key, f"the {e.label}'s inertia at the output varies by {np.ptp(elem[k]):.3g} {unit} along "
                           "the stroke; the model holds a load-side member's inertia at its q0 value and moves the "
                           f"variation to the motor side, which it leaves at {np.min(j_row):.3g} {unit}, not a "
                           "positive inertia: a member this heavy for its place in the chain is outside what the "
                           "model is conditioned for")


def chain_model(drive, q, q0: float, options, j_tot, dj_tot, zeta: float):
    """Tables and parameters of the full chain.

    Parameters
    ----------
    drive : Drivetrain
    q : numpy.ndarray
        The stroke grid of the tables.
    q0 : float
        Operating point (nodes, segments and dampers are those at q0).
    options : ModelOptions
    j_tot, dj_tot : numpy.ndarray
        The chain's total inertia along q and its derivative (constant without
        ``options.variable_inertia``).
    zeta : float
        Damping ratio of each compliance whose stage gives none.

    Returns
    -------
    dict
        ``j_row``, ``dj_row`` (the motor node's inertia along p and its derivative: the total
        less every other node's), ``k_rows`` (segment stiffness, values and derivatives,
        shape (2 n_seg, n_q)), ``node_rows`` (the motor node's J_w, dJ_w/dp, then per further
        node J_j, dJ_j/dp, J_w,j, dJ_w,j/dp), ``block`` (the segment block of P, SEG_STRIDE
        per segment), ``half_play`` (segment 0's), ``j_load`` (the load node at q0),
        ``j_motor0`` (the motor node at q0), ``k_series0`` (every segment in series at q0),
        ``damping`` (:class:`~servo_toolkit.drivetrain.chain_damping.ChainDamping`),
        ``load_side`` (names), ``nodes`` (kept node indices), ``jw_motor`` (node 0's inertia
        before the losses at q0), ``variation`` (each further node's relative variation of
        inertia along the stroke).
    """
    chain = drive.chain
    segs = segments(chain, q0)
    keep = kept_nodes(chain, q0)
    beyond = list(keep[1:])
    fractions = chain.loss_fractions()
    grid = q if options.variable_inertia else np.array([q0])
    jn, djn = chain.node_jets(grid)
    jw, djw = chain.node_jets(grid, fractions)
    if not options.variable_inertia:
        jn, jw = (np.repeat(a, q.size, axis=1) for a in (jn, jw))
        djn, djw = np.zeros_like(jn), np.zeros_like(jw)
    j_row = j_tot - jn[beyond].sum(axis=0)
    dj_row = dj_tot - djn[beyond].sum(axis=0)
    if np.any(j_row <= 0) or np.any(jn[beyond] <= 0):
        raise SceneError("drivetrain", "a node of the drivetrain chain has no positive inertia along the stroke "
                         "(its inertia is tabulated along the stroke)")
    k_seg = segment_stiffness(chain, q, segs)
    k_rows = np.vstack([np.vstack([k, CubicSpline(q, k)(q, 1)]) for k in k_seg])
    node_rows = np.vstack([jw[0], djw[0]] + [np.vstack([jn[j], djn[j], jw[j], djw[j]]) for j in beyond])
    eta = chain.efficiency
    pi_s = chain.spring_losses()
    frac_s = [(1.0 - eta / pi_s[a]) / (1.0 - eta) if eta < 1.0 else 0.0 for a, _ in segs]
    plays = segment_plays(drive, segs, q0, options)
    damping = chain_damping(chain, q0, zeta, stiffness_scale=options.stiffness_scale)
    block = np.zeros(lo.SEG_STRIDE * len(segs))
    for s in range(len(segs)):
        block[lo.SEG_STRIDE * s + lo.SEG_PLAY] = 0.5 * plays[s]
        block[lo.SEG_STRIDE * s + lo.SEG_LOSS] = frac_s[s]
        block[lo.SEG_STRIDE * s + lo.SEG_BETA] = damping.beta[s]
    k0 = np.array([np.interp(q0, q, k) for k in k_seg])
    at_q0 = chain.node_jets([q0])[0][:, 0]
    last = keep[-1]
    lo_s, hi_s = drive.stroke
    inside = (q >= lo_s) & (q <= hi_s)
    variation = {int(j): float(np.ptp(jn[j][inside]) / at_q0[j]) for j in beyond}
    return {"j_row": j_row, "dj_row": dj_row, "k_rows": k_rows, "node_rows": node_rows, "block": block,
            "half_play": 0.5 * plays[0], "j_load": float(at_q0[last]), "j_motor0": float(np.interp(q0, q, j_row)),
            "k_series0": float(1.0 / np.sum(1.0 / k0)), "damping": damping,
            "load_side": tuple(e.label for e in chain.elements if e.node == last),
            "nodes": tuple(int(n) for n in keep), "jw_motor": float(chain.node_jets([q0], fractions)[0][0, 0]),
            "variation": variation}


def chain_damping_facts(damping) -> dict:
    """The full chain's dampers as plain numbers (:attr:`servo_toolkit.sim.model.Model.damping`)."""
    return {"segment_ratios": [float(z) for z in damping.ratios], "beta_s": [float(b) for b in damping.beta],
            "modes_hz": [float(w / (2 * math.pi)) for w in damping.frequencies],
            "mode_ratios": [float(z) for z in damping.modal_ratios]}


def damping_note(damping) -> str:
    """The full chain's structural damping in words: each segment's ratio, each mode's."""
    ratios = ", ".join(f"{z:.3g}" for z in damping.ratios)
    modes = ", ".join(f"{z:.3g} at {w / (2 * math.pi):.4g} Hz" for z, w in zip(damping.modal_ratios,
                                                                             damping.frequencies))
    return (f"a damper on each compliance (damping ratios {ratios} in the modes they dominate): modal damping "
            f"ratios {modes}")


def chain_state_names(nodes) -> list[str]:
    """Names of the intermediate nodes' states."""
    return [name for n in nodes[1:-1] for name in (f"node[{n}]_position", f"node[{n}]_rate")]


__all__ = ["CHAIN_CHOICES", "chain_damping_facts", "chain_model", "chain_state_names", "damping_note", "kept_nodes",
           "resolve", "segment_plays", "segment_stiffness", "segments"]
