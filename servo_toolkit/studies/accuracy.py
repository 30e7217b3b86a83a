"""Error against run time: RK4 (and the cam paper's scheme) at a ladder of steps against the
tight-tolerance reference, with the observed order of convergence.

With friction that holds (``ModelOptions(friction="stick")``) the right-hand side switches
where a node carrying friction sticks, breaks away or reverses. The study finds these
switching instants in the reference run (a speed entering or leaving exactly 0, or changing
sign, between two records) and measures RK4's order on the window before the first of them,
where the right-hand side is smooth, on the window after the last (where the errors made at
every switch have carried on) and over the whole run (:func:`switching_note` says what it
sees). RK4 locates the switches within its steps to high order
(``servo_toolkit/_physics/split_step.h``), so all three read about 4.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from ..core.progress import progress_bar

from ..errors import SimulationError
from ..sim import layout as lo
from ..sim.engine import run
from ..sim.ivp_friction import friction_nodes
from ..sim.reference import Reference


@dataclass(frozen=True)
class AccuracyResult:
    """Runs of one model at several steps, and the reference.

    Attributes
    ----------
    runs : tuple of dict
        ``method``, ``dt_s``, ``wall_s``, ``error`` (max |q - q_ref| / motion amplitude).
    order : float
        Observed RK4 order against the reference (slope of log error against log dt, over
        the steps whose errors are above the reference's own accuracy; NaN when fewer than
        two are).
    paper_order : float
        Order of the cam paper's scheme from its self-convergence (differences between
        successive halvings): against the reference its error levels off at the model
        difference of the play operator (seed 002 eqs 6-8), which opens the play at every
        reversal even under preload, where the elasto-backlash law keeps contact.
    reference_wall_s : float
    amplitude_rad : float
    duration_s : float
    description : str
    self_order : float
        Observed RK4 order from its self-convergence (differences between successive
        halvings), which needs no reference: where the reference's own error is larger than
        RK4's (a non-smooth run, a cam), it still measures the step's order.
    repeats : int
        Each wall time is the best (smallest) of this many identical runs, so that one
        noisy repeat does not order the methods.
    switching : dict
        With friction that holds: ``instants`` (how many switching instants the reference
        run has), ``first_s`` (the first), ``smooth_window_s`` (the window before it, where
        the order ``order_smooth`` is measured), ``errors_smooth`` (RK4's errors there, per
        step), and after the last: ``last_s``, ``after_window_s``, ``errors_after`` (against
        the reference, which carries its own event-location errors there) and ``order_after``
        (RK4's own, from successive halvings of the step); empty without friction that
        holds.
    notes : tuple of str
    output_unit : {"rad", "m"}
        Unit of ``amplitude_rad`` (m for an output travel).
    """

    runs: tuple
    order: float
    paper_order: float
    reference_wall_s: float
    amplitude_rad: float
    duration_s: float
    description: str = ""
    self_order: float = math.nan
    repeats: int = 1
    switching: dict = field(default_factory=dict)
    notes: tuple = ()
    output_unit: str = "rad"

    def to_dict(self) -> dict:
        """JSON-ready; the amplitude's key carries its unit (``amplitude_rad``, or
        ``amplitude_m`` for an output travel)."""
        return {"runs": list(self.runs), "order": self.order, "self_order": self.self_order,
                "paper_order": self.paper_order,
                "reference_wall_s": self.reference_wall_s, f"amplitude_{self.output_unit}": self.amplitude_rad,
                "duration_s": self.duration_s, "description": self.description, "repeats": self.repeats,
                "switching": dict(self.switching), "notes": list(self.notes), "output_unit": self.output_unit}

    def table(self) -> str:
        """Text table."""
        lines = [f"{self.description}", f"{'method':10s} {'dt [s]':>10s} {'wall [ms]':>10s} {'error [1]':>10s}"]
        for r in self.runs:
            dt = "adaptive" if r["dt_s"] is None else f"{r['dt_s']:.3g}"
            if r.get("failed"):  # a rung that could not run: its reason, no figures
                lines.append(f"{r['method']:10s} {dt:>10s} {'-':>10s} {'-':>10s}  failed: {r['failed']}")
            else:
                floor = r["method"] == "rk4" and 0.0 < r["error"] <= REFERENCE_FLOOR
                lines.append(f"{r['method']:10s} {dt:>10s} {r['wall_s'] * 1e3:10.2f} {r['error']:10.3g}"
                             + ("  (at the reference's own accuracy)" if floor else ""))
        lines.append("error: largest |q - q_ref| over the run, relative to the motion amplitude "
                     f"({self.amplitude_rad:.4g} {self.output_unit})")
        lines.append(f"observed order: {self.order_text()}")
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def order_text(self) -> str:
        """The observed orders in one line, saying how each was measured."""
        if math.isfinite(self.order):
            rk4 = f"RK4 {self.order:.2f} against the reference"
        else:
            errors = [r["error"] for r in self.runs if r["method"] == "rk4" and math.isfinite(r["error"])]
            rk4 = ("RK4 not measured (no step ran)" if not errors else
                   f"RK4 not measurable against the reference (its errors do not fall steadily below "
                   f"{max(errors):.2g}: friction's switching instants, see the note)" if self.switching.get("instants")
                   else f"RK4 not measurable against the reference (its errors stay at {min(errors):.2g}, the "
                   "reference's own accuracy)")
        own = (f"{self.self_order:.2f} by self-convergence" if math.isfinite(self.self_order)
               else "self-convergence not measured")
        paper = (f"{self.paper_order:.2f} by self-convergence" if math.isfinite(self.paper_order)
                 else "not measured")
        return f"{rk4}, {own}; paper scheme {paper}"

    def plot(self, ax=None):
        """Error against wall time, one line per method."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 4))
        for method, marker in (("rk4", "o-"), ("paper", "s--")):
            rs = [r for r in self.runs if r["method"] == method]
            ax.loglog([r["wall_s"] for r in rs], [max(r["error"], 1e-16) for r in rs], marker, label=method)
        ax.axvline(self.reference_wall_s, color="k", ls=":", label="reference solve")
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel("max error / amplitude")
        ax.legend()
        return ax


