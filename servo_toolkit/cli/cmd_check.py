"""``servo-toolkit check``: gate one or more scenes on their loop requirements.

Exit 0 when every requirement holds for every scene, 1 when some do not (a table says which
and by how much), 2 on bad input. A scene's ``[robustness]`` (or ``--vary``) adds its
robustness requirements, checked on the worst variant: ``robust_stable_fraction``,
``robust_gain_margin``, ``robust_phase_margin``, ``robust_sensitivity_peak`` (and
``robust_bandwidth`` when the table sets ``min_bandwidth``). A scene with ``[robustness]`` is
designed robustly (``--nominal`` checks the nominal design over the same variants).
A scene with a ``[duty_cycle]`` adds the rows of its sizing (inverse dynamics along the
cycle, as ``servo-toolkit size --no-sweep``): the motor's envelope (``envelope_peak_torque``,
``envelope_rms_torque``, ``envelope_peak_current``, ``envelope_peak_voltage``), the winding's
``thermal_margin``, a roller screw's ``static_load_<screw>`` (peak thrust against its static
rating) and, when the cycle sets ``required_life``, the L10 lives (``life_<part>``).
A scene that requires a yield (``min_yield`` in ``[tolerances]`` or ``[robustness]``) adds
the rows of its tolerance study (:mod:`servo_toolkit.studies.tolerances.run`): ``yield`` (every
requirement at once) and ``yield_<requirement>``, each met when the lower end of the yield's
Clopper-Pearson interval reaches ``min_yield``.
"""

from __future__ import annotations

import re
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from ..errors import SceneError, SimulationError
from ..core.files import atomic_file, check_output_file
from .cmd_design import add_design_options, add_large_signal_option, design_from_args
from .plant_frf import add_plant_frf_options, plant_frf_check, settle_plant_frf
from .common import (add_force, add_json, add_scheduler, bounded, check_design_budget, check_robustness_budget,
                     load_scene, scheduler_of, study_executor, to_json)


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("check", help="check loop requirements (exit 0 met, 1 not met, 2 bad input)")
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene TOML files")
    add_design_options(p)
    add_large_signal_option(p)
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LO:HI",
                   help="robustness: vary load_inertia (kg*m^2, kg for a travel output: 0 or 1e-12..1e6) or stiffness (a factor, 1e-3..1e3), e.g. "
                        "load_inertia=0:4 stiffness=0.7:1.3 (repeatable; replaces that range of the "
                        "scene's [robustness]; a positive range over a decade is sampled logarithmically, "
                        "and the corners of the ranges are always among the variants)")
    p.add_argument("--samples", type=bounded(int, 1, 1_000_000, what="a number of variants"), default=None,
                   help="variants of the robustness study (default: the scene's [robustness] samples, else 1000)")
    p.add_argument("--junit", metavar="FILE", help="write JUnit XML: one testcase per scene and requirement")
    add_scheduler(p, workers=False, what="the chunks of the robustness variants (margins and Monte Carlo runs)")
    add_plant_frf_options(p)
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def _cases(rows):
    """(test name, passed, message) per row of the requirement table
    (:mod:`servo_toolkit.studies.gate`): the JUnit testcases."""
    return [(r.id, r.passed, r.message()) for r in rows]


def robustness_spec(scene, varies: dict, samples):
    """The scene's ``[robustness]`` with the command line's ranges and sample count, or None
    when neither asks for a robustness study."""
    from dataclasses import replace

    from ..scene.loader import Robustness
    base = scene.robustness
    if base is None and not varies:
        return None
    spec = base if base is not None else Robustness(load_inertia=None, stiffness=None)
    spec = replace(spec, **varies)
    if samples is not None:
        if samples < 1:
            raise SceneError("--samples", f"must be at least 1 (got {samples})")
        spec = replace(spec, samples=samples)
    return spec


#: characters XML 1.0 forbids (C0 controls but tab, newline and carriage return; surrogates;
#: U+FFFE and U+FFFF)
_XML_FORBIDDEN = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def xml_text(text: str) -> str:
    """``text`` with every character XML 1.0 forbids written as a visible escape (``\\x1b``)."""
    return _XML_FORBIDDEN.sub(lambda m: f"\\x{ord(m.group()):02x}" if ord(m.group()) < 0x100
                              else f"\\u{ord(m.group()):04x}", text)


