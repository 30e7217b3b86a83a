"""``servo-toolkit report``: the HTML (and PDF) report of a scene."""

from __future__ import annotations

import sys
import time

from ..scene import load_scene
from .common import add_scene


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("report", help="HTML and PDF report of a scene (default: built-in EMA)")
    add_scene(p, optional=True)
    p.add_argument("-o", "--output", default="servo_report", metavar="DIR",
                   help="output folder (default: servo_report)")
    p.add_argument("--full", action="store_true",
                   help="full settings for the expensive studies (slower; default: light settings)")
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command; exit 0 once the report is written (2 on a bad scene)."""
    from ..report import build_report, write_report
    start = time.perf_counter()
    scene = load_scene(args.scene)
    report = build_report(scene, light=not args.full, progress=True)
    paths = write_report(report, args.output)
    report.close()
    for s in report.sections:
        if s.status in ("unavailable", "n/a"):
            print(f"servo-toolkit: {s.title}: {s.status}: {s.reason}", file=sys.stderr)
    print(f"wrote {paths['html']} and {paths['pdf']} ({time.perf_counter() - start:.1f} s)")
    return 0
