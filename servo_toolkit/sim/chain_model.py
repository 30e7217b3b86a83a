"""The compiled model of the full drivetrain chain, and the choice between it and the two-mass
reduction.

The full chain keeps every node of :class:`~servo_toolkit.drivetrain.chain.Chain` that has
inertia (nodes without inertia are condensed: the springs on either side act in series,
their plays add up): the motor side p (node 0), the intermediate nodes (states after the
controller's in x) and the load q. Each segment between two kept nodes has its stiffness
tabulated along the stroke at p, its own play, and the chain's stiffness-proportional damping
``beta = 2 zeta / w_1`` (w_1 the lowest mode, as :func:`servo_toolkit.plant.chain_plant.chain_plant`
has it). Intermediate and load inertias are held at their q0 values; the variation of the
chain's inertia along the stroke goes to the motor side, as in the two-mass model. The losses
sit where the chain has them: node j's inertia before the losses J_w,j and segment s's loss
fraction l_s = (1 - eta / Pi_s) / (1 - eta), scaled in the kernel by one loss coefficient c
for the whole chain (:func:`servo_toolkit.sim.kernel.chain_accelerations`): driving, the model
is the chain's driving-mode form and its Jacobian is the chain plant's.

Which one a run uses (``ModelOptions.chain``): ``"full"``, ``"two_mass"``, or ``"auto"``, the
full chain when its second mode lies within :data:`MODE_FACTOR` times the frequencies the scene
works at (the loop's crossover, the required bandwidth, the 8 Hz requirement sine), else the
two-mass reduction with the left-out modes named in the model's notes. ``servo-toolkit reduce``
measures what lumping them costs.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline

from ..core.output_units import REQUIREMENT_SINE_HZ
from ..errors import SceneError
from . import layout as lo

#: modes above this multiple of the scene's working frequencies are lumped by "auto"
MODE_FACTOR = 10.0
CHAIN_CHOICES = ("auto", "full", "two_mass")


def working_frequency(scene, controller=None) -> tuple[float, str]:
    """The highest frequency (Hz) the scene works at and what it is: the loop's gain
    crossover (with a controller), the required bandwidth, the requirement sine."""
    best, what = REQUIREMENT_SINE_HZ, f"the {REQUIREMENT_SINE_HZ:g} Hz requirement sine"
    bw = scene.requirements.bandwidth if scene.requirements is not None else None
    if bw is not None and bw > best:
        best, what = bw, "the required bandwidth"
    if controller is not None:
        fc = crossover_hz(scene, controller)
        if math.isfinite(fc) and fc > best:
            best, what = fc, "the loop's crossover"
    return best, what


def crossover_hz(scene, controller) -> float:
    """Highest 0 dB crossing of the loop broken at the position error (two-mass plant)."""
    import warnings

    import control as ct

    from ..loop.closed_loop import open_loop
    f = np.logspace(-1, 4, 400)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mag = np.abs(ct.frequency_response(open_loop(scene, controller, model="two_mass"),
                                               2 * np.pi * f).complex).ravel()
    except (ValueError, np.linalg.LinAlgError, SceneError):
        return math.nan
    above = np.flatnonzero(mag >= 1.0)
    return float(f[above[-1]]) if above.size else math.nan


def kept_nodes(chain, q0: float) -> np.ndarray:
    """The chain's nodes with inertia at q0 (the others are condensed)."""
    return chain.condensed(q0)[2]


def resolve(scene, controller, options, q0: float, notes: list) -> str:
    """``"full"`` or ``"two_mass"`` for ``options.chain`` (``"auto"`` decided here, and said)."""
    chain = scene.drivetrain.chain
    if chain.rigid or kept_nodes(chain, q0).size <= 2:
        return "two_mass"  # one compliance: the two-mass model is the chain
    modes = chain.eigenfrequencies(q0, driving=True) / (2 * math.pi)
    if options.chain != "auto":
        if options.chain == "two_mass":
            notes.append(f"drivetrain modes {_hz(modes[1:])} lumped into the two-mass reduction (chain='two_mass')")
        return options.chain
    f_work, what = working_frequency(scene, controller)
    if modes[1] <= MODE_FACTOR * f_work:
        notes.append(f"full drivetrain chain: its second mode {modes[1]:.4g} Hz lies within {MODE_FACTOR:g}x "
                     f"{what} ({f_work:.3g} Hz)")
        return "full"
    notes.append(f"drivetrain modes {_hz(modes[1:])} lumped into the two-mass reduction: above {MODE_FACTOR:g}x "
                 f"{what} ({f_work:.3g} Hz); chain='full' keeps them, `servo-toolkit reduce` measures the cost")
    return "two_mass"


