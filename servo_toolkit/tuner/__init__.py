"""The interactive loop tuner for Jupyter (ipywidgets; ``pip install servo_toolkit[jupyter]``).

``servo_toolkit.tune(scene)`` shows sliders for the loop's free parameters and, live, the
loop's Bode plot with its margins, the Nichols chart, the step and 8 Hz sine responses, the
requirement table and the worst case over the stroke. Its logic is the pure function
:func:`servo_toolkit.loop.tuning.tuned_design`; the widget only maps controls to a
:class:`~servo_toolkit.loop.tuning.LoopTuning` and draws the result. "Use this design" stores
the tuned :class:`~servo_toolkit.loop.DesignResult` in ``tuner.result``, which
``build_report(scene, design=...)``, ``export`` and ``check_design`` take, and
``tuner.save(path)`` writes it for ``servo-toolkit check/export/report --design FILE``.
"""

from __future__ import annotations

from .widget import Tuner, tune

__all__ = ["Tuner", "tune"]
