"""How a measured frequency response shows itself: its one line, its card, its JSON form and
its Bode plot (:class:`~servo_toolkit.identify.data.FrequencyData` delegates here).

A line whose coherence is below :data:`POOR_COHERENCE` is marked in the plot and counted in
the card: the input explains less than 80 % of the output's power there (noise, a
nonlinearity, leakage), and its gain and phase scatter the more.
"""

from __future__ import annotations

import os

import numpy as np

from ..core.json_text import nulls
from ..display.cards import card, facts, num, svg, table

#: coherence below which a line is marked as poorly measured
POOR_COHERENCE = 0.8
#: lines listed in the card's table (log-spaced over the band)
CARD_ROWS = 8


def _estimator(data) -> str:
    """The estimator and its averaging in words."""
    spectra = "spectra" if data.averages != 1 else "spectrum"
    if data.window is not None:
        over = f" over {data.averages} {spectra}" if data.averages is not None else ""
        return f"H1 {data.window}{over}"
    return f"{data.averages} {spectra} averaged" if data.averages is not None else "averages unknown"


def _coherence(data) -> str:
    """The coherence in a few words."""
    c = np.asarray(data.coherence, float)
    if np.all(c == 1.0):
        return "coherence 1 at every line"
    return f"coherence {num(float(np.median(c)), 2)} median"


def _band(data) -> str:
    f = data.frequency_hz
    return f"{num(float(f[0]), 3)}-{num(float(f[-1]), 3)} Hz"


def repr_line(data) -> str:
    """One line: the lines and their band, the estimator, the coherence, the file."""
    src = f", from {os.path.basename(data.source)}" if data.source else ""
    of = f" of {data.signal}" if data.signal else ""
    return (f"{data.points} lines {_band(data)}{of}, {_estimator(data)}, {_coherence(data)}{src}")


def to_dict(data) -> dict:
    """JSON-ready (strict JSON: a non-finite value is None), units in the key names."""
    def floats(a):
        return None if a is None else [float(x) for x in np.asarray(a, float)]
    return nulls({"points": int(data.points), "frequency_hz": floats(data.frequency_hz),
                  "gain_db": floats(data.gain_db), "phase_deg": floats(data.phase_deg),
                  "coherence": floats(data.coherence), "averages": data.averages, "window": data.window,
                  "signal": data.signal, "resolution_db": floats(data.resolution_db),
                  "resolution_deg": floats(data.resolution_deg), "source": data.source})


def _rows(data):
    """About :data:`CARD_ROWS` lines, log-spaced over the band (each shown once)."""
    f = data.frequency_hz
    want = np.geomspace(f[0], f[-1], min(CARD_ROWS, data.points))
    picks = sorted({int(np.argmin(np.abs(np.log(f / w)))) for w in want})
    return [(num(f[k], 4), num(data.gain_db[k], 4), num(data.phase_deg[k], 4), num(data.coherence[k], 3))
            for k in picks]


def card_html(data) -> str:
    """The Jupyter card: the facts of :func:`repr_line`, a few lines as a table, the plot."""
    c = np.asarray(data.coherence, float)
    poor = int(np.sum(c < POOR_COHERENCE))
    pairs = [("lines", f"{data.points}, {_band(data)}"), ("estimator", _estimator(data)),
             ("coherence", f"median {num(float(np.median(c)), 3)}, lowest {num(float(c.min()), 3)}; "
                           f"{poor} line{'' if poor == 1 else 's'} below {POOR_COHERENCE:g}")]
    if data.signal:
        pairs.append(("response of", data.signal))
    if data.resolution_db is not None:
        pairs.append(("resolution (1 sd, largest)", f"{num(float(np.max(data.resolution_db)), 3)} dB, "
                                                    f"{num(float(np.max(data.resolution_deg)), 3)} deg"))
    if data.source:
        pairs.append(("file", data.source))
    rows = table(("frequency [Hz]", "gain [dB]", "phase [deg]", "coherence"), _rows(data))
    plot = svg(data.plot, size=(7.0, 6.0), rows=3, sharex=True, height_ratios=(3, 3, 1.5))
    return card(f"Frequency response{' of ' + data.signal if data.signal else ''}",
                parts=[facts(pairs), rows, plot])


def plot(data, axes=None):
    """Bode plot (gain in dB, phase in deg against log frequency) with the coherence in a
    third, smaller panel; lines of coherence below :data:`POOR_COHERENCE` marked. Returns
    the three axes."""
    if axes is None:
        import matplotlib.pyplot as plt
        _, axes = plt.subplots(3, 1, sharex=True, figsize=(7.0, 6.5), height_ratios=(3, 3, 1.5),
                               layout="constrained")
    ag, ap, ac = axes
    f, c = data.frequency_hz, np.asarray(data.coherence, float)
    poor = c < POOR_COHERENCE
    label = f"coherence < {POOR_COHERENCE:g}"
    for ax, y in ((ag, data.gain_db), (ap, data.phase_deg), (ac, c)):
        ax.semilogx(f, y, ".-", ms=3, lw=0.8, color="C0", label="measured")
        if poor.any():
            ax.semilogx(f[poor], y[poor], "x", ms=6, color="C3", label=label)
        ax.grid(True, which="both", alpha=0.3)
    ac.axhline(POOR_COHERENCE, color="C3", ls="--", lw=0.8)
    ac.set_ylim(0.0, 1.05)
    ag.set_ylabel("gain [dB]")
    ap.set_ylabel("phase [deg]")
    ac.set_ylabel("coherence [-]")
    ac.set_xlabel("frequency [Hz]")
    of = f" of {data.signal}" if data.signal else ""
    ag.set_title(f"Frequency response{of}: {data.points} lines, {_estimator(data)}", fontsize="medium")
    if poor.any():  # right of the axes: the curve may pass through every corner
        ag.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return axes


__all__ = ["POOR_COHERENCE", "card_html", "plot", "repr_line", "to_dict"]
