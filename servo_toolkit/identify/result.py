"""The result of an identification fit."""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field

import numpy as np

from .data import FrequencyData

_RESPONSE_LABEL = {"plant": "motor current -> motor speed", "closed_loop": "position command -> output position",
                   "time": "time traces of the voltage-driven plant",
                   "loop": "closed-loop time traces of the nonlinear model"}


@dataclass(frozen=True, repr=False, eq=False)
class FitResult:
    """Fitted scene parameters with their 95 % intervals.

    Attributes
    ----------
    scene : str
        Scene name.
    source : str
        Scene file.
    response : {"plant", "closed_loop", "time", "loop"}
    keys, units : tuple of str
        Scene key paths and their SI units.
    initial, values : numpy.ndarray
        Initial and fitted values (SI).
    ci95 : numpy.ndarray
        (n, 2) 95 % intervals (SI); ``[0, inf]`` for a parameter without influence
        (``[0, null]`` in JSON).
    correlation : numpy.ndarray
        (n, n) correlation of the estimates (NaN for a parameter without influence).
    residual_db_rms, residual_phase_deg_rms : float or None
        RMS gain (dB) and phase (deg) residual of a frequency-response fit.
    residual_rms, initial_residual_rms : float
        RMS of the weighted residual vector after and before the fit.
    warnings : tuple of str
        Parameters the data cannot identify, or cannot separate.
    data : FrequencyData, TimeData or LoopData
    initial_model, fitted_model : numpy.ndarray or tuple
        Model response (complex) or traces (current, motor angle, output angle; or output
        and current of a closed-loop log) of the initial and the fitted scene.
    calibrated : Scene
        The scene with the fitted values.
    written : tuple
        The values as the scene file writes them (None: the loader's default).
    evaluations, dof : int
        Model evaluations, degrees of freedom of the residual.
    verdict : str
        ``"fits to the noise"``, ``"model mismatch"``, ``"not identifiable"`` or
        ``"noise floor unknown"`` (see :mod:`servo_toolkit.identify.verdict`).
    noise_floor : float or None
        RMS of the weighted residual vector that the data's own noise would leave.
    misses : tuple of str
        Where a mismatched model misses the data most (frequency bands or time windows).
    noise_basis : str
        Where the noise floor comes from (the coherence, the scatter of the data), or why it
        is unknown.
    profiles : tuple of ParameterProfile
        The profile of each parameter whose Wald interval is not trusted (a pair correlated
        beyond 0.99, or an ill-conditioned Fisher matrix; :mod:`servo_toolkit.identify.profile`):
        its ``ci95`` is the profile's.
    correlated : str
        Time traces whose residual is not white noise: the worst channel's finding
        (:mod:`servo_toolkit.identify.whiteness`); empty otherwise.
    """

    scene: str
    source: str
    response: str
    keys: tuple
    units: tuple
    initial: np.ndarray
    values: np.ndarray
    ci95: np.ndarray
    correlation: np.ndarray
    residual_db_rms: float | None
    residual_phase_deg_rms: float | None
    residual_rms: float
    initial_residual_rms: float
    warnings: tuple
    data: object
    initial_model: object
    fitted_model: object
    calibrated: object = field(default=None)
    written: tuple = ()
    evaluations: int = 0
    dof: int = 0
    verdict: str = "noise floor unknown"
    noise_floor: float | None = None
    misses: tuple = ()
    noise_basis: str = ""
    profiles: tuple = ()
    correlated: str = ""

    @property
    def mismatch(self) -> bool:
        """True when the model misses the data beyond their noise."""
        return self.verdict == "model mismatch"

    def verdict_text(self) -> str:
        """The verdict as one sentence."""
        if self.verdict == "model mismatch":
            where = f"; it misses most at {', '.join(self.misses)}" if self.misses else ""
            white = f"; {self.correlated}" if self.correlated else ""
            return (f"model mismatch: residual {self.residual_rms:.3g} against a noise floor of "
                    f"{self.noise_floor:.3g}{white}{where} (a parameter missing from --param, or the model lacks "
                    "what the rig does); the 95 % intervals assume a model that fits the data and do not hold")
        if self.verdict == "noise floor unknown":
            why = self.noise_basis.partition("unknown: ")[2] or "too few points to estimate it"
            return f"noise floor unknown ({why}); residual not judged"
        basis = f" ({self.noise_basis})" if self.noise_basis else ""
        text = f"{self.verdict}: residual {self.residual_rms:.3g}, noise floor {self.noise_floor:.3g}{basis}"
        return text + ("; see the warnings" if self.verdict == "not identifiable" else "")

    def to_dict(self) -> dict:
        """JSON-ready summary: ``parameters`` [{key, value, unit, ci95, initial}],
        ``residual_db_rms``, ``correlation``, ``warnings``, ``profiles`` (each
        profile's ``to_dict``)."""
        corr = [[None if not math.isfinite(c) else float(c) for c in row] for row in self.correlation]
        return {"scene": self.scene, "response": self.response,
                "parameters": [{"key": k, "value": float(v), "unit": u, "ci95": [float(lo), float(hi) if math.isfinite(hi) else None],
                                "initial": float(i)}
                               for k, v, u, (lo, hi), i in zip(self.keys, self.values, self.units, self.ci95,
                                                               self.initial)],
                "residual_db_rms": self.residual_db_rms, "residual_phase_deg_rms": self.residual_phase_deg_rms,
                "residual_rms": self.residual_rms, "initial_residual_rms": self.initial_residual_rms,
                "correlation": {"keys": list(self.keys), "matrix": corr},
                "warnings": list(self.warnings), "points": int(self.data.points), "dof": self.dof,
                "verdict": self.verdict, "noise_floor": self.noise_floor, "noise_basis": self.noise_basis,
                "misses": list(self.misses), "correlated": self.correlated, "profiles": [p.to_dict() for p in self.profiles],
                "evaluations": self.evaluations}

    def value(self, key: str) -> float:
        """The fitted value of ``key`` (SI)."""
        return float(self.values[self.keys.index(key)])

    def _rows(self):
        for k, v, u, (lo, hi), i in zip(self.keys, self.values, self.units, self.ci95, self.initial):
            ci = f"[{lo:.4g}, {hi:.4g}]" if math.isfinite(hi) else "not identified"
            yield k, f"{v:.5g}", u, ci, f"{i:.5g}", f"{100 * (v / i - 1):+.1f} %"

    def table(self) -> str:
        """Parameters, intervals, residual and warnings as text."""
        head = ("key", "value", "unit", "95 % interval", "initial", "change")
        rows = [head, *self._rows()]
        widths = [max(len(r[c]) for r in rows) for c in range(len(head))]
        lines = [f"Fit of {self.scene} to {_RESPONSE_LABEL[self.response]} ({self.data.points} points)"]
        lines += ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
        if self.residual_db_rms is not None:
            lines.append(f"  residual: {self.residual_db_rms:.3g} dB RMS gain, {self.residual_phase_deg_rms:.3g} deg "
                         f"RMS phase (weighted residual RMS {self.initial_residual_rms:.3g} -> {self.residual_rms:.3g})")
        else:
            lines.append(f"  residual: {self.residual_rms:.3g} RMS of the traces' differences, each over its noise "
                         f"(initial {self.initial_residual_rms:.3g})")
        if len(self.keys) > 1:
            pairs = [(abs(self.correlation[a, b]), a, b) for a in range(len(self.keys))
                     for b in range(a + 1, len(self.keys)) if math.isfinite(self.correlation[a, b])]
            if pairs:
                c, a, b = max(pairs)
                lines.append(f"  largest correlation: {self.keys[a]} / {self.keys[b]} {self.correlation[a, b]:+.3f}")
        if self.profiles:
            lines.append("  intervals from the profile of the cost (the Fisher matrix is ill-conditioned): "
                         + ", ".join(p.key for p in self.profiles))
        lines += [f"  warning: {w}" for w in self.warnings]
        lines.append(f"  verdict: {self.verdict_text()}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        parts = ", ".join(f"{k}={v:.4g} {u}" for k, v, u in zip(self.keys, self.values, self.units))
        res = (f"{self.residual_db_rms:.3g} dB RMS" if self.residual_db_rms is not None
               else f"residual {self.residual_rms:.3g}")
        return f"<FitResult {self.scene} {self.response}: {parts}; {res}; {self.verdict}; {len(self.warnings)} warnings>"

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{h}</th>" for h in ("key", "value", "unit", "95 % interval", "initial", "change"))
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in self._rows())
        warn = "".join(f"<li>{html.escape(w)}</li>" for w in self.warnings)
        res = (f"{self.residual_db_rms:.3g} dB RMS gain residual" if self.residual_db_rms is not None
               else f"normalised residual {self.residual_rms:.3g}")
        from ..display.cards import card
        return card(f"Fit of {self.scene} to {_RESPONSE_LABEL[self.response]}",
                    parts=[f"<p>{res}; <b>{html.escape(self.verdict_text())}</b></p>"
                           f"<table><tr>{head}</tr>{body}</table>" + (f"<ul>{warn}</ul>" if warn else "")])

    def plot_profiles(self, axes=None):
        """The profile of each parameter profiled: the cost rise against the value, with the
        threshold of the 95 % interval. Returns the axes (empty without profiles)."""
        import matplotlib.pyplot as plt
        if not self.profiles:
            return []
        if axes is None:
            _, axes = plt.subplots(len(self.profiles), 1, figsize=(6.5, 3.2 * len(self.profiles)), squeeze=False)
            axes = list(axes[:, 0])
        for ax, p in zip(axes, self.profiles):
            p.plot(ax)
        return axes

    def plot(self, axes=None):
        """Measured vs initial vs fitted: Bode (gain, phase) of a frequency response, or
        the three traces of a time fit. Returns the axes."""
        import matplotlib.pyplot as plt
        if isinstance(self.data, FrequencyData):
            if axes is None:
                _, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5.5))
            d = self.data
            ref = d.phase_deg
            ag, ap = axes
            ag.semilogx(d.frequency_hz, d.gain_db, "o", ms=3, color="k", label="measured")
            for h, style, label in ((self.initial_model, "--", "initial"), (self.fitted_model, "-", "fitted")):
                phase = ref + ((np.degrees(np.angle(h)) - ref + 180) % 360 - 180)
                ag.semilogx(d.frequency_hz, 20 * np.log10(np.abs(h)), style, label=label)
                ap.semilogx(d.frequency_hz, phase, style, label=label)
            ap.semilogx(d.frequency_hz, d.phase_deg, "o", ms=3, color="k", label="measured")
            ag.set_ylabel("gain [dB]")
            ap.set_ylabel("phase [deg]")
            ap.set_xlabel("frequency [Hz]")
            ag.set_title(f"{self.scene}: {_RESPONSE_LABEL[self.response]}")
            ag.legend()
            for a in axes:
                a.grid(True, which="both", alpha=0.3)
            return axes
        d = self.data
        if self.response == "loop":
            measured = (d.output, d.current_A)
            labels = (f"output [{d.unit}]", "current [A]")
        else:
            measured = (d.current_A, d.motor_angle_rad - d.motor_angle_rad[0],
                        d.output_angle_rad - d.output_angle_rad[0])
            labels = ("current [A]", "motor angle [rad]", "output angle [rad]")
        if axes is None:
            _, axes = plt.subplots(len(measured), 1, sharex=True, figsize=(7, 2.4 * len(measured)))
        for a, m, yi, yf, label in zip(axes, measured, self.initial_model, self.fitted_model, labels):
            a.plot(d.time_s, m, color="k", lw=1, label="measured")
            a.plot(d.time_s, yi, "--", label="initial")
            a.plot(d.time_s, yf, "-", label="fitted")
            a.set_ylabel(label)
            a.grid(True, alpha=0.3)
        axes[0].legend()
        axes[0].set_title(f"{self.scene}: {_RESPONSE_LABEL[self.response]}")
        axes[-1].set_xlabel("time [s]")
        return axes
