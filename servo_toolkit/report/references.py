"""The sources the report's methods come from: a numbered list printed at the end of every
report, and the wording that names each method and its source in the report's text
(``Ref. [n]``) instead of a name only the toolkit's code knows."""

from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class Reference:
    """One entry of the reference list.

    Attributes
    ----------
    number : int
        Its number in the list, ``[number]``.
    authors, title, where : str
        As published (the Chinese papers under their English titles and author names; the
        year, issue and pages read off each paper's own article number, e.g.
        ``2095-8110(2018)05-0049-05``: 2018, no. 5, from p. 49, 5 pages).
    method : str
        The method of the toolkit taken from it, in words an engineer reads.
    """

    number: int
    authors: str
    title: str
    where: str
    method: str

    @property
    def cite(self) -> str:
        """``Ref. [n]``."""
        return f"Ref. [{self.number}]"

    def text(self) -> str:
        """The entry as one line of the reference list."""
        return f"[{self.number}] {self.authors}. {self.title}. {self.where}. Used for: {self.method}."

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"number": self.number, "authors": self.authors, "title": self.title, "where": self.where,
                "method": self.method}


#: the reference list, in the order of its numbers
REFERENCES = (
    Reference(1, "LIU Hai, DUAN Xiao-shuai, HUANG Jian",
              "Dynamics Analysis on the Transmission Mechanism of Electro-Mechanical Actuators Based on "
              "Equivalent Finite Element Method",
              "Navigation Positioning and Timing, 2018, no. 5, pp. 49-53, doi:10.19306/j.cnki.2095-8110.2018.05.009 "
              "(in Chinese)",
              "the equivalent-element method (lumped masses, Jacobians of the linkage) and the dynamic-load "
              "factor Kv"),
    Reference(2, "LIU Yuan, WANG Yong-le, CAO Dong-hai, LIU Tao", "A Stiffness Calculation Method of Servo Mechanism",
              "Navigation Positioning and Timing, 2014, no. 2, pp. 46-49 (in Chinese)",
              "series stiffness reflected through the square of the ratio, the criterion for neglecting front "
              "stages, and the measured stiffness of a test rig"),
    Reference(3, "LI Xing-Hua, ZHAI Lin-Pei", "Modeling and Simulation of Electromechanical System with Cam Mechanism",
              "Changchun Institute of Optics and Fine Mechanics, Chinese Academy of Sciences (in Chinese)",
              "the cam drive's load and inertia, the clearance (play) operator and the frozen-configuration "
              "fixed-step scheme"),
    Reference(4, "CHEN Chun, XU Yongshuai, WANG Jiawei, FANG Zhou, WEI Bihui",
              "Design and Dynamic Analysis of Novel Parallel Bidirectional Deflection Platform",
              "Transactions of the Chinese Society for Agricultural Machinery, 2019, 50(5): 420-426 (in Chinese)",
              "the crossed-arch platform's kinematics and Lagrange dynamics"),
    Reference(5, "LI Xin, LIU Geng, SONG Chunyu, FU Xiaojun, MA Shangjun, WAN Qi",
              "Rigid-Body Dynamic Analysis of Multi-Stage Planetary Roller Screw Mechanism",
              "Journal of Northwestern Polytechnical University, 2020, 38(5): 1001-1009 (in Chinese)",
              "the multi-stage planetary roller screw's kinematics, joint friction and efficiency"),
    Reference(6, "Modelica Association", "Modelica Standard Library: Modelica.Mechanics.Rotational.Components.LossyGear",
              "https://doc.modelica.org (model documentation)",
              "the gear loss that switches with the direction of the power flow, and its stuck mode"),
)

#: name of each method in the report's text (a reader meets these, never the code's own names)
EQUIVALENT_ELEMENT = f"equivalent-element method ({REFERENCES[0].cite})"
SERIES_STIFFNESS = f"series-stiffness method ({REFERENCES[1].cite})"
NEGLECT_CRITERION = f"front-stage criterion ({REFERENCES[1].cite})"
FROZEN_SCHEME = f"frozen-configuration scheme ({REFERENCES[2].cite})"
LOSSY_GEAR = f"power-flow gear loss ({REFERENCES[5].cite})"

_SEED = {f"00{k}": ref.cite for k, ref in enumerate(REFERENCES[:5])}

#: an apostrophe in plain text or in escaped HTML
_APOS = "(?:'|&#x27;)"

#: (pattern, replacement) applied in order to the text of every section: names that come
#: from the toolkit's lower layers (their notes, their docstrings) said in the report's words
_WORDING = (
    (re.compile(r"\bseeds (00[0-4])/(00[0-4]) class\b"),
     lambda m: f"the actuator class of Refs. [{int(m[1]) + 1}] and [{int(m[2]) + 1}]"),
    (re.compile(rf"\b[Ss]eed (00[0-4]){_APOS}s (neglect )?criterion\b"), lambda m: NEGLECT_CRITERION
     if m[1] == "001" else f"the criterion of {_SEED[m[1]]}"),
    (re.compile(rf"\b[Ss]eed (00[0-4]){_APOS}s\b"), lambda m: f"{_SEED[m[1]]}'s"),
    (re.compile(r"\b[Ss]eed (00[0-4])\b"), lambda m: _SEED[m[1]]),
    (re.compile(rf"\bthe paper scheme{_APOS}s\b"), lambda m: f"the {FROZEN_SCHEME}'s"),
    (re.compile(r"\bpaper scheme\b"), lambda m: FROZEN_SCHEME),
    (re.compile(rf"\bthe cam paper{_APOS}s\b"), lambda m: f"{REFERENCES[2].cite}'s"),
    (re.compile(r"\bLossyGear-like\b"), lambda m: LOSSY_GEAR),
    (re.compile(rf"\bLossyGear{_APOS}s stuck mode\b"),
     lambda m: f"the stuck mode of Modelica's LossyGear, {REFERENCES[5].cite}"),
    (re.compile(rf"\bModelica{_APOS}s LossyGear\b(?!, Ref)"), lambda m: f"Modelica's LossyGear ({REFERENCES[5].cite})"),
)


def reader_words(text: str) -> str:
    """``text`` (plain, or HTML whose apostrophes are escaped) with the toolkit's internal
    names of methods and sources (``seed 001``, ``paper scheme``, ``LossyGear-like``) replaced
    by the method's name and its reference."""
    for pattern, replace in _WORDING:
        text = pattern.sub(replace, text)
    return text


__all__ = ["EQUIVALENT_ELEMENT", "FROZEN_SCHEME", "LOSSY_GEAR", "NEGLECT_CRITERION", "REFERENCES", "Reference",
           "SERIES_STIFFNESS", "reader_words"]
