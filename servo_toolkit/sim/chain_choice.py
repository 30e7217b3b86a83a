"""Keep the drivetrain chain's modes above the first, or lump them: the one rule of
``simulate`` (``ModelOptions.chain="auto"``) and of the time runs and reductions of
:mod:`servo_toolkit.studies`.

The two-mass reduction keeps the chain's lowest mode and lumps the others. Lumping them
*costs* the change of the linear loop's response at the frequencies the run works at: the
relative difference ``max_f |T_two_mass(j w) / T_chain(j w) - 1|`` of the closed loop
theta/theta_ref (open loop: of the plant's output speed per volt), the two-mass plant against
the chain plant (:func:`servo_toolkit.plant.linear.plant`, ``model="chain"``). Keeping them
costs run time: fewer states per step for the reduction, and often a larger RK4 step (the
stability limit of the fastest eigenvalue of each linear model: the plant with its current
loop closed, as the compiled model integrates it; a sampled controller's step is at most its
sample time).

The rule: the chain is lumped when the cost is within :data:`LUMP_TOLERANCE` (the reduction
is then as good for the run, and never slower); it is kept otherwise, at its own step. The
note says which, with both steps and the cost.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..core.output_units import REQUIREMENT_SINE_HZ
from ..drivetrain.chain_damping import kept_nodes
from ..errors import SceneError
from .stability import max_stable_dt

#: the largest estimated cost (relative response difference) of lumping the upper modes:
#: half the reductions' default tolerance (:data:`servo_toolkit.studies.reduce.estimates.DEFAULT_TOLERANCE`)
LUMP_TOLERANCE = 0.01


@dataclass(frozen=True)
class ChainChoice:
    """Whether a run keeps the chain's upper modes.

    Attributes
    ----------
    chain : {"full", "two_mass"}
    modes_hz : tuple of float
        The chain's modes above the first (Hz), those the reduction lumps.
    cost : float
        Estimated relative response difference of lumping them, at ``frequencies_hz``.
    dt_full, dt_reduced : float
        The RK4 step (s) each model allows: the stability limit of its fastest eigenvalue,
        at most the controller's sample time.
    frequencies_hz : tuple of float
        The frequencies the cost is taken at.
    note : str
    limit_full, limit_reduced : float
        Each model's stability limit (s) alone, above the sample time where that caps the step.
    sample_time : float
        The controller's sample time (s; 0 without a sampled controller).
    """

    chain: str
    modes_hz: tuple
    cost: float
    dt_full: float
    dt_reduced: float
    frequencies_hz: tuple
    note: str
    limit_full: float = math.nan
    limit_reduced: float = math.nan
    sample_time: float = 0.0

    def steps_text(self) -> str:
        """The two models' RK4 steps in words: each step, and where the sample time caps
        both, that it is the same for both with each stability limit above it."""
        return steps_text(self.dt_reduced, self.dt_full, self.limit_reduced, self.limit_full, self.sample_time)


def steps_text(dt_reduced: float, dt_full: float, limit_reduced: float, limit_full: float,
               sample_time: float) -> str:
    """``"RK4 step 0.0002 s, the sample time, for both (stability limits 0.00031 s two-mass,
    0.00024 s full chain)"`` when the sample time caps both steps, else ``"RK4 step limit A s
    for the two-mass reduction against B s for the full chain"`` with the digits that tell them
    apart."""
    capped = sample_time > 0 and dt_reduced == dt_full == sample_time
    if capped:
        return (f"RK4 step {sample_time:.3g} s, the sample time, for both models (stability limits "
                f"{limit_reduced:.3g} s two-mass, {limit_full:.3g} s full chain)")
    digits = 3
    while f"{dt_reduced:.{digits}g}" == f"{dt_full:.{digits}g}" and digits < 12:
        digits += 1

    def one(dt):
        return f"{dt:.{digits}g} s" + (" (the sample time)" if sample_time > 0 and dt == sample_time else "")
    return f"RK4 step limit {one(dt_reduced)} for the two-mass reduction against {one(dt_full)} for the full chain"


def has_upper_modes(chain, q0: float) -> bool:
    """True when the chain has more than one mode (three or more nodes with inertia)."""
    return not chain.rigid and kept_nodes(chain, q0).size > 2


def study_frequencies(scene) -> list[float]:
    """The frequencies (Hz) of the scene's time-run studies (the kinds whose runs a model
    built for the scene serves, :attr:`~servo_toolkit.scene.study_kind.StudyKind.time_run`; a
    frequency sweep reduces its own model at its own frequencies by the same rule): a sine's
    frequency (or 1 / period), the frequencies a study lists."""
    from ..scene.study_kind import study_kinds
    kinds = study_kinds()
    out = []
    for study in scene.studies.values():
        if not kinds[study.kind].time_run:
            continue
        p = study.params
        sweep = p.get("frequencies", [])
        if isinstance(sweep, dict):  # {start, stop, points, spacing}
            space = np.geomspace if sweep.get("spacing", "log") == "log" else np.linspace
            sweep = space(sweep["start"], sweep["stop"], int(sweep.get("points", 20)))
        out += [float(f) for f in np.atleast_1d(sweep)]
        if p.get("frequency"):
            out.append(float(p["frequency"]))
        elif p.get("period"):
            out.append(1.0 / float(p["period"]))
    return out


def working_frequencies(scene, controller=None) -> tuple[list[float], str]:
    """The frequencies (Hz) a run of the scene works at, and what they are: the requirement
    sine, the required bandwidth, the loop's gain crossover (with a controller) and the
    frequencies of the scene's time-run studies (:func:`study_frequencies`)."""
    freqs, what = [REQUIREMENT_SINE_HZ], [f"the {REQUIREMENT_SINE_HZ:g} Hz requirement sine"]
    bw = scene.requirements.bandwidth if scene.requirements is not None else None
    if bw is not None:
        freqs.append(float(bw))
        what.append("the required bandwidth")
    if controller is not None:
        fc = crossover_hz(scene, controller)
        if math.isfinite(fc):
            freqs.append(fc)
            what.append(f"the loop's crossover {fc:.3g} Hz")
    studies = study_frequencies(scene)
    if studies:
        freqs += studies
        what.append("the scene's kv and simulate studies")
    return sorted(set(freqs)), ", ".join(what)


