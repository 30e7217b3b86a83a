"""Stability margins of a loop: every crossing, disk margin, Ms, closed-loop bandwidth and
phase at a given frequency (MATLAB ``allmargin`` in spirit), with python-control's
definitions and arithmetic on the toolkit's own state-space blocks (:mod:`servo_toolkit.lti`;
a python-control system is taken as well). The Nyquist count the closed-loop poles are
cross-checked with is :mod:`.nyquist`'s."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.output_units import REQUIREMENT_SINE_HZ
from ..lti.analysis import bandwidth
from ..lti.connect import feedback
from ..lti.system import as_system, ss
from .crossings import crossings, response_of
from .nyquist import _scale, nyquist_count


@dataclass(frozen=True, repr=False)
class Margins:
    """Margins of an open loop ``L`` with negative unit feedback; ``repr`` is one line.

    Attributes
    ----------
    gain_margins_db : tuple of float
        20 log10 of python-control's gain margin at every phase crossing (positive: the gain
        may rise by that much; negative: it may fall by that much).
    phase_crossover_hz : tuple of float
    phase_margins_deg : tuple of float
        At every gain crossing.
    gain_crossover_hz : tuple of float
    delay_margins_s : tuple of float
        At every gain crossing ``w_gc`` of a stable closed loop, the smallest pure delay that
        puts the loop through -1 there: ``(phase margin mod 360 deg, in rad) / w_gc`` (MATLAB
        ``allmargin``'s convention; a crossing with a negative phase margin has one too, as
        the delay must turn the loop clockwise by 360 deg + PM); NaN (JSON null) when the
        closed loop is unstable. See :func:`delay_margins`. Each is a delay at which
        closed-loop poles reach the imaginary axis; past the smallest the loop may regain
        stability (at a crossing where ``|L|`` rises) and lose it again.
    gain_margin_db, phase_margin_deg, delay_margin_s : float
        The smallest of each (``inf`` without a crossing); the gain margin is the smallest in
        magnitude. The smallest delay margin is the largest delay the loop tolerates: below
        it the closed loop stays stable, just above it is unstable. A margin is the distance
        of a stable closed loop to instability: for an unstable one every margin figure here
        (and the lower and upper gain margins, disk margin, Ms and bandwidth) is NaN, JSON
        null, and :attr:`unstable_reason` says why. The per-crossing lists
        (``gain_margins_db``, ``phase_margins_deg``) still give where ``L`` crosses and the
        gain or phase change that puts it through -1 there.
    disk_margin : float
        Balanced (skew 0) disk margin alpha, python-control's ``disk_margins``.
    disk_gain_margin_db, disk_phase_margin_deg : float
    sensitivity_peak_db : float
        Ms = max |1 / (1 + L)| (dB).
    bandwidth_hz : float
        -3 dB bandwidth of the closed loop (python-control's ``bandwidth``).
    phase_at_hz : float
        Frequency where the closed-loop phase is reported (Hz).
    phase_at_freq_deg : float
        Closed-loop phase there, unwrapped from low frequency (deg).
    closed_loop_stable : bool
        Every closed-loop pole in the open left half plane.
    max_closed_loop_pole_real : float
        Largest real part of the closed-loop poles (1/s).
    open_loop_rhp_poles : int
        Open-loop poles in the open right half plane (P of the Nyquist criterion).
    integrators : int
        Open-loop poles at the origin.
    nyquist_rhp_closed_loop_poles : int
        Closed-loop right-half-plane poles by the Nyquist criterion, Z = P + N (N clockwise
        encirclements of -1 by L along the imaginary axis, indented right of the axis poles);
        cross-checked against the closed-loop poles.
    lower_gain_margin_db, upper_gain_margin_db : float
        The smallest factor (dB) by which the gain may fall (a negative figure; ``-inf`` when
        no reduction destabilizes the loop) and rise (``inf`` when none) before the closed loop
        changes stability, over every crossing including w = 0 and w -> inf.
    notes : tuple of str
        Why a figure is left out (the margins of an unstable closed loop are NaN, JSON null),
        and any disagreement of the Nyquist count with the poles.
    unstable_closed_loop_poles : int
        Closed-loop poles with a real part of 0 or more (0 for a stable closed loop).
    """

    gain_margins_db: tuple
    phase_crossover_hz: tuple
    phase_margins_deg: tuple
    gain_crossover_hz: tuple
    delay_margins_s: tuple
    gain_margin_db: float
    phase_margin_deg: float
    delay_margin_s: float
    disk_margin: float
    disk_gain_margin_db: float
    disk_phase_margin_deg: float
    sensitivity_peak_db: float
    bandwidth_hz: float
    phase_at_hz: float
    phase_at_freq_deg: float
    closed_loop_stable: bool
    max_closed_loop_pole_real: float
    open_loop_rhp_poles: int = 0
    integrators: int = 0
    nyquist_rhp_closed_loop_poles: int = 0
    lower_gain_margin_db: float = -math.inf
    upper_gain_margin_db: float = math.inf
    notes: tuple = ()
    unstable_closed_loop_poles: int = 0

    @property
    def instability(self) -> str:
        """The unstable closed-loop poles in words ("" when the closed loop is stable)."""
        if self.closed_loop_stable:
            return ""
        n = self.unstable_closed_loop_poles
        return (f"{n} closed-loop pole{'' if n == 1 else 's'} in the right half-plane, the largest real part "
                f"{self.max_closed_loop_pole_real:.4g} 1/s")

    @property
    def unstable_reason(self) -> str:
        """Why the closed loop has no margins, in words ("" when it is stable)."""
        return f"closed loop unstable: {self.instability}" if not self.closed_loop_stable else ""

    def headline(self) -> str:
        """The margins in one line, or, for an unstable closed loop, that it has none."""
        if not self.closed_loop_stable:
            return ("margins: none (gain, phase, delay and disk margins, Ms and bandwidth describe a stable "
                    "closed loop only)")
        return (f"GM {self.gain_margin_db:.2f} dB, PM {self.phase_margin_deg:.1f} deg, delay margin "
                f"{self.delay_margin_s * 1e3:.3g} ms, disk margin {self.disk_margin:.3f}, "
                f"Ms {self.sensitivity_peak_db:.2f} dB")

    def __repr__(self) -> str:
        if not self.closed_loop_stable:
            return f"<Margins: {self.unstable_reason}>"
        return f"<Margins: {self.headline()}, bandwidth {self.bandwidth_hz:.3g} Hz>"

    def to_dict(self) -> dict:
        """JSON-ready (strict JSON), units in the key names; a figure that is not finite is None
        (JSON null): not defined (NaN: an unstable closed loop, ``unstable_reason`` and notes say
        why) or unbounded (inf: no crossing limits it, e.g. ``lower_gain_margin_db`` when no
        reduction of the gain destabilizes the loop, ``gain_margin_db`` without a phase
        crossover)."""
        from ..core.json_text import nulls
        d = dict(self.__dict__)
        d["unstable_reason"] = self.unstable_reason or None
        if self.phase_at_hz == REQUIREMENT_SINE_HZ:
            d["phase_at_8hz_deg"] = d.pop("phase_at_freq_deg")
        else:
            d["phase_at_8hz_deg"] = None
            d["phase_at_freq_deg"] = d.pop("phase_at_freq_deg")
        return nulls(d)

    def table(self) -> str:
        """Every crossing, as text (for an unstable closed loop, where ``L`` crosses and
        ``|L|`` or its phase there: no margins)."""
        if not self.closed_loop_stable:
            return "\n".join([
                "  phase crossings (not margins, the closed loop is unstable):  " + (", ".join(
                    f"|L| {-g:+.2f} dB at {f:.3g} Hz" for g, f in zip(self.gain_margins_db, self.phase_crossover_hz))
                    or "none"),
                "  gain crossings (not margins, the closed loop is unstable):   " + (", ".join(
                    f"phase {p - 180:.1f} deg at {f:.3g} Hz" for p, f in zip(self.phase_margins_deg,
                                                                          self.gain_crossover_hz)) or "none")])
        lines = ["  phase crossings:  " + (", ".join(f"{g:+.2f} dB at {f:.3g} Hz" for g, f in
                                                 zip(self.gain_margins_db, self.phase_crossover_hz)) or "none"),
                 "  gain crossings:   " + (", ".join(f"PM {p:.1f} deg, delay {d * 1e3:.3g} ms at {f:.3g} Hz"
                                                   for p, d, f in zip(self.phase_margins_deg, self.delay_margins_s,
                                                                      self.gain_crossover_hz)) or "none")]
        return "\n".join(lines)


def frequency_grid(f_min: float = 0.01, f_max: float = 5e3, points: int = 2000, extra=()) -> np.ndarray:
    """Log-spaced angular frequencies (rad/s) including ``extra`` frequencies (Hz)."""
    f = np.unique(np.concatenate([np.logspace(np.log10(f_min), np.log10(f_max), points),
                                  np.asarray(extra, float)]))
    return 2 * np.pi * f


def delay_margins(phase_margins_deg, gain_crossover, closed_loop_stable: bool) -> np.ndarray:
    """Delay margin (s) at every gain crossing.

    A delay ``tau`` turns ``L(jw)`` clockwise by ``w tau`` without changing ``|L|``, so the
    loop passes through -1 at a gain crossing ``w_gc`` when ``w_gc tau`` equals the phase
    margin modulo 360 deg; a stable closed loop stays stable for every delay below the
    smallest such ``tau`` over the crossings (closed-loop poles reach the imaginary axis only
    there). This is MATLAB ``allmargin``'s delay margin.

    Parameters
    ----------
    phase_margins_deg : array_like
        Phase margins (deg) at the gain crossings, python-control's convention (in
        [-180, 180)).
    gain_crossover : array_like
        Gain crossover frequencies (rad/s).
    closed_loop_stable : bool
        Without delay; an unstable closed loop has no delay margin (NaN at every crossing).

    Returns
    -------
    numpy.ndarray
        ``radians(pm mod 360) / w_gc``; ``inf`` at a crossing at ``w = 0`` with a
        nonzero margin (no delay moves ``L(0)``); NaN for an unstable closed loop.
    """
    pm = np.asarray(phase_margins_deg, float)
    wgc = np.asarray(gain_crossover, float)
    if not closed_loop_stable:
        return np.full_like(pm, np.nan)
    turn = np.radians(np.remainder(pm, 360.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(wgc > 0, turn / np.where(wgc > 0, wgc, 1.0), np.where(turn > 0, np.inf, 0.0))


#: relative size below which an open-loop pole counts as at the origin (an integrator)
ORIGIN_TOL = 1e-9


def _evaluate(loop, s):
    """L at complex frequencies ``s`` (SISO)."""
    with np.errstate(all="ignore"):
        return response_of(loop)(s)


def disk_margins(loop, omega):
    """python-control's balanced disk margins of a SISO loop on the grid ``omega`` (rad/s):
    ``control.disk_margins(loop, omega)`` (skew 0), its arithmetic per frequency, with the
    balanced sensitivity ``S - 1/2`` of a state-space loop evaluated at every frequency in
    one batched solve instead of one call per point; the same figures.

    Returns
    -------
    tuple of float
        Disk margin, disk-based gain margin (dB) and phase margin (deg).
    """
    loop = as_system(loop)
    if not loop.issiso():
        raise ValueError("disk margins of a SISO loop only")
    balanced = _balanced_sensitivity(loop)
    with np.errstate(all="ignore"):
        dm = 1.0 / np.abs(response_of(balanced)(1j * np.sort(np.array(omega, float, ndmin=1))))
        gamma_min = (1 - 0.5 * dm * (1 - 0.0)) / (1 + 0.5 * dm * (1 + 0.0))
        gamma_max = (1 + 0.5 * dm * (1 - 0.0)) / (1 - 0.5 * dm * (1 + 0.0))
        dgm = 20.0 * np.log10(np.minimum(1 / gamma_min, gamma_max))
        dgm[np.isnan(dgm)] = np.inf
        cos = (1 + gamma_min * gamma_max) / (gamma_min + gamma_max)
        dpm = np.where(np.isinf(gamma_max), 90.0, np.where(np.abs(cos) >= 1.0, np.inf, np.rad2deg(np.arccos(cos))))
    gm = np.inf if np.isinf(dgm).all() else dgm[np.where(dgm == np.min(dgm))][0]
    return np.amin(dm), gm, dpm[np.where(dpm == np.min(dpm))][0]


def _balanced_sensitivity(loop):
    """``S - 1/2`` of the SISO loop, ``S = 1 / (1 + L)``, as python-control builds it for its
    ``disk_margins`` (``ss(1).feedback(L) - 0.5``, with its ``feedback`` arithmetic), so the
    figures are python-control's to the last bit."""
    s = feedback(1.0, loop)
    return ss(s.A, s.B, s.C, s.D + 0.5 * (0.0 - 1))


