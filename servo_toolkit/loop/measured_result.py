"""The result of a loop closed on a measured plant response (:mod:`.measured`): the loop's
crossings, margins, Ms, bandwidth and the model's response beside the measured one."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .measured_crossing import Crossing, interval_text
from .measured_interval import basis_note, combined, interval, near_approach, quantile, sensitivity_sd_db

#: at most this many bands in the table of the model's mismatch
BANDS = 6
#: a point whose phase is within this (deg) of 180 deg off the model's counts as reversed
REVERSED_WITHIN_DEG = 45.0
#: more than this fraction of the good points reversed: a reversed sensor or drive sign
REVERSED_MOST = 0.5


def mismatch_bands(f, measured, model, coherence, poor: float, bands: int = BANDS) -> tuple:
    """The model's response against the measured one per log-spaced band of the measured
    range: ``(lo_hz, hi_hz, points, poor points, mean and largest |dB|, mean and largest
    |deg|)``, the figures over the points of good coherence (NaN when a band has none)."""
    edges = np.geomspace(f[0], f[-1], min(bands, max(1, len(f) // 3)) + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(model) / np.asarray(measured)
    db = 20 * np.log10(np.abs(ratio))
    deg = np.degrees(np.angle(ratio))
    out = []
    for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        inside = (f >= lo) & ((f < hi) if k < len(edges) - 2 else (f <= hi))
        good = inside & (coherence >= poor)
        n_in, n_good = int(inside.sum()), int(good.sum())
        if not n_in:
            continue
        stats = ((float(np.mean(np.abs(db[good]))), float(np.max(np.abs(db[good]))),
                  float(np.mean(np.abs(deg[good]))), float(np.max(np.abs(deg[good])))) if n_good
                 else (math.nan,) * 4)
        out.append((float(lo), float(hi), n_in, n_in - n_good) + stats)
    return tuple(out)


def reversed_points(measured, model, good) -> tuple[int, int]:
    """``(reversed, good)``: the points of good coherence (mask ``good``) whose measured
    phase lies within :data:`REVERSED_WITHIN_DEG` of 180 deg off the model's, and their number."""
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.degrees(np.abs(np.angle(np.asarray(measured)[good] / np.asarray(model)[good])))
    return int(np.sum(off >= 180.0 - REVERSED_WITHIN_DEG)), int(np.sum(good))


def sign_reversed(n: int, good: int) -> bool:
    """More than :data:`REVERSED_MOST` of the ``good`` points reversed (``n``): the measured
    phase is about 180 deg off the model's over most of the band, a reversed sign."""
    return good > 0 and n > REVERSED_MOST * good


def _first_below(f, mag, level, coherence, poor):
    """First frequency where ``mag`` falls below ``level``, interpolated log-log, with the
    bracket's coherence: ``(f or None, poor, why)``."""
    below = np.flatnonzero(mag < level)
    if not below.size:
        return None, False, f"|T| stays above -3 dB up to {f[-1]:.4g} Hz, the last measured point"
    j = int(below[0])
    if j == 0:
        return None, False, f"|T| is below -3 dB at {f[0]:.4g} Hz, the first measured point"
    x0, x1 = np.log10(f[j - 1]), np.log10(f[j])
    y0, y1, yl = np.log10(mag[j - 1]), np.log10(mag[j]), np.log10(level)
    fc = float(10 ** (x0 + (x1 - x0) * (yl - y0) / (y1 - y0)))
    return fc, bool(min(coherence[j - 1], coherence[j]) < poor), f"between {f[j - 1]:.4g} and {f[j]:.4g} Hz"