def _hz(values) -> str:
    return ", ".join(f"{v:.4g}" for v in values) + " Hz"


def segments(chain, q0: float) -> list[tuple[int, int]]:
    """(first, last) node of each segment between consecutive kept nodes; segment s holds the
    chain's springs first .. last - 1."""
    keep = kept_nodes(chain, q0)
    return [(int(a), int(b)) for a, b in zip(keep[:-1], keep[1:])]


def segment_stiffness(chain, q, segs) -> np.ndarray:
    """Series stiffness of each segment along q, shape (n_segments, n_q)."""
    k = chain.spring_stiffness(q)
    return np.array([1.0 / np.sum(1.0 / k[a:b], axis=0) for a, b in segs])


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


def chain_model(drive, q, q0: float, options, j_tot, zeta: float):
    """Tables and parameters of the full chain.

    Returns
    -------
    dict
        ``j_row`` (the motor side's inertia along q), ``k_rows`` (segment stiffness, values and
        derivatives, shape (2 n_seg, n_q)), ``block`` (the segment block of P, SEG_STRIDE per
        segment), ``half_play`` (segment 0's), ``j_load``, ``j_motor0`` (the motor side at
        q0), ``k_series0`` (every segment in series at q0), ``beta``, ``load_side`` (names),
        ``nodes`` (kept node indices), ``jw_motor`` (node 0's inertia before the losses).
    """
    chain = drive.chain
    segs = segments(chain, q0)
    keep = kept_nodes(chain, q0)
    nodes0 = chain.node_inertias([q0])[:, 0]
    held = nodes0[keep[1:]]
    j_row = j_tot - held.sum()
    if np.any(j_row <= 0):
        raise held_inertia_error(drive, q, j_row)
    k_seg = segment_stiffness(chain, q, segs)
    k_rows = np.vstack([np.vstack([k, CubicSpline(q, k)(q, 1)]) for k in k_seg])
    eta = chain.efficiency
    elem_j = chain.element_inertias([q0])[:, 0]
    frac_e = np.array([(1.0 - eta / e.loss) / (1.0 - eta) if eta < 1.0 else 0.0 for e in chain.elements])
    jw_node = np.zeros(chain.n_nodes)
    for e, j, fr in zip(chain.elements, elem_j, frac_e):
        jw_node[e.node] += j * fr
    pi_s = chain.spring_losses()
    frac_s = [(1.0 - eta / pi_s[a]) / (1.0 - eta) if eta < 1.0 else 0.0 for a, _ in segs]
    plays = segment_plays(drive, segs, q0, options)
    block = np.zeros(lo.SEG_STRIDE * len(segs))
    for s, (a, b) in enumerate(segs):
        block[lo.SEG_STRIDE * s + lo.SEG_PLAY] = 0.5 * plays[s]
        block[lo.SEG_STRIDE * s + lo.SEG_LOSS] = frac_s[s]
        block[lo.SEG_STRIDE * s + lo.SEG_J] = nodes0[b]
        block[lo.SEG_STRIDE * s + lo.SEG_JW] = jw_node[b]
    w1 = float(chain.eigenfrequencies(q0, driving=True)[0]) * math.sqrt(options.stiffness_scale)
    k0 = np.array([np.interp(q0, q, k) for k in k_seg])
    last = keep[-1]
    return {"j_row": j_row, "k_rows": k_rows, "block": block, "half_play": 0.5 * plays[0],
            "j_load": float(nodes0[last]), "j_motor0": float(np.interp(q0, q, j_row)),
            "k_series0": float(1.0 / np.sum(1.0 / k0)), "beta": 2.0 * zeta / w1,
            "load_side": tuple(e.label for e in chain.elements if e.node == last),
            "nodes": tuple(int(n) for n in keep), "jw_motor": float(jw_node[0])}


def chain_state_names(nodes) -> list[str]:
    """Names of the intermediate nodes' states."""
    return [name for n in nodes[1:-1] for name in (f"node[{n}]_position", f"node[{n}]_rate")]


__all__ = ["CHAIN_CHOICES", "MODE_FACTOR", "chain_model", "chain_state_names", "crossover_hz", "resolve",
           "segment_plays", "segment_stiffness", "segments", "working_frequency"]
