"""``servo-toolkit report``: the HTML (and PDF) report of a scene."""

from __future__ import annotations

import sys
import time

from .common import add_force, add_scene, bounded, check_design_budget, check_robustness_budget, load_scene
from .plant_frf import add_plant_frf_options, settle_plant_frf


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("report", help="HTML and PDF report of a scene (default: built-in EMA)")
    add_scene(p, optional=True)
    p.add_argument("-o", "--output", default="servo_report", metavar="DIR",
                   help="output folder (default: servo_report)")
    p.add_argument("--full", action="store_true",
                   help="run the expensive studies as the scene defines them: every sweep frequency with the "
                        "default dwell, the measured reduction on that sweep, longer accuracy runs and finer Kv "
                        "sampling (several minutes; default: light settings, under a minute)")
    p.add_argument("--design", metavar="FILE",
                   help="use the controller saved in FILE (a tuned design, servo_toolkit.loop.tuning.save_design) "
                        "instead of designing one")
    p.add_argument("--section-time-limit", type=bounded(float, 0.0, 86400.0, what="seconds"), default=None, metavar="S",
                   help="stop a section that runs longer than S seconds and say so in the report (default: "
                        "60 with light settings, none with --full; 0: no limit)")
    p.add_argument("--strict", action="store_true",
                   help="exit 1 when a row of the report's requirements table (the rows of servo-toolkit "
                        "check) is not met or could not be evaluated; the report is still written")
    add_plant_frf_options(p)
    add_force(p)
    p.set_defaults(run=run)


def _check_budget(scene, args, designs: bool) -> None:
    """The report's long sections within the work budget unless ``--force`` (before any
    work): the robustness study of a scene with ``[robustness]``, the time runs at the
    scene's sample time and, with ``--full``, the sweep and its reduction."""
    if not (scene.stages and scene.motor is not None):
        return
    from .budget import check_time, time_run_seconds
    check_robustness_budget(scene, scene.robustness, designs, None, args.force)
    seconds, what, _ = time_run_seconds(scene, 1.0, None, "rk4")
    check_time(seconds, "sensors.sample_time", what, f"{scene.sensors.sample_time:g} s", args.force)
    from ..studies.sweep.kind import SWEEP
    if args.full and scene.studies_of_kind(SWEEP.name):
        from .cmd_sweep import check_sweep_budget
        check_sweep_budget(scene, None, None, None, args.force, runs=3)


def run(args) -> int:
    """Run the command; exit 0 once the complete report is written, 1 when a section the
    scene needs is unavailable (the report is still written and says why) or, with
    ``--strict``, when a requirement is not met or not evaluated, 2 on a bad scene
    or an output folder that cannot take a report (checked before any work: it must be new,
    empty or an earlier report). The report is written into a temporary folder and renamed
    into place."""
    from ..report import build_report, write_report
    from ..report.builder import check_report_folder
    start = time.perf_counter()
    scene = load_scene(args.scene)
    measured = settle_plant_frf(args)  # a bad file: exit 2 before any work
    out_dir = check_report_folder(args.output, "--output",
                                  inputs=[args.scene, args.design, args.plant_frf, *scene.input_files])
    check_design_budget(scene, args.force)  # before a --design file is evaluated
    given = None
    if args.design:
        from ..loop.tuning import load_design
        given = load_design(scene, args.design)
    _check_budget(scene, args, given is None)
    limit = "auto" if args.section_time_limit is None else (args.section_time_limit or None)
    report = build_report(scene, light=not args.full, progress=True, section_time_limit=limit, design=given,
                          plant_frf=measured, plant_frf_signal=args.plant_frf_signal)
    paths = write_report(report, out_dir, progress=True, key="--output")  # swapped in whole
    report.close()
    if paths["pdf_engine"] != "weasyprint":
        from ..report.pdf_writer import engine_problem
        print(f"servo-toolkit: report.pdf is the plain fallback: {engine_problem()}", file=sys.stderr)
    missing = [s for s in report.sections if s.status == "unavailable"]
    for i, s in enumerate(report.sections, 1):
        if s.status in ("unavailable", "n/a"):
            print(f"servo-toolkit: {s.title}: {s.status}: {s.reason}", file=sys.stderr)
        for problem in s.layout:
            print(f"servo-toolkit: layout of section {i} ({s.title}), {problem}", file=sys.stderr)
    print(f"wrote {paths['html']} and {paths['pdf']} ({time.perf_counter() - start:.1f} s)")
    if missing:
        print(f"servo-toolkit: the report is incomplete: {len(missing)} section(s) unavailable: "
              + ", ".join(s.title for s in missing), file=sys.stderr)
        return 1
    if args.strict and not report.passed:
        failed = [r.id for r in report.requirements if r.status == "fail"]
        missing = [r.id for r in report.requirements if r.status not in ("pass", "fail")]
        print("servo-toolkit: " + "; ".join(
            [f"{len(failed)} requirement(s) not met: {', '.join(failed)}"] * bool(failed)
            + [f"{len(missing)} requirement(s) not evaluated: {', '.join(missing)}"] * bool(missing)), file=sys.stderr)
        return 1
    return 0