def gain_crossings(loop, integrators: int, found=None):
    """Every gain margin (factor) and where (rad/s): the loop's own -180 deg crossings
    (:func:`.crossings.crossings`; never a root of rounded polynomial coefficients),
    w = 0 when L(0) is finite, real and negative (as for an open-loop-unstable plant), and
    w -> inf when L(inf) is real and negative. A crossing at w = 0 of a loop with
    integrators is L's asymptote, not a margin, and is left out. ``found`` is the result of
    :func:`.crossings.crossings` when the caller has it."""
    loop = as_system(loop)
    wpc, gm, _, _ = crossings(loop) if found is None else found
    keep = np.isfinite(gm) & (gm > 0)
    gm, wpc = list(gm[keep]), list(wpc[keep])
    if integrators == 0 and not any(x == 0 for x in wpc):
        l0 = _evaluate(loop, [0.0])[0]
        if np.isfinite(l0) and l0.real < 0 and abs(l0.imag) <= 1e-9 * abs(l0):
            gm.append(-1.0 / l0.real)
            wpc.append(0.0)
    d = loop.D.reshape(-1)
    if d.size == 1 and d[0] < 0:
        gm.append(-1.0 / d[0])
        wpc.append(math.inf)
    order = np.argsort(wpc)
    return np.asarray(gm, float)[order], np.asarray(wpc, float)[order]


