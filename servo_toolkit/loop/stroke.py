"""The designed loop along the drivetrain's stroke: operating point and stroke check.

A linkage or a cam makes the plant depend on the operating point q: the ratio N(q), the
reflected inertia J(q) (and its motor-side share J(q) / N(q)^2), the stiffness K(q). A loop
designed at one q0 runs unchanged (same structure, same gains, same speed-feedback ratio
N(q0)) at every other q, so it is checked there too: :func:`stroke_check` rebuilds the
linear plant at a grid of operating points and evaluates the fixed controller on each.

For a cascade (speed PI inside a position P) the speed-loop crossover scales as
1 / (motor-side inertia): where the inertia is larger than at q0 the crossover falls below
the PI's integral corner and the loop loses its phase (a fixed-gain design at a cam's
dwell, where the follower adds nothing, is unstable on the rise); where it is smaller the
crossover rises, which is safe until it meets the sampling delay or the drivetrain mode.
Hence the default operating point (:func:`operating_point`): the largest motor-side
inertia when it varies by more than :data:`INERTIA_SPREAD_LIMIT` along the stroke.

The figures come from the closed-form loop response (:mod:`.response`) refined with
:func:`.metrics.refined_figures` (the machinery of the robustness study, tested against
python-control), and stability from the eigenvalues of each closed-loop matrix
(:mod:`.assembly`); the tests rebuild points with python-control.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import SceneError
from ..drivetrain.operating_point import INERTIA_SPREAD_LIMIT, SCAN_POINTS, _scan, operating_point, show_q  # noqa: F401
from ..core.output_units import OutputUnit
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, plant_matrices
from .assembly import closed_loop_matrix, controller_matrices
from .margins import frequency_grid
from .metrics import grid_figures
from .requirements import Check, check, unstable_checks
from .response import current_response, loop_response, mechanical_response
from .variant_loops import controller_blocks as _controller_blocks, controller_response as _controller_response
from .schedule import crossover_hz
from .stroke_plants import PlantScan, plants_at

STROKE_POINTS = 25
"""Evenly spaced operating points of the stroke check, ends included (one turn of a cam:
the end that repeats the start is dropped), plus q0 and the inertia extremes."""

#: margin requirement -> its figure over the stroke
_MARGIN_FIGURES = {"gain_margin": "gain_margin_db", "phase_margin": "phase_margin_deg",
                   "sensitivity_peak": "sensitivity_peak_db"}
#: the figures a one-line repr names: key, name, unit
_REPR_FIGURES = (("gain_margin_db", "GM", "dB"), ("phase_margin_deg", "PM", "deg"), ("sensitivity_peak_db", "Ms", "dB"),
                 ("bandwidth_hz", "bandwidth", "Hz"))
_FIGURES = ("gain_margin_db", "phase_margin_deg", "sensitivity_peak_db", "bandwidth_hz")
#: figure -> worst is its minimum or its maximum (over the stable points)
_WORST = {"gain_margin_db": "min", "phase_margin_deg": "min", "sensitivity_peak_db": "max",
          "bandwidth_hz": "min", "max_pole_real": "max"}


def stroke_points(drivetrain, points: int = STROKE_POINTS, extra=()) -> np.ndarray:
    """Operating points of the stroke check (rad): ``points`` evenly spaced over the
    stroke, ends included (for a cam's turn the end repeating the start is dropped), the
    motor-side inertia's largest and smallest points and ``extra`` (each unless a point
    lies within 1e-9 rad of it); sorted."""
    lo, hi = drivetrain.stroke
    q = np.linspace(lo, hi, max(int(points), 2))
    if drivetrain.ends_in_cam and math.isclose(hi - lo, 2 * math.pi):
        q = q[:-1]
    qs, j = _scan(drivetrain)
    for x in np.concatenate([[qs[int(np.argmax(j))], qs[int(np.argmin(j))]], np.asarray(extra, float).ravel()]):
        if np.min(np.abs(q - x)) > 1e-9:  # a grid point already there stays as it is
            q = np.append(q, x)
    return np.sort(q)


def plant_scan(scene, q0: float, points: int = STROKE_POINTS, model: str = "auto",
               structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> PlantScan:
    """The plant at the stroke check's ``points`` evenly spaced points (and q0)."""
    q = stroke_points(scene.drivetrain, int(points), extra=[q0])
    return PlantScan(q, plants_at(scene, q, model, structural_damping), model, structural_damping)