#: a halved step that shrinks the error by less than this has reached the reference's own
#: accuracy (a plateau): it and the smaller steps are left out of the order's fit
PLATEAU_RATIO = 1.2


#: relative errors at or below this are the reference's own accuracy, not the step's: the
#: LSODA reference at rtol = atol = 1e-12 differs from an RK4 run at 1/128 of the sample time
#: by 8.6e-12 of the amplitude on the reference EMA (8 Hz, 2 deg, 0.1 s), so an error must be
#: ten times that for the reference to change it by less than a tenth
REFERENCE_FLOOR = 1e-10
#: relative differences between two fixed-step runs at or below this are rounding
ROUNDING_FLOOR = 1e-12


def _order(dts, errors, floor: float = REFERENCE_FLOOR):
    """Slope of log error against log dt over the steps that ran, above ``floor`` and before
    the errors stop falling."""
    dts, errors = np.asarray(dts), np.asarray(errors)
    ok = np.isfinite(errors) & (errors > floor)  # ran, and above the floor
    steps = [k for k in np.argsort(-dts) if ok[k]]
    for prev, k in zip(steps, steps[1:]):
        if errors[prev] < PLATEAU_RATIO * errors[k]:
            ok[dts <= dts[k]] = False
            break
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(dts[ok]), np.log(errors[ok]), 1)[0])


