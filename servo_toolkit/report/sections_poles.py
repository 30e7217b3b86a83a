"""Closed-loop poles and the sampled loops: the pole-zero map of ``theta_ref -> theta`` with
each pole's damping and frequency, and the Bode of the current loop at its own period and of
the motion loop at its sample time, in z, beside the continuous loops the design uses.

The sampled loops hold the continuous plant through a zero-order hold (exact
discretization, ``c2d(..., "zoh")``) and add one period of computation delay: the 1.5
sample times the continuous design models as a Pade delay. The current PI runs at the
period of the exported controller (forward Euler, :mod:`servo_toolkit.export.blocks`); the
motion controller is sampled by Tustin, as the simulation runs it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..display.units import label
from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table


@dataclass(frozen=True)
class PoleTable:
    """Poles of a linear system with their natural frequency and damping ratio.

    Attributes
    ----------
    poles : ndarray of complex
        Sorted by natural frequency; one of each conjugate pair (positive imaginary part).
    frequency_hz : ndarray
        Natural frequency |p| / 2 pi (Hz).
    damping : ndarray
        Damping ratio -Re(p) / |p| (1 for a pole at the origin).
    zeros : ndarray of complex
        Finite transmission zeros.
    """

    poles: np.ndarray
    frequency_hz: np.ndarray
    damping: np.ndarray
    zeros: np.ndarray

    @property
    def smallest_damping(self) -> float:
        """The smallest damping ratio of any pole (nan without poles)."""
        return float(np.min(self.damping)) if self.damping.size else math.nan


def pole_table(sys) -> PoleTable:
    """Poles (python-control's ``poles``), natural frequencies and damping ratios of ``sys``."""
    import control as ct
    p = np.asarray(ct.poles(sys), complex)
    p = p[p.imag >= -1e-9 * np.maximum(1.0, np.abs(p))]  # one of each conjugate pair
    wn = np.abs(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        zeta = np.where(wn > 0, -p.real / np.where(wn > 0, wn, 1.0), 1.0)
    order = np.argsort(wn)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            z = np.asarray(ct.zeros(sys), complex)
        except Exception:  # noqa: BLE001 - a zero computation that fails leaves the map without zeros
            z = np.zeros(0, complex)
    z = z[np.isfinite(z)]
    return PoleTable(p[order], wn[order] / (2 * math.pi), zeta[order], z)


def _delayed(sys_d):
    """``sys_d`` followed by one sample of computation delay (z^-1 on its input)."""
    import control as ct
    delay = ct.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], sys_d.dt)
    return ct.series(delay, sys_d)


def current_loop_pair(design, motor):
    """(continuous, sampled, period) of the current loop broken at the current error, or
    None when the current loop is ideal (no inductance or no PI gains).

    The continuous loop is the analog PI kp + ki/s times the plant from voltage to current
    (back-emf included); the sampled one is that plant behind a zero-order hold, one period of
    computation delay and the forward-Euler PI of the exported controller.
    """
    import control as ct
    from ..export.blocks import current_loop
    c = design.controller
    if motor.inductance <= 0 or (c.current_kp <= 0 and c.current_ki <= 0) or c.sample_time <= 0:
        return None
    ts = current_loop(c, motor, None).sample_time
    g = ct.ss(design.plant)[design.plant.output_index["i"], design.plant.input_index["u"]]
    pi_s = ct.tf([c.current_kp, c.current_ki], [1.0, 0.0])
    pi_z = ct.tf([c.current_kp, c.current_ki * ts - c.current_kp], [1.0, -1.0], ts)
    loop_s = ct.ss(ct.series(pi_s, g))
    loop_z = _delayed(ct.series(ct.ss(pi_z), ct.c2d(ct.ss(g), ts, "zoh")))
    return loop_s, loop_z, ts