def loop_margins(loop, closed_loop, phase_hz: float = REQUIREMENT_SINE_HZ, omega=None) -> Margins:
    """Margins of the SISO open loop ``loop`` and its SISO closed loop ``closed_loop``,
    on the Nyquist criterion (MATLAB ``allmargin`` semantics).

    Every gain margin is reported, crossings at w = 0 and w -> inf included, lower (a
    negative figure in dB: the gain may fall that much) and upper; stability is that of
    the closed-loop poles, cross-checked with the Nyquist count of the open loop's
    encirclements of -1 (a disagreement is noted). Disk margin and Ms describe a stable
    closed loop only; for an unstable one they are NaN and the notes say why.

    Parameters
    ----------
    loop : control.LTI
        Open loop, negative unit feedback.
    closed_loop : control.LTI
        Reference to output, for the bandwidth and the phase at ``phase_hz``.
    phase_hz : float
        Frequency of the reported closed-loop phase (Hz).
    omega : array_like, optional
        Grid (rad/s) for the disk margin and Ms; default 0.01 Hz .. 5 kHz.
    """
    if not (math.isfinite(phase_hz) and phase_hz > 0):
        raise ValueError(f"phase_hz must be a positive frequency (got {phase_hz!r})")
    omega = frequency_grid(extra=[phase_hz]) if omega is None else np.asarray(omega, float)
    loop, closed_loop = as_system(loop), as_system(closed_loop)
    ol_poles = loop.poles()
    scale = _scale(ol_poles, loop.zeros())
    at_origin = np.abs(ol_poles) <= ORIGIN_TOL * scale
    integrators = int(np.sum(at_origin))
    rhp = int(np.sum((ol_poles.real > ORIGIN_TOL * scale) & ~at_origin))
    found = crossings(loop)
    gm, wpc = gain_crossings(loop, integrators, found)
    gm_db = 20 * np.log10(gm)
    _, _, wgc, pm = found
    poles = closed_loop.poles()
    stable = bool(np.all(poles.real < 0))
    notes = []
    z = nyquist_count(loop, rhp)
    if (z == 0) != stable:
        notes.append(f"the Nyquist count ({z} closed-loop right-half-plane poles from P = {rhp} and the "
                     f"encirclements of -1) disagrees with the closed-loop poles (largest real part "
                     f"{float(np.max(poles.real)):.4g} 1/s); the poles decide")
    if stable:
        lw = _evaluate(loop, 1j * omega)
        with np.errstate(divide="ignore"):
            ms = float(20 * np.log10(np.max(np.abs(1 / (1 + lw)))))
        try:
            dmarg, dgm, dpm = (float(x) for x in disk_margins(loop, omega))
        except (ValueError, np.linalg.LinAlgError) as exc:  # 1 + L(inf) = 0: no proper sensitivity
            dmarg = dgm = dpm = math.nan
            notes.append(f"the disk margin could not be computed ({exc})")
    else:
        dmarg = dgm = dpm = ms = math.nan
        notes.append("gain, phase, delay and disk margins, sensitivity peak Ms and bandwidth are not defined for "
                     "an unstable closed loop")
    dm = delay_margins(pm, wgc, stable)
    try:
        bw = bandwidth(closed_loop) if stable else math.nan
    except Exception:  # noqa: BLE001 - python-control raises on degenerate loops
        bw = math.nan
        notes.append("the closed-loop bandwidth could not be computed")
    bw = float(bw) / (2 * np.pi) if np.isfinite(bw) else math.inf if stable else math.nan
    w_ph = omega[omega <= 2 * np.pi * phase_hz * (1 + 1e-12)]
    t = _evaluate(closed_loop, 1j * w_ph)
    phase = float(np.degrees(np.unwrap(np.angle(t)))[-1])
    order = np.argsort(np.abs(gm_db)) if gm_db.size else []
    lower, upper = gm_db[gm_db < 0], gm_db[gm_db > 0]
    nan = math.nan
    return Margins(
        gain_margins_db=tuple(float(x) for x in gm_db), phase_crossover_hz=tuple(float(x) for x in wpc / (2 * np.pi)),
        phase_margins_deg=tuple(float(x) for x in pm), gain_crossover_hz=tuple(float(x) for x in wgc / (2 * np.pi)),
        delay_margins_s=tuple(float(x) for x in dm),
        gain_margin_db=(float(gm_db[order[0]]) if gm_db.size else math.inf) if stable else nan,
        phase_margin_deg=(float(pm.min()) if pm.size else math.inf) if stable else nan,
        delay_margin_s=(float(dm.min()) if dm.size else math.inf) if stable else nan,
        disk_margin=dmarg, disk_gain_margin_db=dgm, disk_phase_margin_deg=dpm,
        sensitivity_peak_db=ms, bandwidth_hz=bw, phase_at_hz=float(phase_hz), phase_at_freq_deg=phase,
        closed_loop_stable=stable, max_closed_loop_pole_real=float(np.max(poles.real)) if poles.size else -math.inf,
        open_loop_rhp_poles=rhp, integrators=integrators, nyquist_rhp_closed_loop_poles=z,
        lower_gain_margin_db=(float(lower.max()) if lower.size else -math.inf) if stable else nan,
        upper_gain_margin_db=(float(upper.min()) if upper.size else math.inf) if stable else nan, notes=tuple(notes),
        unstable_closed_loop_poles=int(np.sum(poles.real >= 0)))