def accuracy_study(model, reference: Reference, duration: float, dts=None, progress: bool = True,
                   rtol: float = 1e-12, atol: float = 1e-12, repeats: int = 3, x0=None) -> AccuracyResult:
    """Run the ladder of steps and the reference on one model.

    Parameters
    ----------
    model : Model
    reference : Reference
    duration : float
    dts : sequence of float, optional
        Steps; default the sample time (or 1e-4 s) divided by 1, 2, 4, 8, 16.
    repeats : int
        Every run is repeated this many times (the runs are deterministic); its wall time is
        the best of them.
    x0 : array_like, optional
        Initial state of every run (default: at rest at the model's operating point).
    """
    repeats = max(1, int(repeats))

    def timed(*args, **kwargs):
        first = run(*args, **kwargs)
        best = min([first.wall_s] + [run(*args, **kwargs).wall_s for _ in range(repeats - 1)])
        return first, best

    base = model.sample_time or 1e-4
    dts = list(dts) if dts is not None else [base / k for k in (1, 2, 4, 8, 16)]
    out_dt = max(dts)
    ref, ref_wall = timed(model, reference, duration, "reference", output_dt=out_dt, rtol=rtol, atol=atol, x0=x0)
    q_ref = ref.output_angle
    amp = reference.amplitude if reference.kind in ("sine", "step") and reference.amplitude else \
        max(np.ptp(q_ref) / 2, 1e-12)
    runs, qs = [], {"rk4": [], "paper": []}
    for method in ("rk4", "paper"):
        for dt in progress_bar(dts, show=progress, desc=f"accuracy {method}", leave=False):
            try:
                r, wall = timed(model, reference, duration, method, dt, output_dt=out_dt, x0=x0)
            except SimulationError as exc:  # a step outside the scheme's stability region: a failed rung
                runs.append({"method": method, "dt_s": dt, "wall_s": math.nan, "error": math.nan, "failed": str(exc)})
                qs[method].append(None)
                continue
            runs.append({"method": method, "dt_s": r.dt_s, "wall_s": wall,
                         "error": float(np.max(np.abs(r.output_angle - q_ref)) / abs(amp))})
            qs[method].append(r.output_angle)
    runs.append({"method": ref.method, "dt_s": None, "wall_s": ref_wall, "error": 0.0})
    order = _order([r["dt_s"] for r in runs if r["method"] == "rk4"], [r["error"] for r in runs if r["method"] == "rk4"])
    rk4_self, porder = (_self_order(dts, qs[m], amp) for m in ("rk4", "paper"))
    switching, notes = {}, ()
    if model.P[lo.STICK] > 0.0:
        rates = [model.state_names[i] for i in friction_nodes(model, model.P) if i > 3]  # intermediate nodes
        switching = _smooth_window(ref, switching_instants(ref, model.P[lo.TS_L] > 0.0, rates), dts, qs["rk4"], q_ref,
                                   amp, out_dt)
        floor = switched_floor(switching.get("errors_after", []))
        if floor > REFERENCE_FLOOR:  # the reference's own error after its switches bounds the whole run's
            order = _order([r["dt_s"] for r in runs if r["method"] == "rk4"],
                           [r["error"] for r in runs if r["method"] == "rk4"], floor)
            switching["reference_floor"] = floor
        notes = (switching_note(switching, order),)
    return AccuracyResult(tuple(runs), order, porder, ref_wall, float(abs(amp)), duration,
                          f"{model.name}: {reference.describe(model.output_unit)}, {duration:g} s, controller {model.controller}",
                          rk4_self, repeats, switching, notes, model.output_unit)


def switched_floor(errors_after) -> float:
    """The errors the reference's own accuracy hides after its friction switches: twice the
    level where RK4's errors after the last switch stop falling (a halving that shrinks them
    by less than :data:`PLATEAU_RATIO`: the reference's event locations and restarts, not the
    step); :data:`REFERENCE_FLOOR` when they fall to the end."""
    e = np.asarray(errors_after, dtype=float)
    e = e[np.isfinite(e)]
    for a, b in zip(e, e[1:]):
        if a < PLATEAU_RATIO * b:
            return max(REFERENCE_FLOOR, 2.0 * float(b))
    return REFERENCE_FLOOR