@dataclass(frozen=True)
class MeasuredLoop:
    """The design's loop on a measured plant response, beside the model's.

    Attributes
    ----------
    frequency_hz, response, model_response, coherence : numpy.ndarray
        The measured frequencies (Hz), the measured and the model's response from the motor
        current to :attr:`signal`, the coherence.
    loop, model_loop, closed, model_closed : numpy.ndarray
        Open loop ``L`` and closed loop ``T`` (reference to output) on the measured response
        and on the model's, at the same frequencies.
    signal : str
        The measured signal's column (``motor_angle_rad``, ...).
    source : str or None
    gain_crossings, phase_crossings : tuple of Crossing
        Every crossing; phase crossings of the model outside the band marked ``model``.
    closed_loop_rhp_poles : int or None
        Closed-loop right-half-plane poles by the Nyquist count on the data (None: not
        decided; :attr:`nyquist_note` says why and on what basis).
    nyquist_note : str
    poor_coherence : float
        The coherence below which a point never decides.
    reference_gain : float
        ``|T(0)|`` of the model, the bandwidth's 0 dB.
    required_bandwidth_hz : float or None
        Where the closed-loop phase lag is read.
    model_margins : Margins
        The model's own margins (python-control, continuous).
    bands : tuple
        :func:`mismatch_bands`.
    mode, model_mode : MeasuredMode or None
        The drivetrain mode read off the measured response and off the model's at the same
        points (:mod:`.measured_mode`).
    transmission_ratio : float
        The model's output transmission's mode moved by this factor (1: the model's).
    averages : int or None
        The spectra averaged behind the coherence (None: unknown).
    loop_sd : numpy.ndarray or None
        Standard deviation of ``ln L`` at each point from the estimate's random error
        (:mod:`.measured_interval`; None: ``averages`` unknown).
    loop_sd_resolution : numpy.ndarray or None
        The same from the logged signals' rounding (None: none recorded, or no ``loop_sd``).
    """

    frequency_hz: np.ndarray
    response: np.ndarray
    model_response: np.ndarray
    coherence: np.ndarray
    loop: np.ndarray
    model_loop: np.ndarray
    closed: np.ndarray
    model_closed: np.ndarray
    signal: str
    source: str | None
    gain_crossings: tuple
    phase_crossings: tuple
    closed_loop_rhp_poles: int | None
    nyquist_note: str
    poor_coherence: float
    reference_gain: float
    required_bandwidth_hz: float | None
    model_margins: object
    bands: tuple
    mode: object = None
    model_mode: object = None
    transmission_ratio: float = 1.0
    averages: int | None = None
    loop_sd: np.ndarray | None = None
    loop_sd_resolution: np.ndarray | None = None

    @property
    def poor(self) -> np.ndarray:
        """Points of poor coherence."""
        return self.coherence < self.poor_coherence

    @property
    def stable(self) -> bool | None:
        """The closed loop on the data is stable (None: not decided)."""
        return None if self.closed_loop_rhp_poles is None else self.closed_loop_rhp_poles == 0

    @property
    def phase_margin_crossing(self):
        """The crossing of good coherence with the smallest phase margin (None: none)."""
        return min((c for c in self.gain_crossings if not c.poor), key=lambda c: c.margin, default=None)

    @property
    def gain_margin_crossing(self):
        """The crossing of good coherence (or the model's outside the band) with the gain
        margin smallest in magnitude (None: none)."""
        return min((c for c in self.phase_crossings if not c.poor), key=lambda c: abs(c.margin), default=None)

    @property
    def phase_margin_deg(self) -> float:
        """Smallest phase margin over the crossings of good coherence (NaN: none)."""
        c = self.phase_margin_crossing
        return math.nan if c is None else float(c.margin)

    @property
    def gain_margin_db(self) -> float:
        """Gain margin smallest in magnitude over the phase crossings of good coherence and
        the model's outside the band (``inf`` without one; NaN when every crossing is poor)."""
        c = self.gain_margin_crossing
        if c is None:
            return math.nan if self.phase_crossings else math.inf
        return float(c.margin)

    @property
    def sensitivity_peak_interval(self) -> tuple[float, float] | None:
        """95 % interval of Ms (dB) at the point where it peaks (None: not known)."""
        ms, at = self.sensitivity_peak
        if self.loop_sd is None or not math.isfinite(ms):
            return None
        j = int(np.flatnonzero(self.frequency_hz == at)[0])
        rounding = 0.0 if self.loop_sd_resolution is None else float(self.loop_sd_resolution[j])
        sd, q = combined(float(self.loop_sd[j]), rounding, self.averages)
        return interval(ms, float(sensitivity_sd_db(self.loop[j], sd)), q)

    def _margin_interval(self, crossing, kind: str):
        """The deciding crossing's interval, its lower end taken down to a near approach's
        (:func:`.measured_interval.near_approach`)."""
        bounds = None if crossing is None else crossing.interval
        if bounds is None:
            return None
        crossings = self.gain_crossings if kind == "gain" else self.phase_crossings
        sd = self.loop_sd if self.loop_sd_resolution is None else np.hypot(self.loop_sd, self.loop_sd_resolution)
        low = near_approach(self.frequency_hz, self.loop, sd, ~self.poor, crossings, kind, quantile(self.averages))
        return bounds if low is None or low >= bounds[0] else (low, bounds[1])

    def intervals(self) -> dict:
        """The 95 % intervals of the figures that have one (gain margin dB, phase margin deg,
        Ms dB; None where not known)."""
        return {"gain margin": self._margin_interval(self.gain_margin_crossing, "phase"),
                "phase margin": self._margin_interval(self.phase_margin_crossing, "gain"),
                "sensitivity peak Ms": self.sensitivity_peak_interval}

    @property
    def reversed_points(self) -> tuple[int, int]:
        """:func:`reversed_points` of the measured response against the model's."""
        return reversed_points(self.response, self.model_response, ~self.poor)

    @property
    def sign_reversed(self) -> bool:
        """:func:`sign_reversed` of the measured response against the model's."""
        return sign_reversed(*self.reversed_points)

    def _ms(self, points) -> tuple[float, float]:
        s = np.abs(1.0 / (1.0 + self.loop))
        if not points.any():
            return math.nan, math.nan
        j = int(np.argmax(np.where(points, s, -np.inf)))
        return float(20 * np.log10(s[j])), float(self.frequency_hz[j])

    @property
    def sensitivity_peak(self) -> tuple[float, float]:
        """Ms (dB) and where (Hz), over the points of good coherence."""
        return self._ms(~self.poor)

    @property
    def poor_sensitivity_peak(self) -> tuple[float, float]:
        """Largest ``|1 / (1 + L)|`` (dB) over the points of poor coherence, and where."""
        return self._ms(self.poor)

    @property
    def bandwidth(self) -> tuple:
        """``(Hz or None, poor, where)``: the closed loop's -3 dB from the model's ``|T(0)|``."""
        return _first_below(self.frequency_hz, np.abs(self.closed), self.reference_gain / math.sqrt(2),
                            self.coherence, self.poor_coherence)

    def closed_phase_at(self, hz: float) -> tuple:
        """``(deg or None, poor)``: the closed loop's phase at ``hz``, unwrapped along the
        points from the branch of the model's at the first point."""
        f = self.frequency_hz
        if not f[0] <= hz <= f[-1]:
            return None, False
        ph = np.degrees(np.unwrap(np.angle(self.closed)))
        start = float(np.degrees(np.angle(self.model_closed[0])))
        ph += 360.0 * round((start - ph[0]) / 360.0)
        j = int(min(max(np.searchsorted(f, hz), 1), f.size - 1))
        x = np.log10(hz)
        x0, x1 = np.log10(f[j - 1]), np.log10(f[j])
        value = float(ph[j - 1] + (ph[j] - ph[j - 1]) * (x - x0) / (x1 - x0))
        return value, bool(min(self.coherence[j - 1], self.coherence[j]) < self.poor_coherence)

    def notes(self) -> tuple:
        """What the figures leave out and on what they rest."""
        f = self.frequency_hz
        out = [f"measured: the response from the motor current to {self.signal}, {f.size} points from "
               f"{f[0]:.4g} to {f[-1]:.4g} Hz; the controller, the sampling delay, the current loop's "
               "electrical side" + ("" if self.signal.startswith("output_") else " and the output's transmission")
               + " are the model's",
               "crossings interpolated between measured points (log |L| and unwrapped phase linear in log f), "
               "each with the two points bracketing it; Ms is the largest over the measured points and may be "
               "higher between them",
               basis_note(self.averages, self.loop_sd_resolution is not None), f"Nyquist: {self.nyquist_note}"]
        if self.sign_reversed:
            n, good = self.reversed_points
            out.insert(0, f"SIGN: the measured phase is 180 deg off the model's (within {REVERSED_WITHIN_DEG:g} deg) at "
                          f"{n} of {good} points of good coherence: a reversed sensor or drive sign (the encoder's "
                          "counting direction, the motor's leads or the logged current's sign); the figures are those "
                          "of the loop as logged")
        if self.transmission_ratio != 1.0 and self.mode is not None:
            what = "anti-resonance" if self.mode.antiresonance_hz is not None else "resonance"
            seen, model = ((self.mode.antiresonance_hz, self.model_mode.antiresonance_hz) if what == "anti-resonance"
                           else (self.mode.resonance_hz, self.model_mode.resonance_hz))
            other = "the motor speed" if self.signal.startswith("output_") else "the output"
            out.append(f"the measured {what} lies at {seen:.4g} Hz, the model's at {model:.4g} Hz "
                       f"({100 * (self.transmission_ratio - 1):+.1f} %): the model's transmission to {other}, "
                       f"which the rig did not log, is taken with its mode moved alike (a stiffness error)")
        n_poor = int(self.poor.sum())
        if n_poor:
            out.append(f"{n_poor} of {f.size} points have a coherence below {self.poor_coherence:g}: shown and "
                       "marked, they decide no requirement")
            peak, at = self.poor_sensitivity_peak
            if math.isfinite(peak) and peak > self.sensitivity_peak[0]:
                out.append(f"a point of poor coherence shows |1/(1+L)| of {peak:.2f} dB at {at:.4g} Hz, above the "
                           "Ms of the good points: not used")
        return tuple(out)

    def to_dict(self) -> dict:
        """JSON-ready, units in the key names (a figure not decided is None)."""
        def num(x):
            return None if x is None or (isinstance(x, float) and math.isnan(x)) else x
        ms, ms_hz = self.sensitivity_peak
        bw, bw_poor, bw_where = self.bandwidth
        return {"source": self.source, "signal": self.signal, "input": "current_A", "points": int(self.frequency_hz.size),
                "band_hz": [float(self.frequency_hz[0]), float(self.frequency_hz[-1])],
                "poor_coherence_below": self.poor_coherence, "poor_points": int(self.poor.sum()),
                "phase_margin_deg": num(self.phase_margin_deg), "gain_margin_db": num(self.gain_margin_db),
                "sensitivity_peak_db": num(ms), "sensitivity_peak_hz": num(ms_hz), "averages": self.averages,
                "intervals_include_rounding": self.loop_sd_resolution is not None,
                **{key: None if ci is None else list(ci) for key, ci in zip(
                    ("gain_margin_interval95_db", "phase_margin_interval95_deg", "sensitivity_peak_interval95_db"),
                    self.intervals().values())},
                "bandwidth_hz": bw, "bandwidth_poor_coherence": bw_poor, "bandwidth_between": bw_where,
                "closed_loop_rhp_poles": self.closed_loop_rhp_poles, "nyquist": self.nyquist_note,
                "gain_crossings": [c.to_dict() for c in self.gain_crossings],
                "phase_crossings": [c.to_dict() for c in self.phase_crossings],
                "model": {"phase_margin_deg": num(self.model_margins.phase_margin_deg),
                          "gain_margin_db": num(self.model_margins.gain_margin_db),
                          "sensitivity_peak_db": num(self.model_margins.sensitivity_peak_db),
                          "bandwidth_hz": num(self.model_margins.bandwidth_hz)},
                "mismatch_bands": [dict(zip(("low_hz", "high_hz", "points", "poor_points", "mean_abs_db", "max_abs_db",
                                             "mean_abs_deg", "max_abs_deg"), (num(v) for v in b))) for b in self.bands],
                "mode": None if self.mode is None else self.mode.to_dict(),
                "model_mode": None if self.model_mode is None else self.model_mode.to_dict(),
                "transmission_ratio": self.transmission_ratio, "sign_reversed": self.sign_reversed,
                "notes": list(self.notes())}

    def side_by_side(self) -> list:
        """``(figure, unit, model, measured)``: the model's figures (python-control, the
        continuous loop) beside those of the loop on the measured response (None: not
        decided; NaN: every crossing of poor coherence)."""
        mm, z = self.model_margins, self.closed_loop_rhp_poles
        return [("gain margin", "dB", mm.gain_margin_db, self.gain_margin_db),
                ("phase margin", "deg", mm.phase_margin_deg, self.phase_margin_deg),
                ("sensitivity peak Ms", "dB", mm.sensitivity_peak_db, self.sensitivity_peak[0]),
                ("bandwidth (-3 dB)", "Hz", mm.bandwidth_hz, self.bandwidth[0]),
                ("closed loop stable", "", "yes" if mm.closed_loop_stable else "no",
                 None if z is None else "yes" if z == 0 else "no")]

    def margins_table(self) -> str:
        """:meth:`side_by_side` as text."""
        def cell(x):
            if x is None or (isinstance(x, float) and math.isnan(x)):
                return "not decided"
            return x if isinstance(x, str) else f"{x:.4g}"
        spans = self.intervals()
        lines = [f"  {'margins':<28}{'model':>12}{'measured plant':>16}  95 % interval"]
        lines += [f"  {name + (f' [{unit}]' if unit else ''):<28}{cell(a):>12}{cell(b):>16}  "
                  f"{interval_text(spans.get(name))}" for name, unit, a, b in self.side_by_side()]
        return "\n".join(lines)

    def table(self) -> str:
        """The crossings and the model's mismatch per band, as text."""
        lines = ["  measured plant: crossings of L on the measured points"]
        lines += [f"    {c.text()}" for c in (*self.gain_crossings, *self.phase_crossings)]
        lines.append("    model's mismatch from the measured response (points of good coherence):")
        lines.append("      band_hz               points  poor  mean|dB|  max|dB|  mean|deg|  max|deg|")
        for lo, hi, n, bad, mdb, xdb, mdeg, xdeg in self.bands:
            lines.append(f"      {lo:9.4g}..{hi:<9.4g}  {n:6d}  {bad:4d}  {mdb:8.2f}  {xdb:7.2f}  {mdeg:9.1f}  {xdeg:8.1f}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"<MeasuredLoop {self.signal} from {self.source}: {self.frequency_hz.size} points, "
                f"PM {self.phase_margin_deg:.1f} deg, GM {self.gain_margin_db:.2f} dB>")

    def _repr_html_(self) -> str:
        from html import escape
        return f"<pre>{escape(repr(self))}\n{escape(self.table())}</pre>"

    def plot(self, ax=None):
        """Bode plot of ``L`` on the measured response and on the model's, points of poor
        coherence hollow; returns the axes (magnitude, phase)."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(2, 1, sharex=True)
        f, poor = self.frequency_hz, self.poor
        for curve, label, style in ((self.model_loop, "model", "-"), (self.loop, "measured", ".")):
            ax[0].semilogx(f, 20 * np.log10(np.abs(curve)), style, label=label)
            ax[1].semilogx(f, np.degrees(np.unwrap(np.angle(curve))), style, label=label)
        ax[0].semilogx(f[poor], 20 * np.log10(np.abs(self.loop[poor])), "o", mfc="none", label="poor coherence")
        ax[0].set_ylabel("|L| [dB]")
        ax[1].set_ylabel("arg L [deg]")
        ax[1].set_xlabel("frequency [Hz]")
        ax[0].legend()
        return ax
