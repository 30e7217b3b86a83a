"""Jupyter display: a one-line repr and an HTML card for every result, whose numbers are the
result's own (to_dict), never a copy typed into the card."""

from __future__ import annotations

import math
from html.parser import HTMLParser

import pytest

from servo_toolkit import load_scene
from servo_toolkit.display.cards import num
from servo_toolkit.loop import design
from servo_toolkit.loop.robustness import robustness
from servo_toolkit.report.builder import Report
from servo_toolkit.report.section import Section
from servo_toolkit.sim import Reference, simulate
from servo_toolkit.studies.kv.study import kv_study
from servo_toolkit.studies.reduce import reduce
from servo_toolkit.studies.stiffness import stiffness_study
from servo_toolkit.studies.sweep.compute import sweep
from servo_toolkit.studies.gate import RequirementRow

from .conftest import SCENES


class _Checker(HTMLParser):
    """Counts open/close tags of the elements a card uses: every one must be closed."""
    TAGS = {"div", "table", "thead", "tbody", "tr", "td", "th", "p", "h4", "span", "style", "svg", "b"}

    def __init__(self):
        super().__init__()
        self.depth = {t: 0 for t in self.TAGS}

    def handle_starttag(self, tag, attrs):
        if tag in self.TAGS:
            self.depth[tag] += 1

    def handle_endtag(self, tag):
        if tag in self.TAGS:
            self.depth[tag] -= 1


def _well_formed(html: str) -> None:
    c = _Checker()
    c.feed(html)
    assert all(v == 0 for v in c.depth.values()), c.depth


@pytest.fixture(scope="module")
def ema():
    return load_scene(SCENES / "ema_reference.toml")


@pytest.fixture(scope="module")
def designed(ema):
    return design(ema, progress=False)


def _results(ema, designed):
    linear = load_scene(SCENES / "linear_roller_screw_actuator.toml")
    return {
        "scene": ema,
        "design": designed,
        "simulation": simulate(ema, designed.controller, reference=Reference.sine(math.radians(2.0), 8.0),
                               duration=0.125),
        "sweep": sweep(ema, frequencies=[8.0], progress=False),
        "kv": kv_study(ema, "kv_8hz", progress=False),
        "stiffness": stiffness_study(ema),
        "robustness": robustness(ema, designed, {"stiffness": (0.8, 1.2)}, samples=20, progress=False),
        "reduction": reduce(linear, progress=False, per_effect=False),
        "report": Report("ema_reference", "test", (Section("Loop", status="pass", key="loop"),),
                         (RequirementRow("bandwidth", "closed-loop bandwidth", ">= 8 Hz", "18 Hz", "", "pass"),)),
    }


@pytest.fixture(scope="module")
def results(ema, designed):
    return _results(ema, designed)


@pytest.mark.parametrize("kind", ["scene", "design", "simulation", "sweep", "kv", "stiffness", "robustness",
                                  "reduction", "report"])
def test_repr_is_one_short_line_and_the_card_is_well_formed(results, kind):
    r = results[kind]
    text = repr(r)
    assert "\n" not in text and len(text) < 300, text
    assert "array(" not in text and "StateSpace" not in text
    html = r._repr_html_()
    _well_formed(html)
    assert len(html) < 400_000


def test_design_card_carries_the_margins_and_the_requirement_rows(results):
    d = results["design"]
    html = d._repr_html_()
    data = d.to_dict()
    for key, unit in (("gain_margin_db", "dB"), ("phase_margin_deg", "deg"), ("bandwidth_hz", "Hz"),
                      ("sensitivity_peak_db", "dB")):
        assert f"{num(data[key])} {unit}" in html, key
    for name, row in data["requirements"].items():
        if name != "closed_loop_stable":
            assert name in html
    assert html.count('class="st-fail"') == sum(1 for c in d.requirements if not c.passed)
    assert ("PASS" in html) == d.passed
    assert "<svg" in html  # the Bode plot


def test_simulation_and_sweep_cards_use_their_figures(results):
    s = results["simulation"]
    d = s.to_dict()
    html = s._repr_html_()
    assert f"{num(d['max_abs_current_A'])} A" in html
    assert f"{num(d['max_abs_tracking_error_deg'])} deg" in html
    sw = results["sweep"]
    dev = sw.deviation()
    assert f"{num(dev['max_gain_difference_dB'][0], 3)} dB" in sw._repr_html_()


def test_kv_and_reduction_cards(results):
    k = results["kv"]
    html = k._repr_html_()
    for c in k.to_dict()["cases"]:
        assert num(c["kv_motor"], 4) in html
    r = results["reduction"]
    assert r.verdict in r._repr_html_() and "left out" in repr(r)


def test_scene_card_shows_the_reflected_drivetrain(ema):
    html = ema._repr_html_()
    dt = ema.drivetrain
    assert f"{num(dt.efficiency, 3)} driving" in html
    assert "drivetrain[0]" in html and ema.name in repr(ema)