def _xml_safe(root) -> None:
    """Every text and attribute value of the tree made valid XML 1.0 (:func:`xml_text`)."""
    for element in root.iter():
        element.attrib.update({k: xml_text(v) for k, v in element.attrib.items()})
        if element.text:
            element.text = xml_text(element.text)


def write_junit(path, entries) -> None:
    """JUnit XML: a testsuite per scene, a testcase per requirement.

    ``entries`` holds (suite name, cases) with cases (test name, passed, message), or
    (suite name, SceneError or SimulationError) for a scene that could not be checked: one
    testcase ``check`` with an ``error`` element (JUnit's "could not run", apart from a
    failed requirement), or (suite name, :class:`Skipped`) for a scene without a loop to
    check: one testcase ``check`` with a ``skipped`` element giving the reason.
    """
    root = ET.Element("testsuites", name="servo-toolkit check")
    for name, cases in entries:
        if isinstance(cases, Skipped):
            suite = ET.SubElement(root, "testsuite", name=name, tests="1", failures="0", errors="0", skipped="1")
            case = ET.SubElement(suite, "testcase", classname=name, name="check")
            ET.SubElement(case, "skipped", message=cases.reason)
            continue
        if isinstance(cases, (SceneError, SimulationError)):
            suite = ET.SubElement(root, "testsuite", name=name, tests="1", failures="0", errors="1")
            case = ET.SubElement(suite, "testcase", classname=name, name="check")
            ET.SubElement(case, "error", message=str(cases), type=type(cases).__name__).text = str(cases)
            continue
        suite = ET.SubElement(root, "testsuite", name=name, tests=str(len(cases)),
                              failures=str(sum(not ok for _, ok, _ in cases)), errors="0")
        for test, ok, message in cases:
            case = ET.SubElement(suite, "testcase", classname=name, name=test)
            if ok:
                ET.SubElement(case, "system-out").text = message
            else:
                ET.SubElement(case, "failure", message=message, type="RequirementNotMet").text = message
    _xml_safe(root)  # a scene name or message with control characters still parses
    with atomic_file(path, "--junit") as tmp:  # never a half-written report
        ET.ElementTree(root).write(tmp, encoding="utf-8", xml_declaration=True)


@dataclass(frozen=True)
class Skipped:
    """A scene the gate has nothing to check in: it has no motor-driven loop.

    Attributes
    ----------
    reason : str
        Why, and what to run for the scene instead.
    """

    reason: str


def skip_reason(scene, path) -> str | None:
    """Why ``check`` skips ``scene`` (no motor-driven drivetrain, so no loop to gate), or
    None when it has a loop to check."""
    from ..studies.run import has_motor_drivetrain
    from .hints import what_to_run
    if has_motor_drivetrain(scene):
        return None
    return f"no motor-driven drivetrain, so no loop to check; to exercise it {what_to_run(scene, path)}"


