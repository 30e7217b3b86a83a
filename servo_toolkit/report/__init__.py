"""HTML and PDF reports of a scene: one section builder per topic, failures isolated.

Examples
--------
>>> from servo_toolkit import load_scene
>>> from servo_toolkit.report import build_report, write_report
>>> report = build_report(load_scene(), progress=False)   # doctest: +SKIP
>>> write_report(report, "servo_report")                  # doctest: +SKIP
"""

from .builder import SECTIONS, Report, build_report, run_section, write_report
from .context import Context
from .section import NotApplicable, NotAvailable, Section

__all__ = ["SECTIONS", "Context", "NotApplicable", "NotAvailable", "Report", "Section",
           "build_report", "run_section", "write_report"]
