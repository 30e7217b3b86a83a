"""Nonlinear least-squares fit of scene parameters to a measured response.

The parameters are fitted as logarithms of their ratio to the initial value (positive by
construction, comparable steps whatever the unit). Frequency-response residuals are the gain
difference in dB and the wrapped phase difference in deg times 20/ln(10) * pi/180 dB/deg
(about 0.152: one neper of log-magnitude weighs as one radian of phase, the real and
imaginary parts of the complex logarithm), each weighted by sqrt(coherence). Time-trace
residuals are the differences of current, motor angle and output angle, each divided by
the RMS of its measurement.

The search is global over each parameter's physical range (:mod:`.bounds`, :mod:`.search`):
a start derived from the data's own features, scattered starts, local refinement. The
verdict compares the residual with the noise floor the data show (:mod:`.verdict`).

The 95 % intervals come from the Jacobian at the solution: cov = s^2 (J^T J)^-1 in the
log-parameter space with s^2 the residual variance, a Student t quantile for the degrees of
freedom, mapped back to values (so the intervals are not symmetric).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ..errors import SceneError
from .data import FrequencyData, TimeData, read_data
from .model import RESPONSES, frequency_model, time_response
from .bounds import physical_range
from .features import feature_mismatch, response_features
from .params import SceneTemplate
from .result import FitResult
from .search import global_least_squares
from .verdict import MISS_FLOORS, bands, coherence_variance, judge, scatter_sd

#: dB of log-magnitude per degree of phase with the weight of the complex logarithm
PHASE_DB_PER_DEG = 20 / math.log(10) * math.pi / 180
#: fitted values stay within this factor of the initial ones
MAX_FACTOR = 100.0
#: relative half-width of the 95 % interval above which a parameter is called unidentified
MAX_RELATIVE_INTERVAL = 1.0
#: the search stops at a residual RMS within this factor of the noise floor
STOP_RATIO = 1.2
#: |correlation| above which two parameters are called not separable
MAX_CORRELATION = 0.99


def wrap_deg(x):
    """Angles wrapped to [-180, 180) deg."""
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


def _frequency_parts(data: FrequencyData):
    """``h -> residual vector`` of a model response against the data, and the noise floor of
    that vector (None with too few points)."""
    w = np.sqrt(data.coherence)

    def residuals_of(h):
        gain = 20 * np.log10(np.abs(h)) - data.gain_db
        phase = wrap_deg(np.degrees(np.angle(h)) - data.phase_deg)
        return np.concatenate([w * gain, w * PHASE_DB_PER_DEG * phase])
    sg = scatter_sd(data.gain_db)
    sp = scatter_sd(np.degrees(np.unwrap(np.radians(data.phase_deg))))
    # the coherence's own uncertainty (gain and phase alike: one neper is one radian, 20/ln 10 dB)
    coh = (20 / math.log(10)) ** 2 * float(np.mean(coherence_variance(data.coherence)))
    floor = None if sg is None else math.sqrt(float(np.mean(w ** 2)) * (sg ** 2 + (PHASE_DB_PER_DEG * sp) ** 2) / 2
                                              + coh)
    return residuals_of, floor


def _time_parts(data: TimeData):
    """``scene -> residual vector`` of the simulated traces against the measured ones, and
    the noise floor of that vector."""
    measured = (data.current_A, data.motor_angle_rad - data.motor_angle_rad[0],
                data.output_angle_rad - data.output_angle_rad[0])
    scales = []
    for name, m in zip(("current_A", "motor_angle_rad", "output_angle_rad"), measured):
        rms = float(np.sqrt(np.mean((m - m.mean()) ** 2)))
        if not rms > 0:
            raise SceneError(name, "is constant in the time traces; nothing to fit it to", data.source)
        scales.append(rms)

    def residuals(scene):
        model = time_response(scene, data.time_s, data.voltage_V)
        return np.concatenate([(y - m) / s for y, m, s in zip(model, measured, scales)])
    sds = [scatter_sd(m) for m in measured]
    floor = None if sds[0] is None else math.sqrt(float(np.mean([(sd / s) ** 2 for sd, s in zip(sds, scales)])))
    return residuals, floor


def _misses(kind, data, resid, floor) -> tuple:
    """Where the model misses the data most: frequency bands or time windows (text)."""
    if floor is None:
        return ()
    if kind == "time":
        per = np.sqrt(np.mean(resid.reshape(3, -1) ** 2, axis=0))
        x, unit = data.time_s - data.time_s[0], "s"
    else:
        per = np.sqrt(np.mean(resid.reshape(2, -1) ** 2, axis=0))
        x, unit = data.frequency_hz, "Hz"
    miss = np.where(per > MISS_FLOORS * floor, per, 0.0)
    return tuple(bands(x, miss, unit))


def _intervals(jac, resid, dof):
    """Half-widths of the 95 % intervals of the log-parameters, their correlation, and
    which parameters have no (independent) influence, from the Jacobian at the solution."""
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
            # the correlation does not depend on s^2 (an exact fit has s^2 = 0)
            corr[np.ix_(idx, idx)] = np.clip(inv / np.outer(d, d), -1.0, 1.0)
    return half, corr, singular


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
    data : FrequencyData, TimeData, str or path-like
        The measurement, or a CSV file of it (see :func:`servo_toolkit.identify.read_data`).
    response : {"plant", "closed_loop"}, optional
        What a frequency response measured: ``plant`` motor current -> motor speed,
        ``closed_loop`` position command -> output position with the scene's designed
        controller. Default ``plant``. Time traces always fit the voltage-driven plant.
    params : sequence of str
        Scene key paths to fit, e.g. ``["load.inertia", "drivetrain[3].stiffness"]``; each
        a positive scalar quantity of the scene.
    controller : CascadeController, optional
        Controller of the ``closed_loop`` response; default: designed on ``scene`` once.
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
    """
    if not isinstance(data, (FrequencyData, TimeData)):
        data = read_data(data)
    if isinstance(data, TimeData):
        if response not in (None, "plant"):
            raise SceneError("--response", "time traces fit the voltage-driven plant; "
                             f"{response!r} needs a frequency response")
        kind = "time"
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
    x0 = np.asarray(template.initial, float)
    lower, upper = physical_range(template.parameters)
    model = None
    features = None
    if kind == "time":
        residuals_of, floor = _time_parts(data)
    else:
        if kind == "closed_loop" and controller is None:
            from ..loop.design import design
            controller = design(template.base, progress=False).controller
        model = frequency_model(template.base, kind, controller)
        compare, floor = _frequency_parts(data)

        def residuals_of(scene_z):
            return compare(model(scene_z, data.frequency_hz))
        if kind == "plant":
            features = response_features(data.frequency_hz, data.complex)

    r0 = residuals_of(template.base)
    penalty = np.full(r0.size, 1e3 * max(1.0, float(np.sqrt(np.mean(r0 ** 2)))))

    def residuals(z):
        try:
            scene_z = template.scene(x0 * np.exp(z))
        except SceneError:  # a value the scene refuses (e.g. an efficiency above 1): step back
            return penalty
        return residuals_of(scene_z)

    def probe(z):
        """Residuals and, for a current -> speed response, the mismatch of its features."""
        if features is None:
            return residuals(z), None
        try:
            scene_z = template.scene(x0 * np.exp(z))
        except SceneError:
            return penalty, np.full(3, 1e3)
        h = model(scene_z, data.frequency_hz)
        return compare(h), feature_mismatch(response_features(data.frequency_hz, h), features)

    zlo, zhi = np.log(lower / x0), np.log(upper / x0)
    # a residual within STOP_RATIO of the noise floor: no other start can do better in earnest
    enough = 0.0 if floor is None else 0.5 * r0.size * (STOP_RATIO * floor) ** 2
    sol = global_least_squares(residuals, zlo, zhi, np.zeros(npar), probe=probe, starts=starts, enough=enough,
                               progress=progress)
    m = sol.fun.size
    dof = max(m - npar, 1)
    norms = np.linalg.norm(sol.jac, axis=0)
    # a parameter without influence keeps the scene's value (the search moved it for nothing)
    z = np.where(norms > 1e-9 * max(float(norms.max()), 1e-300), sol.z, 0.0)
    values = x0 * np.exp(z)
    at_limit = _at_scene_limit(template, values)
    jac = np.where(at_limit, 0.0, sol.jac)  # a parameter held by the scene's rule is not estimated
    half, corr, singular = _intervals(jac, sol.fun, dof)
    with np.errstate(over="ignore"):  # two parameters in series: a half-width of hundreds of nepers
        ci = np.column_stack([values * np.exp(-half), values * np.exp(half)])
    ci[singular] = [0.0, math.inf]
    keys = [p.key for p in template.parameters]
    residual_rms = float(np.sqrt(np.mean(sol.fun ** 2)))
    unidentified = [j for j in range(npar) if not at_limit[j] and (singular[j] or half[j] > math.asinh(MAX_RELATIVE_INTERVAL))]
    inseparable = [(a, b) for a in range(npar) for b in range(a + 1, npar) if abs(corr[a, b]) > MAX_CORRELATION]
    verdict = judge(residual_rms, floor, dof, m, not unidentified and not inseparable)
    judged = verdict != "model mismatch"  # at a mismatch the intervals mean nothing
    warnings = []
    for j, key in enumerate(keys):
        if at_limit[j]:
            warnings.append(f"{key}: ended at the limit the scene accepts for it; the data ask for a value "
                            "beyond it (another parameter or the model is off)")
        elif singular[j] and (judged or not np.any(jac[:, j])):
            warnings.append(f"{key}: the data cannot identify it (no independent influence on the response); "
                            "kept near its initial value")
        elif judged and half[j] > math.asinh(MAX_RELATIVE_INTERVAL):  # sinh(half) overflows for a wide one
            warnings.append(f"{key}: the data cannot identify it (95 % interval wider than "
                            f"+-{100 * MAX_RELATIVE_INTERVAL:.0f} % of the value)")
        if z[j] <= zlo[j] + 1e-3 or z[j] >= zhi[j] - 1e-3:
            warnings.append(f"{key}: ended at the bound of its physical range [{lower[j]:.4g}, {upper[j]:.4g}] "
                            f"{template.parameters[j].unit}")
    if judged:
        for a, b in inseparable:
            warnings.append(f"{keys[a]} and {keys[b]}: correlation {corr[a, b]:+.3f}; the data identify "
                            "only a combination of them")
    try:
        fitted_scene = template.scene(values)
    except SceneError as exc:
        raise SceneError(exc.key, f"the fit ended on a value the scene refuses ({exc.rule})") from None
    if kind == "time":
        initial_model = time_response(template.base, data.time_s, data.voltage_V)
        fitted_model = time_response(fitted_scene, data.time_s, data.voltage_V)
        residual_db_rms, residual_phase_deg_rms = None, None
    else:
        initial_model = model(template.base, data.frequency_hz)
        fitted_model = model(fitted_scene, data.frequency_hz)
        gain = 20 * np.log10(np.abs(fitted_model)) - data.gain_db
        phase = wrap_deg(np.degrees(np.angle(fitted_model)) - data.phase_deg)
        residual_db_rms = float(np.sqrt(np.mean(gain ** 2)))
        residual_phase_deg_rms = float(np.sqrt(np.mean(phase ** 2)))
    misses = _misses(kind, data, sol.fun, floor) if verdict == "model mismatch" else ()
    return FitResult(scene=template.base.name, source=template.source, response=kind, keys=tuple(keys),
                     units=tuple(p.unit for p in template.parameters), initial=x0, values=values, ci95=ci,
                     correlation=corr, residual_db_rms=residual_db_rms,
                     residual_phase_deg_rms=residual_phase_deg_rms, residual_rms=residual_rms,
                     initial_residual_rms=float(np.sqrt(np.mean(r0 ** 2))), warnings=tuple(warnings),
                     data=data, initial_model=initial_model, fitted_model=fitted_model,
                     calibrated=fitted_scene, written=tuple(p.written for p in template.parameters),
                     evaluations=int(sol.nfev), dof=int(dof), verdict=verdict, noise_floor=floor, misses=misses)
