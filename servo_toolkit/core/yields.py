"""Yield: the fraction of built actuators that meet a requirement, with its exact
(Clopper-Pearson) confidence interval.

Of ``n`` variants drawn from the tolerances, ``k`` meet the requirement. The interval is
scipy's ``binomtest(k, n).proportion_ci(confidence_level, method="exact")``: it covers the
true yield with at least the stated probability for independent draws, whatever the yield
(it is conservative: its coverage is at or above the level). A Latin hypercube or a
scrambled Sobol sample estimates a fraction with a variance no larger than independent
draws do (up to n/(n-1) for a Latin hypercube), so the interval stays conservative for
them. A gate on a required yield uses the interval's *lower* end: with 0.99 required and a
95 % interval, at least 368 variants must all pass before any sample can prove it (:func:`minimum_samples`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The exact two-sided interval of a binomial proportion ``k / n``.

    Parameters
    ----------
    k, n : int
        Successes and trials, 0 <= k <= n, n >= 1.
    confidence : float
        Two-sided confidence level in (0, 1).

    Returns
    -------
    (low, high) : tuple of float
    """
    from scipy.stats import binomtest
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=float(confidence), method="exact")
    return float(ci.low), float(ci.high)


def minimum_samples(min_yield: float, confidence: float = 0.95) -> int:
    """The fewest variants that, all passing, give an interval whose lower end reaches
    ``min_yield``: the smallest n with ((1 - confidence) / 2) ** (1 / n) >= min_yield."""
    if min_yield <= 0:
        return 1
    if min_yield >= 1:
        return math.inf
    return int(math.ceil(math.log((1 - confidence) / 2) / math.log(min_yield)))


@dataclass(frozen=True)
class Yield:
    """The yield of one requirement (or of all of them together).

    Attributes
    ----------
    name : str
        Requirement name (``"all"`` for every requirement at once).
    label : str
        In words.
    passed, total : int
        Variants meeting it, variants judged.
    confidence : float
    low, high : float
        Clopper-Pearson interval of the yield.
    required : float or None
        Required yield (None: reported, not gated).
    """

    name: str
    label: str
    passed: int
    total: int
    confidence: float
    low: float
    high: float
    required: float | None = None

    @classmethod
    def of(cls, name: str, label: str, passed: int, total: int, confidence: float = 0.95,
           required: float | None = None) -> "Yield":
        """The yield of ``passed`` out of ``total`` with its interval."""
        low, high = clopper_pearson(passed, total, confidence)
        return cls(name, label, int(passed), int(total), float(confidence), low, high, required)

    @property
    def fraction(self) -> float:
        """The point estimate passed / total."""
        return self.passed / self.total

    @property
    def met(self) -> bool:
        """The interval's lower end reaches the required yield (True when none is
        required)."""
        return self.required is None or self.low >= self.required

    def shortfall(self) -> str:
        """Why the required yield is not met, in words ("" when it is met or none is
        required): a sample too small to show it (every variant passing), a point estimate
        that reaches it with an interval that does not, or too few variants passing."""
        if self.met:
            return ""
        req, conf = f"{100 * self.required:g} %", f"{100 * self.confidence:g} %"
        need = minimum_samples(self.required, self.confidence)
        if self.passed == self.total:
            return (f"every variant passes, but {self.total} variants cannot show {req} at {conf} confidence "
                    f"(the interval's lower end is {100 * self.low:.4g} %): at least {need} variants, all passing, "
                    f"are needed (samples = {need})")
        if self.fraction >= self.required:
            return (f"the point estimate {100 * self.fraction:.4g} % reaches {req} but the interval's lower end "
                    f"{100 * self.low:.4g} % does not: more variants narrow the interval")
        return f"{self.total - self.passed} of {self.total} variants fail: the yield is below {req}"

    def text(self) -> str:
        """E.g. ``99.4 % (97.9..99.9 %, 95 % interval; 994 of 1000)``."""
        return (f"{100 * self.fraction:.4g} % ({100 * self.low:.4g}..{100 * self.high:.4g} %, "
                f"{100 * self.confidence:g} % interval; {self.passed} of {self.total})")

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"name": self.name, "label": self.label, "passed": self.passed, "total": self.total,
                "fraction": self.fraction, "confidence": self.confidence, "low": self.low, "high": self.high,
                "required": self.required, "met": self.met, "shortfall": self.shortfall()}


__all__ = ["Yield", "clopper_pearson", "minimum_samples"]
