"""Nonlinear least-squares fit of scene parameters to a measured response.

The parameters are fitted as logarithms of their ratio to the initial value (positive by
construction, comparable steps whatever the unit), or, for one the scene accepts with either
sign (a constant force), as its change over its initial magnitude (:class:`.bounds.Coordinates`).
What is compared, and how residuals are weighted, is :mod:`.residuals`: a frequency response
(gain and phase), time traces of the voltage-driven plant, or closed-loop time traces of the
nonlinear model (friction, backlash, efficiency, a constant load, the drive's limits).

The search is global over each parameter's physical range (:mod:`.bounds`, :mod:`.search`):
a start derived from the data's own features, scattered starts, local refinement. The
verdict compares the residual with the noise floor the data show (:mod:`.verdict`).

The 95 % intervals come from the Jacobian at the solution, the refinement's own (central
differences of a fixed step in the coordinates, :func:`.search.differences`), which also
decides which parameters have no influence: cov = s^2 (J^T J)^-1 in the
search's coordinates with s^2 the residual variance, a Student t quantile for the degrees of
freedom, mapped back to values (so the intervals of a logarithm are not symmetric). Where the
correlation matrix says those are not to be trusted (a pair correlated beyond
:data:`MAX_CORRELATION`, a condition number beyond :data:`MAX_CONDITION`), the intervals of
the parameters concerned come from the profile of the cost
(:mod:`servo_toolkit.identify.profile`): bounded where the cost rises past the threshold,
unbounded (not identifiable) where it stays below it out to a bound of the range; a profile
point below the optimum's cost restarts the local fit there.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ..errors import SceneError, SimulationError
from . import residuals as compare
from .bounds import Coordinates, physical_range
from .data import FrequencyData, LoopData, TimeData, read_data
from .model import RESPONSES
from .params import SceneTemplate
from .residuals import PHASE_DB_PER_DEG, wrap_deg
from .result import FitResult
from .profile import LOWER_BY, ParameterProfile, noise_variance, profile, threshold
from .search import Search, global_least_squares, refine
from .verdict import MISS_FLOORS, bands, judge
from .whiteness import robust_inflation

__all__ = ["PHASE_DB_PER_DEG", "fit", "wrap_deg"]
#: relative half-width of the 95 % interval above which a parameter is called unidentified
MAX_RELATIVE_INTERVAL = 1.0
#: the search stops at a residual RMS within this factor of the noise floor
STOP_RATIO = 1.2
#: |correlation| above which two parameters are called not separable
MAX_CORRELATION = 0.99
#: condition number of the estimates' correlation matrix above which every parameter is profiled
MAX_CONDITION = 1e3
#: local fits restarted from a profile point below the optimum's cost
MAX_RESTARTS = 2


def _misses(comparison, resid, floor) -> tuple:
    """Where the model misses the data most: frequency bands or time windows (text)."""
    if floor is None:
        return ()
    per = np.sqrt(np.mean(resid.reshape(comparison.blocks, -1) ** 2, axis=0))
    miss = np.where(per > MISS_FLOORS * floor, per, 0.0)
    return tuple(bands(comparison.axis, miss, comparison.unit))


def _intervals(jac, resid, dof, groups=None):
    """Half-widths of the 95 % intervals of the log-parameters, their correlation, and
    which parameters have no (independent) influence, from the Jacobian at the solution;
    with ``groups`` (time traces: each residual's stretch of time), at least the
    cluster-robust interval (:func:`.whiteness.robust_inflation`)."""
    p = jac.shape[1]
    s2 = float(resid @ resid) / dof
    norms = np.linalg.norm(jac, axis=0)
    influential = norms > 1e-9 * max(float(norms.max()), 1e-300)
    half = np.full(p, np.inf)
    corr = np.full((p, p), np.nan)
    singular = ~influential
    idx = np.flatnonzero(influential)
    if idx.size:
        ja = jac[:, idx]
        jtj = ja.T @ ja
        sv = np.linalg.svd(ja, compute_uv=False)
        if sv[-1] <= 1e-10 * sv[0]:
            singular[idx] = True
        else:
            inv = np.linalg.inv(jtj)
            d = np.sqrt(np.abs(np.diag(inv)))
            half[idx] = stats.t.ppf(0.975, dof) * math.sqrt(s2) * d
            if groups is not None:
                factor, robust_dof = robust_inflation(ja, resid, groups)
                robust = stats.t.ppf(0.975, max(robust_dof, 1)) * math.sqrt(s2) * d * factor
                half[idx] = np.fmax(half[idx], robust)
            # the correlation does not depend on s^2 (an exact fit has s^2 = 0)
            corr[np.ix_(idx, idx)] = np.clip(inv / np.outer(d, d), -1.0, 1.0)
    return half, corr, singular


def _assess(sol, coords, template, dof, groups=None):
    """The solution's values, the parameters held by the scene's rules, and the Wald intervals."""
    norms = np.linalg.norm(sol.jac, axis=0)
    # a parameter without influence keeps the scene's value (the search moved it for nothing)
    z = np.where(norms > 1e-9 * max(float(norms.max()), 1e-300), sol.z, 0.0)
    values = coords.values(z)
    at_limit = _at_scene_limit(template, values)
    jac = np.where(at_limit, 0.0, sol.jac)  # a parameter held by the scene's rule is not estimated
    half, corr, singular = _intervals(jac, sol.fun, dof, groups)
    return z, values, at_limit, jac, half, corr, singular


def _profiles(residuals, z, coords, profiled, s2, level, half, rss, lower_by, progress: bool) -> list:
    """The profile of each parameter in ``profiled`` (:func:`servo_toolkit.identify.profile.profile`),
    with a bar counting the model evaluations (each profile re-fits the other parameters)."""
    from ..core.progress import progress_bar
    if not profiled:
        return []
    with progress_bar(total=None, desc="profiles", unit="model", show=progress) as bar:
        def counted(x):
            bar.update(1)
            return residuals(x)
        return [profile(counted, z, coords.lower, coords.upper, j, s2, level, half[j], rss, lower_by)
                for j in profiled]


def _to_profile(corr, singular, at_limit) -> list:
    """The parameters whose Wald interval is not to be trusted: those in a pair correlated
    beyond :data:`MAX_CORRELATION`, or all (estimated) ones when the correlation matrix is
    ill-conditioned beyond :data:`MAX_CONDITION`."""
    idx = [j for j in range(len(singular)) if not singular[j] and not at_limit[j]]
    if len(idx) < 2:
        return []
    c = corr[np.ix_(idx, idx)]
    if not np.all(np.isfinite(c)):
        return []
    if np.linalg.cond(c) > MAX_CONDITION:
        return idx
    return [j for j in idx if any(abs(corr[j, k]) > MAX_CORRELATION for k in idx if k != j)]


def _unbounded_warning(template, profiles, j, coords) -> str:
    """One line: parameter j's profile stays below the threshold out to a bound of its range."""
    p = next(p for p in profiles if p.index == j)
    par = template.parameters[j]
    lower, upper = coords.values(coords.lower)[j], coords.values(coords.upper)[j]
    sides = [f"{name} bound {b:.4g} {par.unit}" for name, b, open_ in
             (("lower", lower, p.unbounded[0]), ("upper", upper, p.unbounded[1])) if open_]
    partner = f"; it trades against {template.parameters[p.partner].key}" if p.partner is not None else ""
    return (f"{par.key}: the data cannot identify it (its profile stays within the 95 % threshold out to the "
            f"{' and the '.join(sides)} of its range{partner})")


def _in_units(p, template, coords, z, values) -> ParameterProfile:
    """A profile in the parameter's own units."""
    def value(c):
        return float(coords.values(np.where(np.arange(z.size) == p.index, c, z))[p.index])
    par = template.parameters[p.index]
    return ParameterProfile(key=par.key, unit=par.unit, value=float(values[p.index]),
                            values=np.array([value(c) for c in p.z]), rise=p.rise, threshold=p.threshold,
                            interval=(value(p.interval[0]), value(p.interval[1])), unbounded=p.unbounded,
                            partner=None if p.partner is None else template.parameters[p.partner].key)


def _at_scene_limit(template, values) -> np.ndarray:
    """Per parameter: a small step up or down gives a scene the loader refuses."""
    out = np.zeros(len(values), bool)
    for j in range(len(values)):
        for factor in (1 + 1e-5, 1 - 1e-5):
            trial = np.array(values, float)
            trial[j] *= factor
            try:
                template.scene(trial)
            except SceneError:
                out[j] = True
    return out


def fit(scene, data, response: str | None = None, params=(), *, controller=None, starts: int | None = None,
        progress: bool = False) -> FitResult:
    """Fit scene parameters to a measured response.

    Parameters
    ----------
    scene : Scene
        Initial scene, loaded from a file (:func:`servo_toolkit.load_scene`).
    data : FrequencyData, TimeData, LoopData, str or path-like
        The measurement, or a CSV file of it (see :func:`servo_toolkit.identify.read_data`).
    response : {"plant", "closed_loop"}, optional
        What a frequency response measured: ``plant`` motor current -> motor speed,
        ``closed_loop`` position command -> output position with the scene's designed
        controller. Default ``plant``. Time traces say what they measured by their columns
        (the voltage-driven plant, or the closed loop).
    params : sequence of str
        Scene key paths to fit, e.g. ``["load.inertia", "drivetrain[3].stiffness"]``; each
        a positive scalar quantity of the scene, or a nonzero one it accepts with either
        sign (``load.hinge_moment``).
    controller : CascadeController, optional
        Controller of a ``closed_loop`` response or of closed-loop traces (the rig's);
        default: designed on ``scene`` once and held fixed.
    starts : int, optional
        Scattered starts of the multi-start search (default 16 per parameter; 0: the
        data-derived start and the scene's values only).
    progress : bool
        Show a progress bar.

    Returns
    -------
    FitResult

    Raises
    ------
    SceneError
        Bad data, an unknown key, a key that is not a positive scalar, or fewer points than
        parameters + 2.
    SimulationError
        Closed-loop traces: the fitted scene's run leaves RK4's stability region at the step
        the initial scene's run chose.
    """
    if not isinstance(data, (FrequencyData, TimeData, LoopData)):
        data = read_data(data)
    if isinstance(data, (TimeData, LoopData)):
        if response not in (None, "plant"):
            raise SceneError("--response", "time traces say what they measured by their columns; "
                             f"{response!r} needs a frequency response")
        kind = data.kind
    else:
        kind = response or "plant"
        if kind not in RESPONSES:
            raise SceneError("--response", f"must be one of {', '.join(RESPONSES)} (got {kind!r})")
    if scene.motor is None or not scene.stages:
        raise SceneError("drivetrain", "fitting needs a motor-driven [[drivetrain]] (a linear plant to compare "
                         "with the measurement)", scene.source)
    template = SceneTemplate(scene, list(params))
    npar = len(template.parameters)
    if data.points < npar + 2:
        raise SceneError("(data)", f"{data.points} points for {npar} parameters; need at least {npar + 2}",
                         data.source)
    coords = Coordinates(template.parameters)
    x0 = coords.initial
    lower, upper = physical_range(template.parameters)
    if kind in ("closed_loop", "loop") and controller is None:
        from ..loop.design import design
        controller = design(template.base, progress=False).controller
    if kind == "time":
        comparison = compare.voltage_traces(data)
    elif kind == "loop":
        comparison = compare.loop_traces(data, template.base, controller)
    else:
        comparison = compare.frequency(data, kind, template.base, controller)
    floor = comparison.floor
    initial_model, r0, m0 = comparison.evaluate(template.base)
    penalty = np.full(r0.size, 1e3 * max(1.0, float(np.sqrt(np.mean(r0 ** 2)))))
    no_features = None if m0 is None else np.full(m0.size, 1e3)

    def probe(z):
        """Residuals and the mismatch of the data's features at coordinates z."""
        try:
            return comparison.evaluate(template.scene(coords.values(z)))[1:]
        except (SceneError, SimulationError):  # a value the scene refuses, a run that fails: step back
            return penalty, no_features

    def residuals(z):
        return probe(z)[0]

    # a residual within STOP_RATIO of the noise floor: no other start can do better in earnest
    enough = 0.0 if floor is None else 0.5 * r0.size * (STOP_RATIO * floor) ** 2
    sol = global_least_squares(residuals, coords.lower, coords.upper, np.zeros(npar),
                               probe=probe if m0 is not None else None, starts=starts, enough=enough,
                               progress=progress)
    m = sol.fun.size
    dof = max(m - npar, 1)
    level = threshold(dof)
    nfev, refined_from = int(sol.nfev), []
    for attempt in range(MAX_RESTARTS + 1):
        z, values, at_limit, jac, half, corr, singular = _assess(sol, coords, template, dof, comparison.clusters)
        profiled = _to_profile(corr, singular, at_limit)
        s2 = noise_variance(sol.fun, dof)
        rss = float(sol.fun @ sol.fun)
        # a drop in RSS that matters is one against the data's noise (an exact fit's s^2 is no measure of it)
        lower_by = LOWER_BY * max(s2, floor ** 2 if floor is not None else 0.0)
        profiles = _profiles(residuals, z, coords, profiled, s2, level, half, rss, lower_by, progress)
        nfev += sum(p.evaluations for p in profiles)
        lows = [p for p in profiles if p.lower is not None]
        if not lows or attempt == MAX_RESTARTS:
            break
        low = min(lows, key=lambda p: float(np.min(p.rise)))
        new = refine(residuals, low.lower, coords.lower, coords.upper)
        nfev += int(new.evaluations)
        if not new.cost < 0.5 * rss:
            break
        if np.max(np.abs(new.x - sol.z)) > 1e-6:
            refined_from.append(template.parameters[low.index].key)
        sol = Search(z=new.x, fun=new.fun, jac=new.jac, nfev=nfev, feature_start=sol.feature_start, ends=sol.ends)
    ci = coords.intervals(values, half)
    ci[singular] = [0.0, math.inf]
    wide = coords.relative_half(values, half) > MAX_RELATIVE_INTERVAL
    unbounded = np.zeros(npar, bool)
    for p in profiles:  # the profile's interval where it was computed: the cost, not its curvature at one point
        lo, hi = p.interval
        ci[p.index] = coords.values(np.where(np.arange(npar) == p.index, lo, z))[p.index], \
            coords.values(np.where(np.arange(npar) == p.index, hi, z))[p.index]
        unbounded[p.index] = any(p.unbounded)
        wide[p.index] = coords.relative_half(values, np.full(npar, max(hi - z[p.index], z[p.index] - lo)))[p.index] \
            > MAX_RELATIVE_INTERVAL
    keys = [p.key for p in template.parameters]
    residual_rms = float(np.sqrt(np.mean(sol.fun ** 2)))
    unidentified = [j for j in range(npar) if not at_limit[j] and (singular[j] or wide[j] or unbounded[j])]
    inseparable = [(a, b) for a in range(npar) for b in range(a + 1, npar) if abs(corr[a, b]) > MAX_CORRELATION]
    # a strong correlation alone is no verdict: the intervals (from the same information, or the profile) allow for it
    white = comparison.whiteness(sol.fun) if comparison.whiteness is not None and floor is not None else None
    verdict = judge(residual_rms, floor, dof, m, not unidentified, white=white is None or white.white)
    judged = verdict != "model mismatch"  # at a mismatch the intervals mean nothing
    warnings = []
    for j, key in enumerate(keys):
        if at_limit[j]:
            warnings.append(f"{key}: ended at the limit the scene accepts for it; the data ask for a value "
                            "beyond it (another parameter or the model is off)")
        elif singular[j] and (judged or not np.any(jac[:, j])):
            warnings.append(f"{key}: the data cannot identify it (no independent influence on the response); "
                            "kept near its initial value")
        elif judged and unbounded[j]:
            warnings.append(_unbounded_warning(template, profiles, j, coords))
        elif judged and wide[j]:
            source = (f" from the profile of the cost, [{ci[j, 0]:.4g}, {ci[j, 1]:.4g}] {template.parameters[j].unit},"
                      if j in profiled else "")
            warnings.append(f"{key}: the data cannot identify it (95 % interval{source} wider than "
                            f"+-{100 * MAX_RELATIVE_INTERVAL:.0f} % of the value)")
        if z[j] <= coords.lower[j] + 1e-3 or z[j] >= coords.upper[j] - 1e-3:
            warnings.append(f"{key}: ended at the bound of its physical range [{lower[j]:.4g}, {upper[j]:.4g}] "
                            f"{template.parameters[j].unit}")
    if judged:
        for a, b in inseparable:  # narrow intervals of correlated estimates are no problem: the table shows it
            if a in unidentified or b in unidentified:
                warnings.append(f"{keys[a]} and {keys[b]}: correlation {corr[a, b]:+.3f}; the data identify "
                                "only a combination of them")
        for p in profiles:  # the pair the profile found trading along the ridge
            pair = tuple(sorted((p.index, p.partner))) if p.partner is not None else None
            if pair and any(p.unbounded) and pair not in inseparable:
                inseparable.append(pair)
                warnings.append(f"{keys[pair[0]]} and {keys[pair[1]]}: they trade along the profile of "
                                f"{keys[p.index]}; the data identify only a combination of them")
    for key in refined_from:
        warnings.append(f"the profile of {key} found a lower residual than the search's optimum; the fit was "
                        "refined from there")
    try:
        fitted_scene = template.scene(values)
        fitted_model = comparison.evaluate(fitted_scene)[0]
    except SceneError as exc:
        raise SceneError(exc.key, f"the fit ended on a value the scene refuses ({exc.rule})") from None
    if comparison.verify is not None:
        comparison.verify(fitted_scene)
    residual_db_rms, residual_phase_deg_rms = None, None
    if isinstance(data, FrequencyData):
        gain = 20 * np.log10(np.abs(fitted_model)) - data.gain_db
        phase = wrap_deg(np.degrees(np.angle(fitted_model)) - data.phase_deg)
        residual_db_rms = float(np.sqrt(np.mean(gain ** 2)))
        residual_phase_deg_rms = float(np.sqrt(np.mean(phase ** 2)))
    misses = _misses(comparison, sol.fun, floor) if verdict == "model mismatch" else ()
    if white is not None and not white.white:
        misses = tuple(dict.fromkeys(misses + white.windows))[:3] if misses else white.windows
    return FitResult(scene=template.base.name, source=template.source, response=kind, keys=tuple(keys),
                     units=tuple(p.unit for p in template.parameters), initial=x0, values=values, ci95=ci,
                     correlation=corr, residual_db_rms=residual_db_rms,
                     residual_phase_deg_rms=residual_phase_deg_rms, residual_rms=residual_rms,
                     initial_residual_rms=float(np.sqrt(np.mean(r0 ** 2))), warnings=tuple(warnings),
                     data=data, initial_model=initial_model, fitted_model=fitted_model,
                     calibrated=fitted_scene, written=tuple(p.written for p in template.parameters),
                     evaluations=int(nfev), dof=int(dof), verdict=verdict, noise_floor=floor, misses=misses,
                     noise_basis=comparison.noise, correlated="" if white is None else white.text,
                     profiles=tuple(_in_units(p, template, coords, z, values) for p in profiles))
