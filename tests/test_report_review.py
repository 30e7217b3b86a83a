"""The design-review sections of the report, each against an independent computation:
margins along the stroke against python-control at the binding point, the dynamic stiffness
against the load-side inertia, the step figures against python-control, the controller's
discrete form against scipy's bilinear transform, the light sweep's grid against the
closed-loop peak, and the robustness rows."""

from __future__ import annotations

import math
import re

import control as ct
import numpy as np
import pytest
import scipy.signal

from servo_toolkit import load_scene
from servo_toolkit.report.context import Context
from servo_toolkit.report.sections_closed import closed_loop, dynamic_stiffness, step_figures
from servo_toolkit.report.sections_loop import controller
from servo_toolkit.report.sections_requirements import requirement_rows
from servo_toolkit.report.sections_robust import robustness
from servo_toolkit.report.sections_stroke import binding_point, margins_along_stroke
from servo_toolkit.report.sections_studies import peak_frequencies
from servo_toolkit.scene.loader import scene_from_dict

from .conftest import SCENES


@pytest.fixture(scope="module")
def ctx():
    c = Context(load_scene())
    c.design()
    return c


def _row(html, label):
    m = re.search(rf"<td>{re.escape(label)}</td><td>([^<]*)</td>", html)
    assert m, label
    return m.group(1)


def test_stroke_section_binding_point_agrees_with_python_control(ctx):
    from servo_toolkit.loop.closed_loop import open_loop
    d = ctx.design()
    section = margins_along_stroke(ctx)
    assert len(section.figures) == 2
    which, q = binding_point(d.stroke, ctx.scene)
    k = int(np.argmin(np.abs(d.stroke.q - q)))
    gm, pm, *_ = ct.stability_margins(open_loop(ctx.scene, d.controller, q))
    assert d.stroke.gain_margin_db[k] == pytest.approx(20 * math.log10(gm), abs=0.05)
    assert d.stroke.phase_margin_deg[k] == pytest.approx(pm, abs=0.2)
    worst = d.stroke.worst()["gain_margin_db"]
    assert f"{worst['value']:.4g} dB" in section.html
    # the reference EMA binds at an end of the stroke, not at q0
    assert abs(math.degrees(q)) == pytest.approx(30.0, abs=1e-6)


def test_dynamic_stiffness_tends_to_the_load_inertia(ctx):
    """Far above the loop and the drivetrain mode an external moment only accelerates the
    load-side inertia: |tau / theta| -> J2 w^2."""
    d = ctx.design()
    f = 2000.0
    k = dynamic_stiffness(d, [f])[0]
    assert k / (2 * math.pi * f) ** 2 == pytest.approx(d.parameters.J2, rel=0.02)
    # integral action: the loop holds against a static moment far better than at mid band
    f_grid = np.geomspace(0.1, 1000, 400)
    kk = dynamic_stiffness(d, f_grid)
    assert kk[0] > 20 * kk.min()


def test_step_figures_are_python_control_step_info(ctx):
    d = ctx.design()
    t, y, info = step_figures(d)
    ref = ct.step_info(d.closed_loop, T=t)
    assert info["Overshoot"] == pytest.approx(ref["Overshoot"])
    section = closed_loop(ctx)
    assert _row(section.html, "step rise time (10-90 %)") == f"{info['RiseTime'] * 1e3:.4g}"
    assert len(section.figures) == 4


def test_controller_rows_carry_units_and_the_tustin_form(ctx):
    d = ctx.design()
    html = controller(ctx).html
    assert "A*s/rad" in html and "rad/s (" in html and " Hz)" in html and "V/(A*s)" in html
    sub = d.controller.motion["i_ref", "theta_ref"]
    tf = ct.ss2tf(sub)
    num, den = np.squeeze(tf.num[0][0]), np.squeeze(tf.den[0][0])
    dnum, dden, _ = scipy.signal.cont2discrete((num, den), d.controller.sample_time, method="bilinear")
    dnum = np.squeeze(dnum) / dden[0]
    m = re.search(r"position error -&gt; i_ref, discrete[^<]*</td><td>num \[([^\]]*)\]", html)
    shown = np.array([float(x) for x in m.group(1).split()])
    np.testing.assert_allclose(shown, dnum[-shown.size:], rtol=1e-5)


def test_light_sweep_grid_resolves_the_closed_loop_peak(ctx):
    d = ctx.design()
    f = np.geomspace(0.5, 40, 4000)
    t = np.abs(np.asarray(ct.frequency_response(d.closed_loop, 2 * np.pi * f).complex).reshape(-1))
    inner = np.nonzero((t[1:-1] > t[:-2]) & (t[1:-1] >= t[2:]))[0] + 1
    assert inner.size  # the drivetrain mode shows as a local peak of |T|
    f_peak = f[inner[np.argmax(t[inner])]]
    grid = peak_frequencies(d, 0.5, 40)
    assert np.min(np.abs(np.log2(grid / f_peak))) < 1 / 12


def test_robustness_section_and_rows(ema_dict):
    import tomllib
    data = tomllib.loads((SCENES / "ema_robust.toml").read_text())
    data["robustness"]["samples"] = 60
    c = Context(scene_from_dict(data, "ema_robust.toml"))
    section = robustness(c)
    d = c.design()
    assert section.status == ("pass" if d.robustness.passed else "fail")
    assert "nominal design" in section.html and len(section.figures) == 1
    rows = requirement_rows(c)
    robust = [r for r in rows if r.id.startswith("robust_")]
    assert len(robust) == len(d.robustness.requirements)
    assert all(r.status == ("pass" if ch.passed else "fail") for r, ch in zip(robust, d.robustness.requirements))


def test_robustness_section_does_not_apply_without_variations(ctx):
    from servo_toolkit.report.section import NotApplicable
    with pytest.raises(NotApplicable):
        robustness(ctx)
