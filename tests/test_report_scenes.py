"""The report on every reference scene, failure isolation, and bad input."""

from __future__ import annotations

import re

import numpy as np

import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.report import NotAvailable, Section, build_report, run_section
from servo_toolkit.report.context import Context
from servo_toolkit.report.sections_limits import leaves_out

from .conftest import SCENE_FILES, SCENES


@pytest.mark.parametrize("name", ["cam_follower", "deflection_platform", "roller_screw_two_stage"])
def test_report_on_other_scenes_completes(name, scene_report):
    run = scene_report(name)  # written once for the session (the PDF tests read it too)
    assert run.code == 0, run.err[-2000:]
    html = (run.folder / "index.html").read_text(encoding="utf-8")
    assert (run.folder / "report.pdf").read_bytes().startswith(b"%PDF")
    assert "Scene summary" in html and name in html
    if name != "cam_follower":
        # no motor-driven drivetrain: the drivetrain sections say so, politely
        stiff = re.search(r'<section id="stiffness" data-status="([^"]+)">(.*?)</section>', html, re.S)
        assert stiff.group(1) == "n/a" and "needs a motor-driven drivetrain" in stiff.group(2)
    assert "wrote" in run.out


@pytest.mark.parametrize("name", [p.stem for p in SCENE_FILES])
def test_every_shipped_scene_reports_every_section(name, scene_report):
    """No section of a shipped scene's report is unavailable (a study that cannot run on a
    scene says n/a and why; unavailable means it failed)."""
    run = scene_report(name)
    html = (run.folder / "index.html").read_text(encoding="utf-8")
    failed = re.findall(r'<section id="([^"]+)" data-status="unavailable">', html)
    assert not failed, (failed, run.err[-2000:])