def _is_junit(path: Path) -> bool:
    """True when ``path`` holds a JUnit XML report (an earlier ``--junit`` output)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    return b"<testsuites" in head or (head.lstrip().startswith(b"<?xml") and b"<testsuite" in head)


def check_writable(path, inputs=()) -> None:
    """SceneError (key ``--junit``) unless a JUnit file may be written at ``path``: its folder
    must exist, ``path`` must not be a folder, one of the ``inputs`` (the scenes), or an
    existing file that is not a JUnit report (nothing a user has is overwritten). Checked
    before any design runs. An empty path (an unset variable in a CI script) is an error,
    not a request to write none (:func:`~servo_toolkit.core.files.check_named`, as for every
    output)."""
    p = check_output_file(path, "--junit", inputs=inputs)
    if p.is_file() and not _is_junit(p):
        raise SceneError("--junit", f"refusing to overwrite {str(path)!r}: it exists and is not a JUnit report")


def _tagged(exc: SceneError, path) -> SceneError:
    """The error naming the scene file it came from."""
    return exc if exc.source else exc.with_source(str(path))


def row_lines(rows) -> list[str]:
    """One text line per requirement row: its ID, ``ok`` or ``FAIL``, and its message, the IDs
    in a column as wide as the longest (at least 24 characters) so the verdicts line up."""
    width = max([24] + [len(r.id) + 2 for r in rows])
    return [f"  {r.id:<{width}}{'ok' if r.passed else 'FAIL'}  {r.message()}" for r in rows]


def _check_tolerance_budget(scene, args) -> None:
    """Refuse (exit 2, naming ``tolerances.samples``) a yield study estimated beyond the work
    budget, unless ``--force``: checked before any work."""
    from .budget import check_time, tolerance_seconds
    tol = scene.tolerances
    if tol is None or tol.min_yield is None:
        return
    timed = not getattr(args, "linear_only", False) and (tol.max_tracking_error is not None
                                                          or tol.max_peak_current is not None)
    seconds, what = tolerance_seconds(scene, tol.samples, timed)
    check_time(seconds, "tolerances.samples", what, tol.samples, args.force)


def _check_scene(path, scene, args, varies, executor=None, design_text=None):
    """Design and check one scene: (suite name, cases, JSON dict); ``executor`` runs the
    chunks of its variants; ``design_text`` is the ``--design`` file's text (read once for
    every scene)."""
    from ..loop.result import requirements_table
    from ..studies.actuator.result import IDS as ACTUATOR_IDS
    from ..studies.gate import SIZING_ROWS, gate
    sizing_ids = {rid for rid, _ in SIZING_ROWS.values()}
    spec = robustness_spec(scene, varies, args.samples)
    if not getattr(args, "design", None):
        robust = args.robust is True or (args.robust is None and scene.robustness is not None)
        check_robustness_budget(scene, spec, robust, args.samples, args.force)
    _check_tolerance_budget(scene, args)
    check_design_budget(scene, args.force)
    g = gate(scene, design_from_args(scene, args, spec, executor=executor, design_text=design_text), spec,
             linear_only=getattr(args, "linear_only", False), executor=executor)
    result, ls, robust = g.result, g.large_signal, g.robustness
    measured = plant_frf_check(args, scene, result) if getattr(args, "plant_frf", None) else ((), None, "")
    cases = _cases((*g.rows, *measured[0]))
    ok = g.passed and all(r.passed for r in measured[0])
    d = result.to_dict()
    d["source"] = str(path)
    d["passed"] = ok
    # the verdict is every row's (sizing, yield and Monte Carlo rows too), not only the loop's
    d["loop_requirements_met"] = d["requirements_met"]
    d["requirements_met"] = ok
    d["rows"] = [r.to_dict() for r in (*g.rows, *measured[0])]
    if measured[1] is not None:
        d["measured_plant"] = measured[1]
    if ls is not None:
        d["large_signal"] = ls.to_dict()
    if g.actuator is not None:
        d["actuator"] = g.actuator.to_dict()
    if robust is not None:
        d["robustness"] = robust.to_dict()
    if g.montecarlo is not None:
        mc = g.montecarlo
        d["montecarlo"] = {"requirements": {c.name: c.to_dict() for c in g.montecarlo_checks},
                           "worst": mc.worst(), "samples": mc.count, "failed_variants": int(mc.failed.sum())}
    if g.sizing is not None:
        d["sizing"] = g.sizing.to_dict()
    if g.tolerances is not None:
        d["tolerances"] = g.tolerances.to_dict()
    if not args.json:
        print(f"{scene.name} ({path}): {'PASS' if ok else 'FAIL'}")
        print(requirements_table(result.requirements, stable=bool(result.margins.closed_loop_stable)))
        if robust is not None:
            print(robust.table())
        extra = [r for r in g.rows  # the rows beyond the loop's table, in the gate's order (the actuator's first)
                 if r.id in ACTUATOR_IDS or r.id in ("robust_tracking_error", "robust_peak_current")
                 or r.id in sizing_ids or r.id.startswith(("life_", "static_load_", "yield"))]
        for line in row_lines(extra):
            print(line)
        for n in (*result.notes, *(g.actuator.notes if g.actuator is not None else ())):
            print(f"  note: {n}")
        if measured[2]:
            print(measured[2])
    return scene.name, cases, d


def _executor(scheduler, scenes, paths):
    """:func:`~.common.study_executor` of ``--scheduler`` when some scene has a loop to check,
    else nothing to open."""
    if scheduler is not None and not any(not isinstance(s, SceneError) and skip_reason(s, p) is None
                                         for s, p in zip(scenes, paths)):
        scheduler = None
    return study_executor(scheduler)


def _check_all(args, scenes, varies, executor, design_text=None):
    """Check every scene: (JUnit entries, errors, skipped, all met, JSON list)."""
    entries, out, all_ok, errors, skipped = [], [], True, 0, 0
    for path, scene in zip(args.scenes, scenes):
        reason = None if isinstance(scene, SceneError) else skip_reason(scene, path)
        if reason is not None:
            skipped += 1
            entries.append((scene.name, Skipped(reason)))
            out.append({"source": str(path), "scene": scene.name, "name": scene.name, "skipped": True, "reason": reason,
                        "passed": None})
            if not args.json:
                print(f"{scene.name} ({path}): SKIPPED: {reason}")
            continue
        try:
            if isinstance(scene, SceneError):
                raise scene
            name, cases, d = _check_scene(path, scene, args, varies, executor, design_text)
        except SimulationError as exc:  # its own nonlinear run could not run: no verdict, exit 2
            print(f"servo-toolkit: simulation error: {path}: {exc}", file=sys.stderr)
            errors += 1
            entries.append((scene.name, exc))
            out.append({"source": str(path), "passed": False, "error": str(exc), "key": "simulation",
                        "rule": str(exc)})
            continue
        except SceneError as exc:
            exc = _tagged(exc, path)
            if exc is not scene:
                print(f"servo-toolkit: error: {exc}", file=sys.stderr)
            errors += 1
            entries.append((str(path) if isinstance(scene, SceneError) else scene.name, exc))
            out.append({"source": str(path), "passed": False, "error": str(exc), "key": exc.key,
                        "rule": exc.rule})
            continue
        ok = all(c[1] for c in cases)
        all_ok &= ok
        entries.append((name, cases))
        out.append(d)
    return entries, errors, skipped, all_ok, out


def run(args) -> int:
    """Run the command.

    Errors of the command line (``--require``, ``--vary``, ``--samples``, an unwritable
    ``--junit`` path) stop before any design. A scene without a motor-driven drivetrain has
    no loop to gate: it is reported as skipped (a ``skipped`` testcase in the JUnit file,
    ``"skipped": true`` in the JSON) and does not change the exit code. A scene that cannot
    be checked (it does not load, or its own nonlinear run, large-signal or Monte Carlo,
    cannot be carried out) is reported on one stderr line naming its file and becomes an
    ``error`` testcase of the JUnit file; the other scenes are still checked and written,
    and the exit code is 2.
    """
    from ..loop.requirements import parse_overrides
    from ..loop.vary import parse_vary
    varies = dict(parse_vary(text) for text in args.vary)
    parse_overrides(args.require)
    if getattr(args, "plant_frf", None):
        settle_plant_frf(args)  # a bad file stops before any design
    if args.samples is not None and args.samples < 1:
        raise SceneError("--samples", f"must be at least 1 (got {args.samples})")
    if args.junit is not None:
        check_writable(args.junit, args.scenes)
    design_text = None
    if getattr(args, "design", None):  # the one design file every scene is checked with: read once, before any work
        from ..loop.tuning import read_design_text
        design_text = read_design_text(args.design)
    scheduler = scheduler_of(args)
    scenes = []
    for path in args.scenes:  # every file is read before any design runs
        try:
            scenes.append(load_scene(path))
        except SceneError as exc:
            scenes.append(_tagged(exc, path))
            print(f"servo-toolkit: error: {scenes[-1]}", file=sys.stderr)
    with _executor(scheduler, scenes, args.scenes) as (executor, _):
        entries, errors, skipped, all_ok, out = _check_all(args, scenes, varies, executor, design_text)
    if args.junit is not None:
        write_junit(args.junit, entries)
    if args.json:
        sys.stdout.write(to_json({"passed": all_ok and not errors, "errors": errors, "skipped": skipped,
                                  "scenes": out}) + "\n")
    else:
        checked = len(entries) - errors - skipped
        if checked:
            print("some requirements NOT met" if not all_ok else "all requirements met" if not errors
                  else "every scene checked meets its requirements")
        if skipped:
            print(f"{skipped} of {len(args.scenes)} scene(s) skipped (no motor-driven loop to check)")
        if errors:
            print(f"{errors} of {len(args.scenes)} scene(s) could not be checked "
                  f"(bad input or a run outside its validity domain)")
    return 2 if errors else 0 if all_ok else 1
