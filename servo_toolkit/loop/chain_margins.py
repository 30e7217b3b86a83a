"""A loop designed on the two-mass plant, checked on the n-mass plant of the drivetrain chain.

Loop design, margins and ``check`` use the chain's two-mass reduction (its lowest mode). The
modes above the first are lumped there; :func:`chain_margins` takes the same controller's
margins on the chain plant (:func:`servo_toolkit.plant.chain_plant.chain_plant`, every mode)
and says so in the design's notes when a lumped mode lies within :data:`MODE_FACTOR` times the
loop's gain crossover, or when the n-mass plant changes the gain margin or the sensitivity
peak by more than :data:`GAIN_TOL_DB`, the phase margin by more than :data:`PHASE_TOL_DEG`, or
the closed loop's stability.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..drivetrain.chain_damping import kept_nodes
from .closed_loop import closed_loop_block, open_loop_block
from .margins import Margins, frequency_grid, loop_margins

#: a lumped mode below this multiple of the loop's gain crossover is near the loop
MODE_FACTOR = 10.0
#: change of the gain margin or of the sensitivity peak (dB) the notes report
GAIN_TOL_DB = 1.0
#: change of the phase margin (deg) the notes report
PHASE_TOL_DEG = 3.0


def _change(a: float, b: float) -> float:
    """b - a, 0 when both are the same infinity."""
    if math.isinf(a) and math.isinf(b) and (a > 0) == (b > 0):
        return 0.0
    return b - a


@dataclass(frozen=True)
class ChainMargins:
    """The two-mass design's controller on the n-mass plant.

    Attributes
    ----------
    modes_hz : tuple of float
        The chain's modes above the first (the ones the two-mass plant lumps).
    margins : Margins
        On the n-mass plant.
    gain_change_db, phase_change_deg, peak_change_db : float
        n-mass minus two-mass: gain margin, phase margin, sensitivity peak.
    near : tuple of float
        The lumped modes below :data:`MODE_FACTOR` times the loop's highest gain crossover.
    note : str or None
        What the design notes say (None: the lumped modes change nothing worth saying).
    """

    modes_hz: tuple
    margins: Margins
    gain_change_db: float
    phase_change_deg: float
    peak_change_db: float
    near: tuple
    note: str | None

    def to_dict(self) -> dict:
        """JSON-ready."""
        m = self.margins
        return {"modes_hz": list(self.modes_hz), "gain_margin_db": m.gain_margin_db,
                "phase_margin_deg": m.phase_margin_deg, "sensitivity_peak_db": m.sensitivity_peak_db,
                "closed_loop_stable": m.closed_loop_stable, "unstable_reason": m.unstable_reason or None,
                "gain_change_db": self.gain_change_db,
                "phase_change_deg": self.phase_change_deg, "peak_change_db": self.peak_change_db,
                "near_modes_hz": list(self.near), "note": self.note}


def chain_margins(scene, controller, q0: float, damping: float, two_mass: Margins, phase_hz: float,
                  f_req: float) -> ChainMargins | None:
    """The controller's margins on the n-mass plant at ``q0`` against ``two_mass`` (the design
    plant's); None for a chain with one mode.

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    q0 : float
    damping : float
        Damping ratio of each compliance whose stage gives none.
    two_mass : Margins
        The margins on the two-mass plant.
    phase_hz, f_req : float
        The frequencies the margins' grid must hold (as the design's).
    """
    chain = scene.drivetrain.chain
    if chain.rigid or kept_nodes(chain, q0).size <= 2:
        return None
    modes = tuple(float(m) for m in chain.eigenfrequencies(q0, driving=True)[1:] / (2 * math.pi))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loop = open_loop_block(scene, controller, q0, "chain", damping)
        cl = closed_loop_block(scene, controller, q0, "chain", damping)["theta", "theta_ref"]
    mg = loop_margins(loop, cl, phase_hz=phase_hz, omega=frequency_grid(extra=[phase_hz, f_req, *modes]))
    d_gain = _change(two_mass.gain_margin_db, mg.gain_margin_db)
    d_phase = _change(two_mass.phase_margin_deg, mg.phase_margin_deg)
    d_peak = _change(two_mass.sensitivity_peak_db, mg.sensitivity_peak_db)
    crossover = max(two_mass.gain_crossover_hz, default=math.nan)
    near = tuple(m for m in modes if math.isfinite(crossover) and m < MODE_FACTOR * crossover)
    changed = (abs(d_gain) > GAIN_TOL_DB or abs(d_peak) > GAIN_TOL_DB or abs(d_phase) > PHASE_TOL_DEG
               or not np.isfinite([d_gain, d_phase, d_peak]).all()
               or mg.closed_loop_stable != two_mass.closed_loop_stable)
    note = None
    if near or changed:
        where = (f"{_hz(near)} within {MODE_FACTOR:g}x the loop's crossover {crossover:.3g} Hz" if near else
                 f"{_hz(modes)}")
        head = f"the drivetrain modes above the first, lumped in the design plant ({where}), checked on the n-mass plant"
        if not mg.closed_loop_stable:
            note = (f"{head}: the closed loop is UNSTABLE on the n-mass plant ({mg.instability}; "
                    + ("as on the two-mass plant)" if not two_mass.closed_loop_stable else "stable on the two-mass plant)"))
        else:
            note = (f"{head}: gain margin {mg.gain_margin_db:.3g} dB (two-mass {two_mass.gain_margin_db:.3g}), "
                    f"phase margin {mg.phase_margin_deg:.3g} deg ({two_mass.phase_margin_deg:.3g}), sensitivity peak "
                    f"{mg.sensitivity_peak_db:.3g} dB ({two_mass.sensitivity_peak_db:.3g})")
    return ChainMargins(modes, mg, d_gain, d_phase, d_peak, near, note)


def _hz(values) -> str:
    return ", ".join(f"{v:.4g}" for v in values) + " Hz"


__all__ = ["ChainMargins", "GAIN_TOL_DB", "MODE_FACTOR", "PHASE_TOL_DEG", "chain_margins"]