def switching_instants(result, load_friction: bool = False, rates=()) -> np.ndarray:
    """Record times (s) just before a node carrying friction sticks, breaks away or reverses
    in ``result``: its speed enters or leaves exactly 0, or changes sign, by the next record
    (the motor's; the load's with ``load_friction``; the states named in ``rates``: the full
    chain's intermediate nodes carrying friction)."""
    speeds = [np.asarray(result.motor_speed)]
    if load_friction:
        speeds.append(result.trace("output_rate_rad_s"))
    speeds += [result.trace(name) for name in rates]
    hits = np.zeros(len(result.times) - 1, dtype=bool)
    for v in speeds:
        stuck = v == 0.0
        hits |= (stuck[:-1] != stuck[1:]) | (v[:-1] * v[1:] < 0.0)
    return np.asarray(result.times)[:-1][hits]


def _smooth_window(ref, instants, dts, q_runs, q_ref, amp, out_dt) -> dict:
    """RK4's errors and order on the records before the first switching instant (one record
    spacing before it: the step meeting it starts no earlier), and on those after the last
    one (two record spacings after it), where the errors made at the switches have carried
    on into a smooth stretch."""
    first = float(instants[0]) if instants.size else math.inf
    last = float(instants[-1]) if instants.size else math.inf
    times = np.asarray(ref.times)

    def errors_on(window):
        return [float(np.max(np.abs(q[window] - q_ref[window])) / abs(amp)) if q is not None and window.any()
                else math.nan for q in q_runs]
    window = times < first - out_dt * (1 - 1e-9)
    after = times > last + 2.0 * out_dt * (1 - 1e-9)
    errors, errors_after = errors_on(window), errors_on(after)
    # after the last switch the reference carries its own event-location errors (about 1e-9 of
    # the amplitude after a few switches): the order there is RK4's own, from the differences
    # between successive halvings of the step
    own = [None if q is None else q[after] for q in q_runs] if after.any() else []
    return {"instants": int(instants.size), "first_s": first,
            "smooth_window_s": float(ref.times[window][-1]) if window.any() else 0.0,
            "errors_smooth": errors, "order_smooth": _order(dts, errors),
            "last_s": last, "after_window_s": float(times[-1] - times[after][0]) if after.any() else 0.0,
            "errors_after": errors_after,
            "order_after": _self_order(np.asarray(dts), own, amp) if own else math.nan}


def switching_note(switching: dict, order: float) -> str:
    """What the study sees at the switching instants of friction that holds, in words."""
    if not switching["instants"]:
        return "friction that holds: no node sticks, breaks away or reverses in the run (a smooth right-hand side)"
    smooth = switching["order_smooth"]
    before = (f"before the first, over {switching['smooth_window_s']:.4g} s where the right-hand side is smooth, "
              f"RK4's order is {smooth:.2f}" if math.isfinite(smooth) else
              "before the first the order is not measurable (nothing moves there, or the errors are at the "
              "reference's own accuracy)")
    across = f"{order:.2f}" if math.isfinite(order) else "no order (the errors do not fall steadily with the step)"
    if "reference_floor" in switching:
        across += (f" (errors below {switching['reference_floor']:.2g}, twice the reference's own after its "
                   "switches, left out)")
    after = switching.get("order_after", math.nan)
    tail = (f", and {after:.2f} over the {switching['after_window_s']:.4g} s after the last (at "
            f"{switching['last_s']:.4g} s; from successive halvings of the step)" if math.isfinite(after) else "")
    return (f"friction that holds: {switching['instants']} switching instants (a node sticking, breaking away or "
            f"reversing) in the reference run, the first at {switching['first_s']:.4g} s; {before}; over the whole "
            f"run {across}{tail}: RK4 locates each switch within its step to high order (a reversal at the zero of "
            "the speed continued past it, a breakaway where the moment on the held node reaches its level) and "
            "restarts there, so the smooth stretches between switches keep its order")


def _self_order(dts, qs, amp):
    """Order from the differences between successive halvings of the step (None: a failed
    run), above the rounding floor."""
    diffs = [float(np.max(np.abs(a - b))) / abs(amp) if a is not None and b is not None else math.nan
             for a, b in zip(qs, qs[1:])]
    return _order(dts[:-1], diffs, ROUNDING_FLOOR) if len(diffs) >= 2 else math.nan