def motion_loop_pair(design, motor):
    """(continuous, sampled, period) of the motion loop broken at the position measurement,
    or None for a continuous controller. The continuous loop is the design's (sampling as a
    Pade delay); the sampled one holds the plant with its analog current loop behind a
    zero-order hold, adds one period of computation delay and runs the Tustin-sampled
    motion controller."""
    import control as ct
    from ..plant.current_loop import current_controller
    c = design.controller
    ts = c.sample_time
    if ts <= 0:
        return None
    cur = current_controller(c.current_kp, c.current_ki, motor)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        inner = ct.interconnect([design.plant, cur], inplist=["i_cmd"], outlist=["theta", "omega_m"],
                                inputs=["i_cmd"], outputs=["theta", "omega_m"], check_unused=False)
        pd = ct.c2d(ct.ss(inner.A, inner.B, inner.C, inner.D), ts, "zoh")
        pd = ct.ss(pd.A, pd.B, pd.C, pd.D, ts, inputs=["i_cmd0"], outputs=["theta", "omega_m"], name="plant_d")
        dly = ct.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], ts, inputs=["i_ref"], outputs=["i_cmd0"], name="delay")
        md = ct.sample_system(c.motion, ts, method="tustin")
        cut = ct.ss(md.A, md.B, md.C, md.D, ts, inputs=["theta_ref", "theta_meas", "omega_m"], outputs=["i_ref"],
                    name="motion_cut")
        sys = ct.interconnect([pd, dly, cut], inplist=["theta_meas"], outlist=["theta"], check_unused=False)
    loop_z = ct.ss(sys.A, -sys.B, sys.C, -sys.D, ts)
    return design.loop, loop_z, ts


def loop_response(sys, f) -> np.ndarray:
    """Complex response of a SISO system (continuous or sampled) at ``f`` (Hz)."""
    import control as ct
    return np.asarray(ct.frequency_response(sys, 2 * np.pi * np.asarray(f, float)).complex).reshape(-1)


def crossings(f, response):
    """(gain crossover Hz, phase margin deg, gain margin dB) of a loop response on the
    increasing grid ``f``: the last crossing of |L| = 1, the phase there plus 180 deg, and
    the gain below 0 dB at the first phase crossing of -180 deg above it (inf when the
    phase does not reach it on the grid; nan values when |L| never crosses 1)."""
    mag = np.abs(response)
    phase = np.degrees(np.unwrap(np.angle(response)))
    down = np.nonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))[0]
    if not down.size:
        return math.nan, math.nan, math.nan
    k = int(down[-1])
    lm = np.log(mag[k:k + 2])
    w = float(lm[0] / (lm[0] - lm[1]))
    fc = float(np.exp(np.log(f[k]) + w * (np.log(f[k + 1]) - np.log(f[k]))))
    pc = float(phase[k] + w * (phase[k + 1] - phase[k]))
    pm = (pc + 180.0 + 180.0) % 360.0 - 180.0
    # the phase above the -180 deg line (on the branch of the crossover), past the crossover
    above = phase - (pc - pm)
    cross = np.nonzero((above[k:-1] > 0) & (above[k + 1:] <= 0))[0]
    if not cross.size:
        return fc, pm, math.inf
    j = int(k + cross[0])
    v = float(above[j] / (above[j] - above[j + 1]))
    return fc, pm, float(-20 * ((1 - v) * np.log10(mag[j]) + v * np.log10(mag[j + 1])))