@dataclass(frozen=True)
class _Rows:
    """Per-point electrical parameters in the shape :func:`.response.current_response` reads."""

    L: float
    R: float
    Ke: float
    N: np.ndarray
    torque_gain: np.ndarray


@dataclass(frozen=True)
class StrokeLoops:
    """The open loop at every operating point as a function of frequency, closed form:
    ``self(rows, w)`` is ``L`` of points ``rows`` at angular frequencies ``w``. The
    controller (its speed feedback divides omega_m by the design's ratio) is fixed; the
    plant's ratio, inertias, stiffness and friction are each point's."""

    params: tuple
    current_gains: tuple
    blocks: tuple
    factors: tuple = ()

    def __post_init__(self):
        cols = {k: np.array([getattr(p, k) for p in self.params], float)
                for k in ("J1", "J2", "K", "c", "b1", "b2", "kh", "N", "eta", "Kt")}
        ge, gw = self.factors if len(self.factors) else (np.ones(len(self.params)), np.ones(len(self.params)))
        cols["ge"], cols["gw"] = np.asarray(ge, float), np.asarray(gw, float)
        object.__setattr__(self, "_cols", cols)

    def __call__(self, rows, w):
        s = 1j * np.asarray(w, float)
        rows = np.asarray(rows)
        col = {k: v[rows] for k, v in self._cols.items()}
        g1, g2 = mechanical_response(s, col["J1"], col["J2"], col["K"], col["c"], col["b1"], col["b2"], col["kh"])
        p0 = self.params[0]
        tg = col["eta"] * col["N"] * col["Kt"]
        ic = current_response(s, _Rows(p0.L, p0.R, p0.Ke, col["N"], tg), g1, *self.current_gains)
        cy, cw, delay = _controller_response(self.blocks, s)
        return loop_response(s, tg * g1 * ic, tg * g2 * ic, delay, cy * col["ge"], cw * col["gw"], col["N"])