def crossover_hz(scene, controller) -> float:
    """Highest 0 dB crossing of the loop broken at the position error (two-mass plant)."""
    from ..loop.closed_loop import open_loop_block
    f = np.logspace(-1, 4, 400)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mag = np.abs(open_loop_block(scene, controller, model="two_mass")(2j * np.pi * f)).ravel()
    except (ValueError, np.linalg.LinAlgError, SceneError):
        return math.nan
    above = np.flatnonzero(mag >= 1.0)
    return float(f[above[-1]]) if above.size else math.nan


def lumping_cost(scene, controller, q0: float, frequencies_hz, damping: float) -> float:
    """``max_f |T_two_mass / T_chain - 1|``: the closed loop's theta/theta_ref with the
    two-mass plant against the chain plant (no controller: the plant's output speed per
    volt)."""
    from ..loop.closed_loop import closed_loop_block
    from ..plant.linear import plant_block
    w = 2 * np.pi * np.asarray(frequencies_hz, dtype=float)
    resp = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for model in ("two_mass", "chain"):
            if controller is None:
                sys = plant_block(scene, q0, model=model, structural_damping=damping)["omega", "u"]
            else:
                sys = closed_loop_block(scene, controller, q0, model=model, structural_damping=damping)["theta",
                                                                                                      "theta_ref"]
            with np.errstate(all="ignore"):
                resp.append(np.asarray(sys(1j * w)).ravel())
    return float(np.max(np.abs(resp[0] / resp[1] - 1.0)))


def step_limit(scene, controller, q0: float, model: str, damping: float) -> float:
    """RK4's step (s) of the linear model with the ``model`` plant: its stability limit
    (:func:`stability_limit`), at most the controller's sample time."""
    limit = stability_limit(scene, controller, q0, model, damping)
    return min(limit, controller.sample_time) if controller is not None and controller.sample_time > 0 else limit


def stability_limit(scene, controller, q0: float, model: str, damping: float) -> float:
    """RK4's stability limit (s) of the linear model with the ``model`` plant: the plant with
    its current loop closed (a controller's current PI, as the compiled model integrates
    it), or the voltage-driven plant."""
    from ..lti.connect import interconnect
    from ..plant.current_loop import current_loop_block
    from ..plant.linear import plant_block
    g = plant_block(scene, q0, model=model, structural_damping=damping)
    if controller is None:
        return max_stable_dt(np.linalg.eigvals(g.A))
    cur = current_loop_block(controller.current_kp, controller.current_ki, scene.motor)
    sys = interconnect([g, cur], inplist=["i_cmd"], outlist=["theta"], check_unused=False)
    return max_stable_dt(np.linalg.eigvals(sys.A))


def choose_chain(scene, controller, q0: float, frequencies_hz, damping: float, what: str = "",
                 tolerance: float = LUMP_TOLERANCE) -> ChainChoice:
    """Keep or lump the chain's modes above the first (module docstring).

    Parameters
    ----------
    scene : Scene
        Its chain must have more than one mode (:func:`has_upper_modes`).
    controller : CascadeController or None
    q0 : float
    frequencies_hz : sequence of float
        The frequencies the run works at.
    damping : float
        Damping ratio of each compliance whose stage gives none.
    what : str
        The frequencies in words, for the note.
    tolerance : float

    Returns
    -------
    ChainChoice
    """
    chain = scene.drivetrain.chain
    modes = tuple(float(m) for m in chain.eigenfrequencies(q0, driving=True)[1:] / (2 * math.pi))
    freqs = tuple(float(f) for f in frequencies_hz)
    cost = lumping_cost(scene, controller, q0, freqs, damping)
    lim_full = stability_limit(scene, controller, q0, "chain", damping)
    lim_red = stability_limit(scene, controller, q0, "two_mass", damping)
    sample = controller.sample_time if controller is not None and controller.sample_time > 0 else 0.0
    dt_full, dt_red = (min(lim, sample) if sample else lim for lim in (lim_full, lim_red))
    steps = steps_text(dt_red, dt_full, lim_red, lim_full, sample)
    lump = cost <= tolerance
    at = f"at {what or 'the working frequencies'} ({_hz(freqs, 3)})"
    cost_text = f"lumping the modes {_hz(modes)} costs ~{cost:.2g} of the response {at}"
    if lump:
        note = (f"drivetrain modes {_hz(modes)} lumped into the two-mass reduction: {steps}; {cost_text} "
                f"(within {tolerance:g}); chain='full' keeps them, servo-toolkit reduce measures the cost")
    else:
        note = f"full drivetrain chain kept: {steps}; {cost_text} (more than {tolerance:g})"
    return ChainChoice("two_mass" if lump else "full", modes, cost, dt_full, dt_red, freqs, note,
                       lim_full, lim_red, sample)


def _hz(values, digits: int = 4) -> str:
    return ", ".join(f"{v:.{digits}g}" for v in values) + " Hz"


__all__ = ["ChainChoice", "LUMP_TOLERANCE", "choose_chain", "crossover_hz", "has_upper_modes", "lumping_cost",
           "stability_limit", "step_limit", "steps_text", "study_frequencies", "working_frequencies"]
