"""The report names each method and its source in words an engineer outside the toolkit reads:
"the equivalent-element method (Ref. [1])", with the reference list (authors, title, where
published) at the end, never the toolkit's internal names ("seed 001", "paper scheme",
"LossyGear-like"); times at the drive's limits read as sentences."""

from __future__ import annotations

import math
import re

import pytest

from servo_toolkit import load_scene
from servo_toolkit.report.builder import SECTIONS, Report, run_section
from servo_toolkit.report.context import Context
from servo_toolkit.report.document import render
from servo_toolkit.report.references import REFERENCES, reader_words

#: names a reader of the report cannot know
INTERNAL = re.compile(r"\bseeds? 00\d|\bpaper scheme|LossyGear-like|\bcam paper|\bthe paper's\b|"
                      r"of \d(\.\d+)?e[+-]\d+ ms", re.I)


def test_internal_names_become_the_method_and_its_reference():
    assert reader_words("(seed 001, eq 8)") == "(Ref. [2], eq 8)"
    assert reader_words("Seed 001's criterion: a front stage") == "front-stage criterion (Ref. [2]): a front stage"
    assert reader_words("Rocker-arm EMA, seeds 000/001 class") == "Rocker-arm EMA, the actuator class of Refs. [1] and [2]"
    assert reader_words("RK4 4.2; paper scheme 1.1") == "RK4 4.2; frozen-configuration scheme (Ref. [3]) 1.1"
    text = reader_words("efficiency 0.87 driving (LossyGear-like loss on the torque); as Modelica's LossyGear models")
    assert "power-flow gear loss (Ref. [6])" in text and "Modelica's LossyGear (Ref. [6]) models" in text
    assert not INTERNAL.search(text)
    html = reader_words("as Modelica&#x27;s LossyGear models a gear; Seed 001&#x27;s criterion")  # escaped HTML
    assert html == "as Modelica's LossyGear (Ref. [6]) models a gear; front-stage criterion (Ref. [2])"


def test_the_reference_list_gives_authors_titles_and_journals():
    assert [r.number for r in REFERENCES] == list(range(1, len(REFERENCES) + 1))
    first, second = REFERENCES[0], REFERENCES[1]
    assert "LIU Hai" in first.authors and "Equivalent Finite Element Method" in first.title
    assert "2095-8110.2018.05.009" in first.where
    assert second.title == "A Stiffness Calculation Method of Servo Mechanism" and "LIU Yuan" in second.authors
    for ref in REFERENCES:
        assert ref.authors and ref.title and ref.where and ref.method


def test_time_at_the_drive_limits_reads_as_a_sentence():
    from servo_toolkit.studies.gate import LargeSignal
    quiet = LargeSignal(8.0, math.radians(2.0), -1.4, -71.1, -1.4, -71.1, 0.0, 0.0, 1.0, 41.3, 53.2)
    note = quiet.note(False)
    assert "the drive reached neither its voltage nor its current limit in the 1000 ms run" in note, note
    assert not INTERNAL.search(note) and "0 ms of" not in note
    busy = LargeSignal(8.0, math.radians(2.0), -1.4, -71.1, -1.4, -71.1, 0.0125, 0.25, 1.0, 60.0, 53.2)
    assert "12.5 ms at its voltage limit and 250 ms at its current limit in the 1000 ms run" in busy.note(False)


@pytest.fixture(scope="module")
def worded_sections():
    """The reference EMA's sections that name a method from the seed papers."""
    ctx = Context(load_scene())
    keys = ("stiffness", "sweep", "kv", "reduce", "accuracy")
    return [run_section(key, title, build, ctx) for key, title, build in SECTIONS if key in keys]


def test_the_sections_name_methods_and_cite_the_list(worded_sections):
    html = " ".join(s.html for s in worded_sections)
    assert all(s.status == "info" for s in worded_sections), [(s.title, s.reason) for s in worded_sections]
    assert not INTERNAL.search(html), INTERNAL.search(html)
    for words in ("series-stiffness method (Ref. [2])", "front-stage criterion (Ref. [2])",
                  "may be neglected (Ref. [2])", "equivalent-element method (Ref. [1])",
                  "frozen-configuration scheme (Ref. [3])", "power-flow gear loss (Ref. [6])",
                  "Modelica's LossyGear (Ref. [6])"):
        assert words in html, words
    captions = [f.figure.axes[0].get_legend_handles_labels()[1] for s in worded_sections if s.key == "accuracy"
                for f in s.figures]
    assert not any(INTERNAL.search(label) or label == "paper" for labels in captions for label in labels)
    page = render(Report("ema_reference", "words", tuple(worded_sections), ()), "html")
    refs = re.search(r'<section id="references">(.*?)</section>', page, re.S)
    assert refs, "the reference list closes the report"
    for ref in REFERENCES:
        assert f'id="ref-{ref.number}"' in refs.group(1) and ref.title in refs.group(1)
