"""The ipywidgets tuner: controls -> :func:`~servo_toolkit.loop.tuning.tuned_design` -> live views."""

from __future__ import annotations

import math
from ..display.cards import svg
from ..core.output_units import output_unit
from ..loop.tuning import LoopTuning, base_design, save_design, tuned_design, tuning_of
from .plots import draw


def _widgets():
    try:
        import ipywidgets
    except ImportError:
        raise ImportError("the loop tuner needs ipywidgets: pip install 'servo_toolkit[jupyter]'") from None
    return ipywidgets


class Tuner:
    """Sliders for the loop's free parameters and live views of the tuned loop.

    Parameters
    ----------
    scene : Scene
    base : DesignResult, optional
        The design to start from (default: the automatic design).

    Attributes
    ----------
    controls : dict of str to ipywidgets widget
        ``bandwidth_hz``, ``kp``, ``kv``, ``wvi``, ``resonance_filter``, ``filter_hz``,
        ``depth_db``, ``width``, ``q0`` (deg, or mm for an output travel), ``feedforward``
        (``"off"``, ``"gains"``, ``"model"``): set their ``value`` to tune from code.
    current : DesignResult
        The loop with the controls' values (updated on every change).
    result : DesignResult or None
        The design taken with "Use this design" (or :meth:`use`).
    """

    def __init__(self, scene, base=None):
        w = _widgets()
        self.scene = scene
        self._base = base if base is not None else base_design(scene)
        self._bases = {None: self._base}
        self._busy = False
        self.result = None
        t = tuning_of(self._base)
        lo, hi = scene.drivetrain.stroke
        self._unit = output_unit(scene)
        bw = self._base.margins.bandwidth_hz
        log = dict(continuous_update=False, readout_format=".4g", style={"description_width": "150px"})

        def logslider(value, text):
            v = max(value, 1e-9)
            return w.FloatLogSlider(value=v, base=10, min=math.log10(v) - 1, max=math.log10(v) + 1, step=0.01,
                                    description=text, **log)
        res = self._base.parameters.resonance_hz
        fhz = t.filter_hz or (res if math.isfinite(res) else 50.0)
        self.controls = {
            "bandwidth_hz": logslider(bw if math.isfinite(bw) and bw > 0 else 5.0, "bandwidth target [Hz]"),
            "kp": logslider(t.kp, "position kp [1/s]"),
            "kv": logslider(t.kv, "speed kv [A s/rad]"),
            "wvi": logslider(t.wvi, "speed PI corner [rad/s]"),
            "resonance_filter": w.Dropdown(options=["none", "notch", "lowpass"], value=t.resonance_filter,
                                           description="resonance filter", style=log["style"]),
            "filter_hz": logslider(fhz, "filter frequency [Hz]"),
            "depth_db": w.FloatSlider(value=t.depth_db if t.depth_db is not None else -20.0, min=-60.0, max=-1.0,
                                      step=0.5, description="notch depth [dB]", **log),
            "width": w.FloatSlider(value=t.width if t.width is not None else 0.5, min=0.05, max=2.0, step=0.05,
                                   description="width (damping)", **log),
            "q0": w.FloatSlider(value=self._unit.show(t.q0), min=self._unit.show(lo), max=self._unit.show(hi),
                                step=(self._unit.show(hi) - self._unit.show(lo)) / 200,
                                description=f"operating point [{self._unit.shown}]", **log),
            "feedforward": w.Dropdown(options=["off", "gains", "model"],
                                      value="off" if self._base.controller.feedforward is None
                                      else self._base.controller.feedforward.kind,
                                      description="feedforward", style=log["style"]),
        }
        self._bw0 = self.controls["bandwidth_hz"].value
        self.views = w.HTML()
        self.table = w.HTML()
        self.button = w.Button(description="Use this design", button_style="success")
        self.button.on_click(lambda _: self.use())
        self.status = w.HTML()
        for c in self.controls.values():
            c.observe(self._changed, names="value")
        self.widget = w.HBox([w.VBox(list(self.controls.values()) + [self.button, self.status]),
                              w.VBox([self.views, self.table])])
        self.current = None
        self.update()

    # --- logic ------------------------------------------------------------------------------

    def values(self) -> LoopTuning:
        """The controls as a :class:`LoopTuning` (the bandwidth target only when moved)."""
        c = self.controls
        bw = c["bandwidth_hz"].value
        return LoopTuning(bandwidth_hz=None if math.isclose(bw, self._bw0) else bw, kp=c["kp"].value,
                          kv=c["kv"].value, wvi=c["wvi"].value, resonance_filter=c["resonance_filter"].value,
                          filter_hz=c["filter_hz"].value, depth_db=c["depth_db"].value, width=c["width"].value,
                          q0=c["q0"].value / self._unit.factor, feedforward=c["feedforward"].value)

    def _base_for(self, bandwidth_hz):
        if bandwidth_hz not in self._bases:
            self._bases[bandwidth_hz] = base_design(self.scene, bandwidth_hz)
        return self._bases[bandwidth_hz]

    def _changed(self, change) -> None:
        if self._busy:
            return
        if change["owner"] is self.controls["bandwidth_hz"]:  # a new automatic design: reset the gains
            base = self._base_for(self.values().bandwidth_hz)
            t = tuning_of(base)
            self._busy = True
            try:
                for name in ("kp", "kv", "wvi"):
                    self.controls[name].value = getattr(t, name)
                self.controls["resonance_filter"].value = t.resonance_filter
                if t.filter_hz is not None:
                    self.controls["filter_hz"].value = t.filter_hz
            finally:
                self._busy = False
        self.update()

    def update(self) -> None:
        """Re-evaluate the loop with the controls' values and redraw."""
        from ..display.cards import requirements_table
        values = self.values()
        base = self._base_for(values.bandwidth_hz)
        # the gains of a fresh automatic design are its own: keep them unless moved
        self.current = tuned_design(self.scene, values, base=base)
        d = self.current
        m = d.margins
        self.views.value = svg(lambda ax: draw(d, ax, self.scene), size=(9.0, 6.0), rows=2, cols=2)
        worst = d.stroke.summary().replace("\n", "<br>") if d.stroke is not None else ""
        self.table.value = (f"<b>{'requirements met' if d.passed else 'requirements NOT met'}</b>; bandwidth "
                            f"{m.bandwidth_hz:.3g} Hz, phase at 8 Hz {m.phase_at_freq_deg:.3g} deg, disk margin "
                            f"{m.disk_margin:.3g}, Ms {m.sensitivity_peak_db:.3g} dB"
                            + requirements_table(d.requirements) + f"<p>{worst}</p>")

    def use(self):
        """Take the current loop as the result (what the button does); returns it."""
        self.result = self.current
        self.status.value = f"taken: {self.result.controller.description}"
        return self.result

    def save(self, path, inputs=()):
        """Write the taken (else the current) design for ``--design FILE``; returns the path."""
        return save_design(self.result or self.current, path, inputs=inputs)

    def _ipython_display_(self):
        from IPython.display import display
        display(self.widget)

    def __repr__(self) -> str:
        d = self.current
        return (f"<Tuner {self.scene.name}: {d.controller.description}; "
                f"{'requirements met' if d.passed else 'requirements NOT met'}>")


def tune(scene, base=None) -> Tuner:
    """The interactive loop tuner of ``scene`` (see :class:`Tuner`)."""
    return Tuner(scene, base)


__all__ = ["Tuner", "tune"]
