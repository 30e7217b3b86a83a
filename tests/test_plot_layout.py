"""The results' plots survive ``fig.savefig``: every title, axis label, tick label and legend
lies within the figure once it is drawn (the figure carries a layout engine), and no legend
covers a curve's point or a bar (legends sit above or beside their axes where the data
leave no corner free)."""

from __future__ import annotations

import math

import matplotlib
import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.loop import design
from servo_toolkit.sim import Reference, simulate
from servo_toolkit.studies.actuator import actuator_check
from servo_toolkit.studies.kv.study import kv_study
from servo_toolkit.studies.reduce import reduce
from servo_toolkit.studies.stiffness import stiffness_study
from servo_toolkit.studies.tolerances import tolerance_study

from .conftest import SCENES
from .figure_layout import layout_faults

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def designed():
    """(scene, design) of the reference EMA."""
    scene = load_scene(SCENES / "ema_reference.toml")
    return scene, design(scene, progress=False)


PLOTS = {
    # x label cut at the bottom
    "kv": lambda ema, d: kv_study(ema, "kv_8hz", progress=False),
    # a title of every effect left out, wider than the figure; x label cut
    "reduction": lambda ema, d: reduce(ema, "kv_stroke", progress=False, per_effect=False),
    # tolerance names as y tick labels, cut on the left
    "tolerances": lambda ema, d: tolerance_study(load_scene(SCENES / "examples" / "ema_tolerances.toml"), samples=8,
                                                 worst_corner=False, progress=False),
    # legends over the sine and the current
    "simulation": lambda ema, d: simulate(ema, d.controller, reference=Reference.sine(math.radians(2.0), 8.0),
                                          duration=0.5),
    # legend over the housing's bar at +30 deg
    "stiffness": lambda ema, d: stiffness_study(ema, [-30.0, 0.0, 30.0]),
    # legends over the sine and the current limits
    "actuator": lambda ema, d: actuator_check(ema, d),
}


@pytest.mark.parametrize("kind", sorted(PLOTS))
def test_a_saved_plot_keeps_its_texts_inside_and_its_legends_off_the_data(designed, kind):
    import matplotlib.pyplot as plt
    fig = np.ravel(PLOTS[kind](*designed).plot())[0].figure
    try:
        assert layout_faults(fig) == []
        assert fig.get_layout_engine() is not None  # whatever size the figure is saved at
    finally:
        plt.close(fig)


def test_the_check_finds_a_cut_label_and_a_legend_over_a_sine():
    """The helper itself: a label pushed past the edge and a legend in the middle of a sine
    are both reported."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(4, 3))
    ax = fig.subplots()
    t = np.linspace(0.0, 1.0, 400)
    ax.plot(t, np.sin(20 * t), label="sine")
    ax.set_xlabel("time [s]", labelpad=60)
    ax.legend(loc="center")
    faults = layout_faults(fig)
    assert any("x label 'time [s]' runs outside the figure" in f for f in faults)
    assert any(f.startswith("axes 1 legend covers") and "'sine'" in f for f in faults)