def test_bad_scene_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENES / "ema_reference.toml").read_text().replace('lead = "5 mm"', 'lead = "0 mm"'))
    assert main(["report", str(bad), "-o", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "drivetrain[1].lead" in err
    assert not (tmp_path / "r").exists()


def test_a_failing_section_becomes_a_box_and_the_report_completes():
    ctx = Context(load_scene())

    def broken(_ctx):
        raise ZeroDivisionError("float division by zero")

    def missing(_ctx):
        raise NotAvailable("servo_toolkit.no_such_module cannot be imported")

    s = run_section("x", "Broken", broken, ctx)
    assert s.status == "unavailable" and "ZeroDivisionError" in s.reason
    s = run_section("y", "Missing", missing, ctx)
    assert s.status == "unavailable" and "servo_toolkit.no_such_module" in s.reason


def test_section_status_is_validated():
    with pytest.raises(ValueError):
        Section("x", status="maybe")


def test_shared_results_are_computed_once():
    ctx = Context(load_scene())
    calls = []

    def compute():
        calls.append(1)
        raise RuntimeError("boom")

    for _ in range(3):
        with pytest.raises(RuntimeError):
            ctx.result("k", compute)
    assert len(calls) == 1


def test_report_to_dict_lists_every_section():
    report = build_report(load_scene(SCENES / "roller_screw_two_stage.toml"), progress=False)
    d = report.to_dict()
    assert [s["key"] for s in d["sections"]][0] == "requirements"
    assert all(s["status"] in ("info", "pass", "fail", "n/a", "unavailable") for s in d["sections"])
    report.close()


def test_a_section_past_the_time_limit_is_stopped_and_says_so():
    """A stuck section becomes a box naming the limit; the next section still runs."""
    import time

    ctx = Context(load_scene())

    def stuck(_ctx):
        deadline = time.perf_counter() + 30.0
        while time.perf_counter() < deadline:   # pure Python: the alarm interrupts it
            pass
        return Section("never", "")

    s = run_section("slow", "Slow", stuck, ctx, time_limit=0.3)  # the 30 s loop is cut short
    assert s.status == "unavailable" and "stopped after 0.3 s" in s.reason
    assert "--section-time-limit" in s.reason
    # the timer is cleared: a later quick section is unaffected
    ok = run_section("quick", "Quick", lambda _c: (time.sleep(0.5), Section("Quick", "done"))[1], ctx)
    assert ok.status == "info"


def test_report_measures_what_the_reduction_costs(tmp_path):
    """The leaves-out section states the a-priori bound and the measured full-vs-reduced
    difference of the report's own sweep, and the measurement is within the bound."""
    from servo_toolkit.report.sections_limits import _measured_reduction

    ctx = Context(load_scene())
    res = _measured_reduction(ctx)
    assert res.frequencies_hz.size >= 2 and res.plan.effects
    # measured, not predicted: two sweeps of the same points, full and reduced model
    assert np.all(np.isfinite(res.difference[~res.saturated]))
    assert res.full_options != res.reduced_options or not res.plan.omitted
    assert res.within_bound, (res.measured, res.bound)
    section = run_section("reduce", "What the model leaves out", leaves_out, ctx)
    assert "Measured full (every effect kept, friction that holds included) against reduced" in section.html \
        and section.figures


def test_linear_output_sections_use_travel_units():
    """A drivetrain ending in a roller screw has an output travel: the report speaks mm, kg,
    rad/m and N/m, over the scene's stroke, not degrees."""
    from servo_toolkit.report.sections_drivetrain import ratio_and_inertia

    scene = load_scene(SCENES / "linear_roller_screw_actuator.toml")
    lo, hi = scene.drivetrain.stroke
    ctx = Context(scene)
    inertia = run_section("inertia", "Reflected inertia", ratio_and_inertia, ctx)
    assert inertia.status == "info", inertia.reason
    assert f"{lo * 1e3:+.4g} to {hi * 1e3:+.4g} mm" in inertia.html
    assert "rad/m" in inertia.html and "kg*m^2</td>" in inertia.html and "mass at the output" in inertia.html
    assert " deg" not in inertia.html
    # the reflected mass is the drivetrain's, in kg (independent: every element's m T^2 summed)
    parts = scene.drivetrain.reflected_inertias(np.array([0.0]))
    assert f"<td>{parts.total[0]:.4g}</td>" in inertia.html


def test_roller_screw_stroke_key():
    import tomllib

    from servo_toolkit.components.roller_screw.stages import RollerScrew
    from servo_toolkit.errors import SceneError
    from servo_toolkit.core.fields import Fields

    table = tomllib.loads((SCENES / "linear_roller_screw_actuator.toml").read_text())["drivetrain"][1]
    assert RollerScrew.from_table(Fields(table, "drivetrain[1]")).stroke == pytest.approx((-0.06, 0.06))
    table["stroke"] = ["60 mm", "-60 mm"]
    with pytest.raises(SceneError, match=r"drivetrain\[1\]\.stroke"):
        RollerScrew.from_table(Fields(table, "drivetrain[1]"))
    del table["stroke"]
    assert RollerScrew.from_table(Fields(table, "drivetrain[1]")).stroke is None


def test_a_travel_output_is_reported_in_mm_and_kg():
    """A chain ending in a screw: the time responses command 0.5 mm / 1 mm (not 1 deg / 2 deg
    read as metres) and every figure of the plant and the time sections is per mm or kg."""
    from servo_toolkit.report.sections_loop import plant_bode
    from servo_toolkit.report.sections_time import time_responses
    ctx = Context(load_scene(SCENES / "linear_roller_screw_actuator.toml"), light=True)
    time = run_section("time", "time", time_responses, ctx)
    assert time.status != "unavailable", time.reason
    assert "q0 = 0 mm" in time.html and " deg" not in time.html.replace("[deg]", "")
    rows = re.findall(r"<tr><td>(linear closed loop|nonlinear simulation)</td><td>([^<]+)</td><td>([^<]+)</td>"
                      r"<td>[^<]+</td><td>([^<]+)</td>", time.html)
    assert [r[0] for r in rows] == ["linear closed loop", "nonlinear simulation"]
    for _, rise_ms, overshoot, gain_db in rows:
        # a 0.5 mm step and a 1 mm sine of a 17 Hz loop: a rise of tens of ms, the 8 Hz gain near 0 dB
        assert 1.0 < float(rise_ms) < 100.0 and abs(float(gain_db)) < 3.0
    plant = run_section("plant", "plant", plant_bode, ctx)
    # one stiffness unit with `design`: N/m for an output travel
    assert "<td>kg</td>" in plant.html and "kg*m^2" not in plant.html and "<td>N/m</td>" in plant.html


def _legend_boxes(fig):
    """(legend boxes, axes boxes) of a drawn figure, in display pixels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    legends = [leg.get_window_extent(renderer) for leg in fig.legends]
    legends += [ax.get_legend().get_window_extent(renderer) for ax in fig.axes if ax.get_legend() is not None]
    return legends, [ax.get_window_extent(renderer) for ax in fig.axes]


def test_legends_sit_outside_every_axes_and_cover_no_curve():
    """Two panels filled by a sine (matplotlib's "best" place still covers it): one legend,
    each label once, outside both axes."""
    from servo_toolkit.report.figures import legends_outside, new_figure
    fig, (a1, a2) = new_figure(1, 2)
    t = np.linspace(0.0, 1.0, 400)
    for ax in (a1, a2):
        ax.plot(t, np.sin(40 * t), label="command")
        ax.plot(t, np.cos(40 * t), label="response")
        ax.legend()
    a2.plot(t, t, label="limit")
    a2.legend()
    legends_outside(fig)
    assert a1.get_legend() is None and a2.get_legend() is None and len(fig.legends) == 1
    assert [x.get_text() for x in fig.legends[0].get_texts()] == ["command", "response", "limit"]
    legends, boxes = _legend_boxes(fig)
    assert legends and not any(leg.overlaps(box) for leg in legends for box in boxes)


def test_report_figures_have_their_legend_outside_the_axes():
    """Every figure passes through :func:`legends_outside` when its section is built: the
    stiffness chain's figures (whose legend used to cover the stage curves)."""
    from servo_toolkit.report.sections_drivetrain import stiffness_chain
    section = run_section("stiffness", "Stiffness", stiffness_chain, Context(load_scene()))
    assert section.status == "info" and section.figures
    for spec in section.figures:
        legends, boxes = _legend_boxes(spec.figure)
        assert legends and not any(leg.overlaps(box) for leg in legends for box in boxes)


def test_a_section_stopped_by_its_time_limit_leaves_no_verdict_behind(monkeypatch):
    """A shared result that a section was computing when its time limit stopped it is not
    cached: the requirements table (built first, without a limit) and a later caller compute
    it in full, so the report's verdicts do not depend on the time limit."""
    import time

    import servo_toolkit.report.builder as builder

    ctx = Context(load_scene(SCENES / "deflection_platform.toml"))
    calls = []

    def slow():
        calls.append(1)
        deadline = time.perf_counter() + 0.6
        while time.perf_counter() < deadline:  # pure Python: the alarm interrupts it
            pass
        return "verdict"
    stopped = run_section("s", "Slow", lambda c: Section("Slow", c.result("shared", slow)), ctx, time_limit=0.2)
    assert stopped.status == "unavailable" and "stopped after 0.2 s" in stopped.reason
    assert ctx.result("shared", slow) == "verdict" and len(calls) == 2

    # the whole report: the requirement rows come first, so a limit that stops every section
    # cannot stop what the rows are computed from
    seen = []

    def rows(c):
        seen.append(c.result("shared", slow))
        return ("row",)
    monkeypatch.setattr(builder, "SECTIONS", (("a", "A", lambda c: Section("A", c.result("shared", slow))),))
    monkeypatch.setattr(builder, "REQUIREMENTS", ("requirements", "Requirements",
                                                  lambda c: Section("Requirements", str(rows(c)))))
    monkeypatch.setattr(builder.requirements_section, "requirement_rows", rows)
    report = builder.build_report(ctx.scene, progress=False, section_time_limit=0.2)
    assert report.section("requirements").status == "info" and report.requirements == ("row",)
    assert report.section("a").status == "info" and seen == ["verdict", "verdict"]