def _pz_figure(pt: PoleTable, f_top: float):
    fig, ax = figures.new_figure(size=(6.5, 5.0))
    p = np.concatenate([pt.poles, np.conj(pt.poles[np.abs(pt.poles.imag) > 0])]) / (2 * math.pi)
    z = pt.zeros / (2 * math.pi)
    lim = 2.0 * f_top
    show_p = p[np.abs(p) <= lim]
    show_z = z[np.abs(z) <= lim]
    ax.plot(show_p.real, show_p.imag, "x", color="C3", ms=8, mew=2, label="poles")
    if show_z.size:
        ax.plot(show_z.real, show_z.imag, "o", mfc="none", color="C0", ms=7, label="zeros")
    for zeta in (0.1, 0.3, 0.5, 0.707):
        a = math.acos(zeta)
        ax.plot([0, -lim * math.cos(a)], [0, lim * math.sin(a)], color="0.75", lw=0.7, ls=":")
        ax.annotate(f"zeta {zeta:g}", (-0.9 * lim * math.cos(a), 0.9 * lim * math.sin(a)), fontsize="x-small",
                    color="0.45")
    ax.axvline(0, color="k", lw=0.7)
    ax.axhline(0, color="k", lw=0.7)
    ax.set(xlim=(-lim, 0.1 * lim), ylim=(-lim, lim), xlabel="real part / 2 pi [Hz]",
           ylabel="imaginary part / 2 pi [Hz]", title="Closed-loop poles and zeros (command to output)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return fig


def _bode_figure(pairs):
    fig, axes = figures.new_figure(2, len(pairs), size=(5.0 * len(pairs) + 1.0, 5.2), sharex="col")
    axes = np.asarray(axes).reshape(2, len(pairs))
    rows = []
    for j, (name, (ls, lz, ts)) in enumerate(pairs):
        nyq = 0.5 / ts
        f = np.logspace(math.log10(nyq) - 4, math.log10(nyq), 800)[:-1]
        rs, rz = loop_response(ls, f), loop_response(lz, f)
        am, ap = axes[0, j], axes[1, j]
        am.semilogx(f, 20 * np.log10(np.abs(rs)), "C0", label="continuous (design model)")
        sampled = f"C{j + 1}--"  # one colour per sample time: the figure has one legend for its panels
        am.semilogx(f, 20 * np.log10(np.abs(rz)), sampled, label=f"sampled, T = {fmt(ts * 1e6)} us")
        ps = np.degrees(np.unwrap(np.angle(rs)))
        pz = np.degrees(np.unwrap(np.angle(rz)))
        pz += 360.0 * np.round((ps[0] - pz[0]) / 360.0)
        ap.semilogx(f, ps, "C0")
        ap.semilogx(f, pz, sampled)
        for ax in (am, ap):
            ax.axvline(nyq, color="0.5", lw=0.8, ls=":")
            ax.grid(True, which="both", alpha=0.3)
        am.axhline(0, color="k", lw=0.7)
        ap.axhline(-180, color="k", lw=0.7)
        am.set(ylabel=label("gain", "dB"), title=f"{name} loop (Nyquist frequency dotted)")
        ap.set(ylabel=label("phase", "deg"), xlabel=label("frequency", "Hz"))
        am.legend(fontsize="x-small", loc="lower left")
        for kind, r in (("continuous", rs), ("sampled", rz)):
            fc, pm, gm = crossings(f, r)
            rows.append((f"{name} loop, {kind}", fmt(ts * 1e6), fmt(fc), fmt(pm), fmt(gm)))
    return fig, rows


def poles_and_sampling(ctx) -> Section:
    """Pole-zero map with damping and frequency; continuous and sampled loop Bode."""
    d = ctx.design()
    motor = ctx.scene.motor
    pt = pole_table(d.closed_loop)
    if not pt.poles.size:
        raise NotApplicable("the closed loop has no dynamics")
    bw = d.margins.bandwidth_hz
    f_top = 5.0 * bw if math.isfinite(bw) and bw > 0 else float(np.median(pt.frequency_hz))
    fig1 = _pz_figure(pt, f_top)
    rows = [(f"{fmt(p.real / (2 * math.pi))} {'+' if p.imag >= 0 else '-'} j{fmt(abs(p.imag) / (2 * math.pi))}",
             fmt(fz), fmt(z, 3), "yes" if abs(p.imag) > 0 else "no")
            for p, fz, z in zip(pt.poles, pt.frequency_hz, pt.damping)]
    least = int(np.argmin(pt.damping))
    text = [f"The closed loop from command to output at q0 has {len(pt.poles)} distinct poles (conjugate pairs "
            f"listed once). The least damped has a damping ratio of {fmt(pt.damping[least], 3)} at "
            f"{fmt(pt.frequency_hz[least])} Hz; a pole in the right half-plane would make every other figure of "
            "this report meaningless."]
    figs = [FigureSpec(fig1, "Closed-loop poles (x) and zeros (o) in Hz, with lines of constant damping ratio.")]
    body = table(("pole / 2 pi [Hz]", "natural frequency [Hz]", "damping ratio", "complex pair"), rows,
                 table_id="poles-table")
    pairs = [(name, pair) for name, pair in (("current", current_loop_pair(d, motor)),
                                             ("motion", motion_loop_pair(d, motor))) if pair is not None]
    if pairs:
        fig2, mrows = _bode_figure(pairs)
        figs.append(FigureSpec(fig2, "The loops in z at their own sample periods beside the continuous loops "
                                     "of the design, up to the Nyquist frequency."))
        text.append("The design works on continuous loops and models sampling as a Pade delay of 1.5 sample "
                    "times. Below, the loops as they run: the plant behind a zero-order hold, one period of "
                    "computation delay, the current PI at the exported controller's period and the motion "
                    "controller sampled by Tustin at its sample time. Where the two curves part, near the Nyquist "
                    "frequency, the continuous model no longer describes the controller.")
        body += table(("loop", "period [us]", "gain crossover [Hz]", "phase margin [deg]", "gain margin [dB]"),
                      mrows, table_id="sampled-table")
    else:
        text.append("The controller runs continuous (no sample time): there is no sampled loop to show.")
    return Section("Closed-loop poles and the sampled loops", para(*text) + body, tuple(figs), key="poles")