@dataclass(frozen=True, repr=False)
class StrokeCheck:
    """A fixed controller on the plant linearized at operating points along the stroke;
    ``repr`` is one line (the span, stability and the worst margins with their units).

    Attributes
    ----------
    q : numpy.ndarray
        Operating points (rad).
    q0 : float
        The design's operating point (rad).
    ratio : numpy.ndarray
        |N(q)|, motor rad per output rad.
    motor_inertia : numpy.ndarray
        Reflected inertia at the motor shaft, J(q) / N(q)^2 (kg*m^2).
    inertia : numpy.ndarray
        Reflected inertia at the output, J(q) (kg*m^2).
    stable : numpy.ndarray of bool
        Every closed-loop pole in the open left half plane.
    max_pole_real : numpy.ndarray
        Largest real part of the closed-loop poles (1/s).
    gain_margin_db, phase_margin_deg, sensitivity_peak_db, bandwidth_hz : numpy.ndarray
        Smallest |gain margin|, smallest phase margin, Ms, closed-loop -3 dB bandwidth
        (``inf`` without a crossing); meaningful where ``stable``.
    crossover_hz : numpy.ndarray or None
        The loop's gain crossover (Hz; first fall of |L| through 1, on the frequency grid).
    scheduled : bool
        The controller's gains were scheduled along the stroke (:mod:`.schedule`): each point
        ran its own factors.
    stroke_note : str or None
        Where the stroke came from when it is a default (the scene gives none), else None.
    """

    q: np.ndarray
    q0: float
    ratio: np.ndarray
    motor_inertia: np.ndarray
    inertia: np.ndarray
    stable: np.ndarray
    max_pole_real: np.ndarray
    gain_margin_db: np.ndarray
    phase_margin_deg: np.ndarray
    sensitivity_peak_db: np.ndarray
    bandwidth_hz: np.ndarray
    output_unit: str = "rad"
    crossover_hz: np.ndarray | None = None
    scheduled: bool = False
    stroke_note: str | None = None

    def show(self, q: float) -> str:
        """Operating point ``q`` as text (deg, or mm for a travel)."""
        return show_q(q, self.output_unit)

    def __repr__(self) -> str:
        unstable = int(np.sum(~self.stable))
        worst = self.worst()
        parts = [f"{name} {worst[key]['value']:.3g} {unit} at {self.show(worst[key]['q'])}"
                 for key, name, unit in _REPR_FIGURES if key in worst]
        return (f"<StrokeCheck: {self.q.size} points {self.show(self.q.min())}..{self.show(self.q.max())}, "
                + ("stable at every point" if unstable == 0 else f"{unstable} points UNSTABLE")
                + (f", worst {', '.join(parts)}" if parts else "") + ">")

    @property
    def all_stable(self) -> bool:
        """Closed loop stable at every point."""
        return bool(np.all(self.stable))

    @property
    def stable_fraction(self) -> float:
        return float(np.mean(self.stable))

    @property
    def unstable_q(self) -> np.ndarray:
        """Operating points (rad) where the closed loop is unstable."""
        return self.q[~self.stable]

    def worst(self) -> dict:
        """Per figure, the worst value over the stable points and where (``q_deg``);
        ``max_pole_real`` over every point. A figure with no stable point is absent."""
        out = {}
        for key, kind in _WORST.items():
            vals = getattr(self, key)
            ok = np.ones_like(self.stable) if key == "max_pole_real" else self.stable
            if not np.any(ok):
                continue
            k = int(np.argmin(np.where(ok, vals, np.inf)) if kind == "min" else np.argmax(np.where(ok, vals, -np.inf)))
            out[key] = {"value": float(vals[k]), "q_deg": math.degrees(self.q[k]), "q": float(self.q[k])}
        return out

    def requirement(self) -> Check:
        """The ``stable_over_stroke`` check: stable fraction of the points >= 1 (source
        ``"always"``, like the closed-loop stability at q0: no scene setting turns it off)."""
        frac = self.stable_fraction
        return Check("stable_over_stroke", 1.0, frac, self.all_stable, "", ">=", "always",
                     0.0 if self.all_stable else 1.0 - frac)

    def margin_requirements(self, requirements=()) -> list:
        """Worst-case margins over the stroke as checks: ``gain_margin_over_stroke``,
        ``phase_margin_over_stroke``, ``sensitivity_peak_over_stroke``, one per margin
        requirement in ``requirements`` and with its required value (the margins the loop
        must have at q0 it must have at every point). Achieved is the worst value over the
        points; when some point is unstable the loop has no margins there and each row fails
        with that reason and no figure (:func:`.requirements.unstable_checks`)."""
        reqs = [r for r in requirements if r.name in _MARGIN_FIGURES]
        if not self.all_stable:
            return unstable_checks(reqs, self.unstable_reason, "_over_stroke")
        out = []
        worst = self.worst()
        for r in reqs:
            key = _MARGIN_FIGURES[r.name]
            if key not in worst:
                continue
            a = worst[key]["value"]
            a = abs(a) if key == "gain_margin_db" else a
            out += check([r], {r.name: a})
        return [replace(c, name=f"{c.name}_over_stroke") for c in out]

    @property
    def unstable_reason(self) -> str:
        """Why the loop is unstable over the stroke ("" when it is stable at every point)."""
        if self.all_stable:
            return ""
        k = int(np.sum(~self.stable))
        return (f"closed loop unstable at {k} of {self.q.size} stroke points (largest closed-loop pole real "
                f"part {float(np.max(self.max_pole_real)):.4g} 1/s, at q = "
                f"{self.show(float(self.q[int(np.argmax(self.max_pole_real))]))})")

    def notes(self, requirements=()) -> tuple:
        """Where the loop is unstable, and each worst margin that misses its requirement
        (rows ``*_over_stroke``), with the operating point and the shortfall."""
        out = [self.stroke_note] if self.stroke_note else []
        if not self.all_stable:
            qs = ", ".join(self.show(q) for q in self.unstable_q)
            out.append(f"the loop designed at q0 = {self.show(self.q0)} is UNSTABLE at "
                       f"{int(np.sum(~self.stable))} of {self.q.size} stroke points: q = {qs}")
        worst = self.worst()
        for r in requirements:
            key = _MARGIN_FIGURES.get(r.name)
            if key is None or key not in worst:
                continue
            value, value_q = worst[key]["value"], worst[key]["q"]
            a = abs(value) if key == "gain_margin_db" else value
            met = a >= r.value if r.sense == ">=" else a <= r.value
            if not met:
                short = r.value - a if r.sense == ">=" else a - r.value
                out.append(f"over the stroke (stable points) the worst {r.name} is {a:.4g} {r.unit} at q = "
                           f"{self.show(value_q)}: required {r.sense} {r.value:g} {r.unit}, short by {short:.3g} "
                           f"{r.unit} ({r.name}_over_stroke)")
        return tuple(out)

    def to_dict(self) -> dict:
        """JSON-ready: per point lists and the worst cases."""
        def floats(a):
            return [float(x) for x in np.asarray(a, float)]
        u = OutputUnit(self.output_unit)
        return {u.key("q0"): float(u.show(self.q0)), "points": int(self.q.size),
                u.key("q"): floats(u.show(self.q)), "ratio": floats(self.ratio),
                "motor_side_inertia_kg_m2": floats(self.motor_inertia),
                f"output_inertia_{'kg' if u.linear else 'kg_m2'}": floats(self.inertia),
                "stable": [bool(x) for x in self.stable], "max_pole_real": floats(self.max_pole_real),
                **{k: floats(getattr(self, k)) for k in _FIGURES},
                **({} if self.crossover_hz is None else {"crossover_hz": floats(self.crossover_hz)}),
                "scheduled": self.scheduled, "spread": self.spread(),
                "output_unit": self.output_unit, "all_stable": self.all_stable, "worst": self.worst()}

    def spread(self) -> dict:
        """Over the stable points: each margin's range (``phase_margin_deg``, ``gain_margin_db``:
        max - min) and the crossover's (``crossover``: max / min - 1;
        ``crossover_deviation_from_q0``: the largest |f_c / f_c(q0) - 1|); empty without a stable
        point."""
        ok = self.stable & np.isfinite(self.phase_margin_deg)
        if not np.any(ok):
            return {}
        gm = self.gain_margin_db[ok & np.isfinite(self.gain_margin_db)]
        out = {"phase_margin_deg": float(np.ptp(self.phase_margin_deg[ok])),
               "gain_margin_db": float(np.ptp(gm)) if gm.size else 0.0}
        if self.crossover_hz is not None and np.all(np.isfinite(self.crossover_hz[ok])):
            c = self.crossover_hz[ok]
            k0 = int(np.argmin(np.abs(self.q - self.q0)))
            out["crossover"] = float(c.max() / c.min() - 1.0)
            out["crossover_deviation_from_q0"] = float(np.max(np.abs(c / self.crossover_hz[k0] - 1.0)))
        return out

    def summary(self) -> str:
        """Two lines: the span of the check, stability and the worst cases."""
        lo, hi = self.show(self.q.min()), self.show(self.q.max())
        unstable = int(np.sum(~self.stable))
        worst = ", ".join(f"{k} {w['value']:.4g} at {self.show(w['q'])}" for k, w in self.worst().items()
                          if k != "max_pole_real")
        return (f"  over the stroke ({self.q.size} points, {lo}..{hi}, motor-side inertia "
                f"{self.motor_inertia.min():.4g}..{self.motor_inertia.max():.4g} kg*m^2): "
                f"{'stable everywhere' if unstable == 0 else f'{unstable} points UNSTABLE'}"
                + (f"\n  worst over the stable points: {worst}" if worst else ""))

    def table(self) -> str:
        """One line per point and the worst cases, as text."""
        lines = [f"  over the stroke ({self.q.size} points, controller of q0 = {self.show(self.q0)}): "
                 f"{int(np.sum(~self.stable))} unstable",
                 f"  {'q [mm]' if self.output_unit == 'm' else 'q [deg]':>9}{'N':>9}{'J_motor':>11}  {'stable':>6}"
                 f"{'GM dB':>8}{'PM deg':>8}{'Ms dB':>7}{'BW Hz':>8}"]
        for k in range(self.q.size):
            qk = self.q[k] * 1e3 if self.output_unit == "m" else math.degrees(self.q[k])
            lines.append(f"  {qk:9.2f}{self.ratio[k]:9.4g}{self.motor_inertia[k]:11.4g}  "
                         f"{'yes' if self.stable[k] else 'NO':>6}{self.gain_margin_db[k]:8.2f}"
                         f"{self.phase_margin_deg[k]:8.1f}{self.sensitivity_peak_db[k]:7.2f}"
                         f"{self.bandwidth_hz[k]:8.3g}")
        for key, w in self.worst().items():
            lines.append(f"  worst {key}: {w['value']:.4g} at q = {self.show(w['q'])}")
        return "\n".join(lines)


