"""A crossing of the open loop found between two measured points (``--plant-frf``), with its
margin's 95 % interval (:mod:`.measured_interval`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .measured_interval import Z95, interval


@dataclass(frozen=True)
class Crossing:
    """A crossing of the open loop found between two measured points.

    Attributes
    ----------
    kind : {"gain", "phase"}
        ``|L| = 1`` (its margin a phase margin, deg) or ``arg L = -180 deg`` (a gain margin, dB).
    frequency_hz : float
        Interpolated between the two points.
    low_hz, high_hz : float
        The measured points that bracket it (the grid's resolution there).
    margin : float
        Phase margin (deg) or gain margin (dB).
    coherence : float
        The lower coherence of the two points.
    poor : bool
        The coherence is poor: the crossing is shown, never decides a requirement.
    source : {"measured", "model"}
        ``model``: a phase crossing of the model's loop outside the measured band.
    sd : float or None
        The margin's standard deviation from the estimate's random error (deg or dB;
        :mod:`.measured_interval`); None: not known.
    quantile : float
        The 95 % interval's half width in standard deviations.
    """

    kind: str
    frequency_hz: float
    low_hz: float
    high_hz: float
    margin: float
    coherence: float
    poor: bool
    source: str = "measured"
    sd: float | None = None
    quantile: float = Z95

    @property
    def unit(self) -> str:
        """The margin's unit."""
        return "deg" if self.kind == "gain" else "dB"

    @property
    def interval(self) -> tuple[float, float] | None:
        """The margin's 95 % interval (None: no standard deviation known)."""
        return interval(self.margin, self.sd, self.quantile)

    def text(self) -> str:
        """One line: margin, where, between which points, and a mark for poor coherence."""
        name = "PM" if self.kind == "gain" else "GM"
        where = (f"{self.frequency_hz:.4g} Hz (model, outside the measured band)" if self.source == "model" else
                 f"{self.frequency_hz:.4g} Hz (between {self.low_hz:.4g} and {self.high_hz:.4g} Hz)")
        mark = f"  [poor coherence {self.coherence:.2f}: not used]" if self.poor else ""
        ci = self.interval
        spread = "" if ci is None else f" (95 %: {ci[0]:+.2f} .. {ci[1]:+.2f} {self.unit})"
        return f"{name} {self.margin:+.2f} {self.unit}{spread} at {where}{mark}"

    def to_dict(self) -> dict:
        """JSON-ready, units in the key names."""
        key = "phase_margin_deg" if self.kind == "gain" else "gain_margin_db"
        ci = self.interval
        return {"kind": self.kind, "frequency_hz": self.frequency_hz, "between_hz": [self.low_hz, self.high_hz],
                key: self.margin, f"{key}_sd": None if self.sd is None or math.isnan(self.sd) else self.sd,
                f"{key}_interval95": None if ci is None else list(ci),
                "coherence": self.coherence, "poor_coherence": self.poor, "source": self.source}


def interval_text(bounds) -> str:
    """A 95 % interval as text (empty without one)."""
    return "" if bounds is None else f"{bounds[0]:.4g} .. {bounds[1]:.4g}"


__all__ = ["Crossing", "interval_text"]
