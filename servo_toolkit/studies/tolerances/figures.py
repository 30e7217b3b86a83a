"""What a tolerance study judges each variant on: the linear study's figure of each margin
requirement, whether a figure meets its requirement and by how much (relative to its limit),
the time runs' figures in their requirements' units, and which failed runs failed by their
physics."""

from __future__ import annotations

import math

import numpy as np

#: margin requirement -> (figure of the linear study, label)
FIGURES = {"gain_margin": ("gain_margin_db", "gain margin"), "phase_margin": ("phase_margin_deg", "phase margin"),
           "sensitivity_peak": ("sensitivity_peak_db", "sensitivity peak Ms"),
           "bandwidth": ("bandwidth_hz", "closed-loop bandwidth"),
           "phase_lag_at_bandwidth": ("phase_lag_deg", "phase lag at the bandwidth")}


def meets(r, y):
    """Per value of ``y``: it meets requirement ``r`` (NaN never meets it)."""
    with np.errstate(invalid="ignore"):
        return (y >= r.value) if r.sense == ">=" else (y <= r.value) & np.isfinite(y)


def relative_margin(r, y):
    """(achieved - required) / |required| in the requirement's sense (positive: met)."""
    scale = abs(r.value) if r.value else 1.0
    with np.errstate(invalid="ignore"):
        return ((y - r.value) if r.sense == ">=" else (r.value - y)) / scale


def time_shown(scene, runs) -> dict:
    """The time runs' figures in the units of their requirements (deg or mm; A)."""
    return {"tracking_error": runs.tracking_error * (1e3 if scene.drivetrain.output_is_linear else 180 / math.pi),
            "peak_current": runs.peak_current}


def physical_failures(runs, stable) -> np.ndarray:
    """Which failed runs failed by their physics: the stroke end reached, or a divergence
    with an unstable linear loop."""
    reasons = np.array(runs.reasons, dtype=object)
    stroke = np.array([r.startswith("stroke end reached") for r in reasons], bool)
    diverged = np.array([r.startswith("non-finite state") for r in reasons], bool) & ~np.asarray(stable, bool)
    return runs.failed & (stroke | diverged)


__all__ = ["FIGURES", "meets", "physical_failures", "relative_margin", "time_shown"]