def stroke_check(scene, controller, q0, *, points: int = STROKE_POINTS, model: str = "auto",
                 structural_damping: float = DEFAULT_STRUCTURAL_DAMPING, f_req: float = 5.0,
                 scan: PlantScan | None = None) -> StrokeCheck:
    """Evaluate ``controller`` (unchanged) on the plant linearized along the stroke.

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    q0 : float
        The design's operating point (rad); it is one of the points.
    points : int
        Evenly spaced points over the stroke, at least 2 (see :func:`stroke_points`).
    model : {"auto", "two_mass", "rigid"}
    structural_damping : float
    f_req : float
        Required bandwidth (Hz), added to the frequency grid.
    scan : PlantScan, optional
        The plants at these points when the caller has them (:func:`plant_scan`).

    Returns
    -------
    StrokeCheck

    Raises
    ------
    SceneError
        ``stroke_points`` below 2 or not an integer.
    """
    if int(points) != points or points < 2:
        raise SceneError("stroke_points", f"must be an integer of at least 2 (0 skips the stroke check), "
                                          f"got {points!r}")
    drive = scene.drivetrain
    q = stroke_points(drive, int(points), extra=[q0])
    params = plants_at(scene, q, model, structural_damping, scan)
    ratio, _ = drive.ratio(q)
    j, _ = drive.inertia(q)
    schedule = getattr(controller, "schedule", None)
    max_real = np.empty(q.size)
    for k, p in enumerate(params):  # a chain may be rigid at some points: one matrix each
        A, B, C, D, _ = plant_matrices(p, inductance=True)
        kc = controller_matrices(controller if schedule is None else schedule.scaled(controller, q[k]), scene.motor)
        max_real[k] = np.linalg.eigvals(closed_loop_matrix(A, B[:, :1], C[:3], D[:3, :1], *kc)).real.max()
    gains = (controller.current_kp, controller.current_ki) if params[0].L > 0 else (0.0, 0.0)
    factors = () if schedule is None else schedule.factors(q)
    response = StrokeLoops(params, gains, _controller_blocks(controller), factors)
    w = frequency_grid(f_min=0.01, f_max=5e3, points=600, extra=[f_req])
    L = response(np.arange(q.size)[:, None], w[None, :])
    try:
        figs = grid_figures(w, L, response=response)
    except FloatingPointError:  # a refinement that does not converge: the grid's figures
        figs = grid_figures(w, L)
    return StrokeCheck(q=q, q0=float(q0), ratio=np.abs(ratio), motor_inertia=j / ratio**2, inertia=j,
                       stable=max_real < 0, max_pole_real=max_real,
                       gain_margin_db=np.abs(figs["gain_margin_db"]), phase_margin_deg=figs["phase_margin_deg"],
                       sensitivity_peak_db=figs["sensitivity_peak_db"], bandwidth_hz=figs["bandwidth_hz"],
                       output_unit=drive.output_unit, crossover_hz=crossover_hz(w, L), scheduled=schedule is not None,
                       stroke_note=drive.stroke_note)
