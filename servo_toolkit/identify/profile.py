"""Profile likelihood of a least-squares fit (Raue et al. 2009, "Structural and practical
identifiability analysis of partially observed dynamical models by exploiting the profile
likelihood", Bioinformatics 25(15)).

The intervals from the Jacobian at the optimum (Wald) describe a quadratic valley. When two
parameters trade against each other (a ridge: two springs in series, whose compliances add)
the valley is not quadratic and the Jacobian at one point says little: a kink of the model on
the ridge makes a finite difference across it arbitrarily steep, and the Wald interval
arbitrarily narrow. The profile asks the cost itself: parameter j is held at values on a grid
each side of the optimum, the others are fitted again (started from the previous grid point,
so they follow the ridge), and the interval ends where the residual sum of squares, over the
noise variance s^2 of the fit, has risen by the threshold of the interval's level,

    (RSS_j(z_j) - RSS_min) / s^2 = t_{dof, 0.975}^2

(the F(1, dof) quantile; 3.84 for many points, the chi-square(1) quantile of a known noise).
For a model linear in its parameters the profile is the parabola of the Wald interval and
both give the same ends; otherwise the profile's ends follow the cost, not its curvature at
one point, and are not symmetric.

A side whose profile stays below the threshold out to the bound of the parameter's physical
range is unbounded: the data do not bound the parameter there (practically not identifiable;
a profile exactly flat: structurally not). The parameter whose value moves most along that
side is the one it trades against. A grid point whose cost is below the optimum's shows the
optimum was not the lowest: the fit is refined from there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from .search import differences

#: the grid's first step from the optimum, as a share of the Wald half-width (so a quadratic
#: profile crosses at the grid's second point)
FIRST_STEP = 0.5
#: the smallest first step (coordinates: log of the value; the Wald half-width of a ridge is no guide)
MIN_STEP = 0.02
#: the grid's steps grow by this factor toward the bound
GROWTH = 3.0
#: most residual evaluations of one re-fit of the other parameters, per parameter
NFEV_PER_PARAMETER = 20
#: most steps locating an interval's end ...
CROSSING_ITERATIONS = 24
#: ... the first of them by regula falsi, the others by halving
FALSE_POSITION_STEPS = 6
#: an interval's end is located to this share of its distance from the optimum
CROSSING_TOL = 1e-3
#: the walk along a side stops where the rise exceeds this many thresholds (the cost has left the valley)
STOP_RISE = 10.0
#: a grid point lower than the optimum by this much (RSS over s^2) means the optimum was not the lowest
LOWER_BY = 0.01


@dataclass(frozen=True)
class Profile:
    """The profile of one parameter.

    Attributes
    ----------
    index : int
        The parameter's position in the fit.
    z : numpy.ndarray
        The parameter's coordinate at each point, ascending (the optimum included).
    rise : numpy.ndarray
        (RSS - RSS_min) / s^2 at each point, the others fitted again.
    path : numpy.ndarray
        (points, parameters): every parameter's coordinate at each point.
    threshold : float
        The rise at which the interval ends.
    interval : tuple of float
        The interval's ends (coordinates); the bound of the range on an unbounded side.
    unbounded : tuple of bool
        (lower side, upper side): the rise stays below the threshold out to the bound.
    partner : int or None
        The parameter that moves most along an unbounded side (what this one trades against).
    lower : numpy.ndarray or None
        Coordinates of the lowest point found below the optimum's cost (None: none).
    evaluations : int
        Residual evaluations spent.
    """

    index: int
    z: np.ndarray
    rise: np.ndarray
    path: np.ndarray
    threshold: float
    interval: tuple
    unbounded: tuple
    partner: int | None
    lower: np.ndarray | None
    evaluations: int

    @property
    def identified(self) -> bool:
        """True when the rise reaches the threshold on both sides."""
        return not any(self.unbounded)


def threshold(dof: int, level: float = 0.95) -> float:
    """The profile's rise at the ends of a ``level`` interval: the square of Student's t
    quantile for ``dof`` degrees of freedom (the F(1, dof) quantile)."""
    return float(stats.t.ppf(0.5 + level / 2, max(int(dof), 1)) ** 2)


def noise_variance(resid, dof: int) -> float:
    """s^2 = RSS / dof, kept above zero (an exact fit: any rise crosses the threshold)."""
    rss = float(np.dot(resid, resid))
    return max(rss / max(int(dof), 1), 1e-300)


def profile(residuals, z, lower, upper, j: int, s2: float, level_threshold: float, half: float | None = None,
            rss: float | None = None, lower_by: float | None = None) -> Profile:
    """The profile of parameter ``j`` about the optimum ``z``.

    Parameters
    ----------
    residuals : callable
        ``z -> residual vector``.
    z : array_like
        The optimum (coordinates).
    lower, upper : array_like
        The box of the coordinates (the physical range).
    j : int
        The parameter profiled.
    s2 : float
        Noise variance of the residuals (:func:`noise_variance`).
    level_threshold : float
        Rise of RSS / s^2 at the interval's ends (:func:`threshold`).
    half : float, optional
        Wald half-width of ``z[j]``: sets the grid's first step.
    rss : float, optional
        RSS at ``z`` (default: evaluated).
    lower_by : float, optional
        A point whose RSS is below the optimum's by more than this is reported in
        ``Profile.lower`` (default :data:`LOWER_BY` s^2; an exact fit, whose s^2 is no
        measure of the noise, passes the data's noise variance).

    Returns
    -------
    Profile
    """
    z = np.asarray(z, float).copy()
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    free = np.array([k for k in range(z.size) if k != j], int)
    count = [0]

    def rss_at(x):
        r = residuals(x)
        count[0] += 1
        return float(np.dot(r, r))

    base = rss_at(z) if rss is None else float(rss)

    def refit_from(value, start):
        x = np.array(start, float)
        x[j] = value
        if free.size == 0:
            return x, rss_at(x)

        def sub(y):
            x[free] = y
            count[0] += 1
            return residuals(x)
        sol = optimize.least_squares(sub, np.clip(x[free], lower[free], upper[free]),
                                     jac=differences(sub, lower[free], upper[free]),
                                     bounds=(lower[free], upper[free]), method="trf",
                                     ftol=1e-9, xtol=1e-9, gtol=1e-9, max_nfev=NFEV_PER_PARAMETER * free.size)
        x[free] = sol.x
        return x.copy(), 2.0 * float(sol.cost)

    def refit(value, start, predicted=None):
        """The others fitted with z_j = value, from ``start`` and from ``predicted`` (the
        ridge extrapolated from the last two points; a narrow curved valley is lost from the
        previous point alone; tried when the first is past the threshold): (coordinates, RSS),
        the lower."""
        best = refit_from(value, start)
        if predicted is not None and free.size and (best[1] - base) / s2 >= level_threshold:
            trial = refit_from(value, np.clip(predicted, lower, upper))
            if trial[1] < best[1]:
                best = trial
        return best

    def crossing(side, inner, inner_rise, outer, start):
        """Distance from the optimum where the rise reaches the threshold, between ``inner``
        (below it) and ``outer`` (above): regula falsi (Illinois) on the square root of the
        rise, which is linear in the distance where the profile is a parabola, then halving. ``(x, rise)``
        instead when the outer point, fitted again from the inner one, is below after all."""
        target = math.sqrt(level_threshold)
        x, c = refit(z[j] + side * outer, start)
        points.append((x[j], x, (c - base) / s2))
        a, fa = inner, math.sqrt(max(inner_rise, 0.0)) - target
        b, fb = outer, math.sqrt(max((c - base) / s2, 0.0)) - target
        if fb < 0:
            return x, (c - base) / s2
        keep = 0
        for it in range(CROSSING_ITERATIONS):
            # regula falsi first (exact for a parabola); halving after (a jump of the rise at a kink)
            c_ = b - fb * (b - a) / (fb - fa) if it < FALSE_POSITION_STEPS else 0.5 * (a + b)
            x, c = refit(z[j] + side * c_, start)
            points.append((x[j], x, (c - base) / s2))
            fc = math.sqrt(max((c - base) / s2, 0.0)) - target
            if abs(fc) < 1e-6 * target:
                return float(c_)
            if fc > 0:
                b, fb = c_, fc
                fa = fa / 2 if keep == 1 else fa
                keep = 1
            else:
                a, fa = c_, fc
                fb = fb / 2 if keep == -1 else fb
                keep = -1
            if abs(b - a) < CROSSING_TOL * outer:
                break
        return float(b)  # the rise jumps across the threshold here (a kink), or it converged: b is past it

    step = max(FIRST_STEP * half if half is not None and math.isfinite(half) else 0.0, MIN_STEP)
    points = [(z[j], z.copy(), 0.0)]
    ends, unbounded, partner_move = [], [], np.zeros(z.size)
    def extend(walk, side, span):
        """Walk on from the walk's last point, steps growing by GROWTH: past the threshold too (a
        kink or a second valley can bring the cost back down), until the rise exceeds
        STOP_RISE thresholds (the cost has left the valley for good) or the bound."""
        while walk[-1][0] < span and walk[-1][2] < STOP_RISE * level_threshold:
            (prev_d, prev_x, _), back = walk[-1], walk[-2] if len(walk) > 1 else None
            d = min(step if prev_d == 0 else prev_d * GROWTH, span)
            predicted = None if back is None else prev_x + (prev_x - back[1]) * (d - prev_d) / (prev_d - back[0])
            x, c = refit(z[j] + side * d, prev_x, predicted)
            walk.append((d, x, (c - base) / s2))
            points.append((x[j], x, (c - base) / s2))

    for side, bound in ((-1.0, lower[j]), (1.0, upper[j])):
        span = abs(bound - z[j])
        walk = [(0.0, z.copy(), 0.0)]  # (distance, coordinates, rise) along this side
        end, open_side = bound, True
        while span > 0:
            extend(walk, side, span)
            last = [k for k, w in enumerate(walk) if w[2] < level_threshold][-1]
            if last == len(walk) - 1:  # below the threshold out to the bound
                break
            found = crossing(side, walk[last][0], walk[last][2], walk[last + 1][0], walk[last][1])
            if not isinstance(found, tuple):
                end, open_side = z[j] + side * found, False
                break
            # the walk's point past the threshold was a re-fit that lost the valley: go on from there
            outer = walk[last + 1][0]
            del walk[last + 1:]
            walk.append((outer, *found))
        if open_side and span > 0 and free.size:
            moved = np.abs(walk[-1][1][free] - z[free]) / np.maximum(upper[free] - lower[free], 1e-12)
            partner_move[free] = np.maximum(partner_move[free], moved)
        ends.append(end)
        unbounded.append(bool(open_side))
    points.sort(key=lambda p: p[0])
    zs = np.array([p[0] for p in points])
    rises = np.array([p[2] for p in points])
    path = np.array([p[1] for p in points])
    k = int(np.argmin(rises))
    drop = LOWER_BY * s2 if lower_by is None else lower_by
    lower_point = path[k].copy() if rises[k] * s2 < -drop else None
    partner = None
    if any(unbounded) and free.size and partner_move.max() > 0:
        partner = int(np.argmax(partner_move))
    return Profile(index=j, z=zs, rise=rises, path=path, threshold=float(level_threshold),
                   interval=(float(min(ends)), float(max(ends))), unbounded=tuple(unbounded), partner=partner,
                   lower=lower_point, evaluations=int(count[0]))



@dataclass(frozen=True, repr=False)
class ParameterProfile:
    """The profile of one fitted parameter, in its own units (a :class:`~.result.FitResult`
    carries one per parameter profiled).

    Attributes
    ----------
    key, unit : str
        Scene key path and SI unit.
    value : float
        The fitted value.
    values : numpy.ndarray
        The parameter held at these values (ascending) ...
    rise : numpy.ndarray
        ... and (RSS - RSS_min) / s^2 there, the other parameters fitted again.
    threshold : float
        The rise at the ends of the 95 % interval.
    interval : tuple of float
        The 95 % interval from the profile; the bound of the physical range on an
        unbounded side.
    unbounded : tuple of bool
        (lower side, upper side) on which the rise stays below the threshold to the bound.
    partner : str or None
        The parameter it trades against along an unbounded side.
    """

    key: str
    unit: str
    value: float
    values: np.ndarray
    rise: np.ndarray
    threshold: float
    interval: tuple
    unbounded: tuple
    partner: str | None

    @property
    def identified(self) -> bool:
        """True when the rise reaches the threshold on both sides."""
        return not any(self.unbounded)

    def to_dict(self) -> dict:
        """JSON-ready: key, unit, value, values, rise, threshold, interval, unbounded, partner."""
        return {"key": self.key, "unit": self.unit, "value": float(self.value),
                "values": [float(v) for v in self.values], "rise": [float(r) for r in self.rise],
                "threshold": self.threshold, "interval": [float(v) for v in self.interval],
                "unbounded": list(self.unbounded), "partner": self.partner}

    def __repr__(self) -> str:
        state = "identified" if self.identified else f"unbounded {'below' if self.unbounded[0] else 'above'}"
        return (f"<ParameterProfile {self.key}: 95 % [{self.interval[0]:.4g}, {self.interval[1]:.4g}] "
                f"{self.unit}; {state}>")

    def plot(self, ax=None):
        """The rise against the value, with the threshold and the fitted value. Returns the axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot(self.values, self.rise, "o-", ms=3, label="profile")
        ax.axhline(self.threshold, color="r", ls="--", label=f"95 % threshold ({self.threshold:.3g})")
        ax.axvline(self.value, color="k", lw=0.8, label="fitted")
        if np.all(self.values > 0):
            ax.set_xscale("log")
        top = max(3 * self.threshold, float(np.min(self.rise)) + 1.0)
        ax.set_ylim(min(0.0, float(np.min(self.rise))) - 0.05 * top, top)
        ax.set_xlabel(f"{self.key} [{self.unit}]")
        ax.set_ylabel("cost rise (RSS - RSS_min) / s^2 [-]")
        title = "identified" if self.identified else "not identified" + (
            f" (trades against {self.partner})" if self.partner else "")
        ax.set_title(f"{self.key}: {title}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        return ax
