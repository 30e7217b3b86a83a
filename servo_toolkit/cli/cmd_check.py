"""``servo-toolkit check``: gate one or more scenes on their loop requirements.

Exit 0 when every requirement holds for every scene, 1 when some do not (a table says which
and by how much), 2 on bad input. A scene's ``[robustness]`` (or ``--vary``) adds its
robustness requirements, checked on the worst variant: ``robust_stable_fraction``,
``robust_gain_margin``, ``robust_phase_margin``, ``robust_sensitivity_peak`` (and
``robust_bandwidth`` when the table sets ``min_bandwidth``). A scene with ``[robustness]`` is
designed robustly (``--nominal`` checks the nominal design over the same variants).
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET

from ..loop.result import requirements_table
from ..scene import load_scene
from .cmd_design import add_design_options, design_from_args
from .common import add_json, to_json


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("check", help="check loop requirements (exit 0 met, 1 not met, 2 bad input)")
    p.add_argument("scenes", nargs="+", metavar="SCENE", help="scene TOML files")
    add_design_options(p)
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LO:HI",
                   help="robustness: vary load_inertia (kg*m^2) or stiffness (factor), e.g. "
                        "load_inertia=0:4 stiffness=0.7:1.3 (repeatable; replaces that range of the "
                        "scene's [robustness])")
    p.add_argument("--samples", type=int, default=None,
                   help="variants of the robustness study (default: the scene's [robustness] samples, else 1000)")
    p.add_argument("--junit", metavar="FILE", help="write JUnit XML: one testcase per scene and requirement")
    add_json(p)
    p.set_defaults(run=run)


def _cases(name, result, robust):
    """(test name, passed, message) per requirement, the stability flag, and per robustness
    requirement (worst variant named)."""
    cases = [(c.name, c.passed, f"required {c.sense} {c.required:g} {c.unit}, achieved {c.achieved:.4g} {c.unit}"
              + ("" if c.passed else f", short by {c.shortfall:.3g} {c.unit}")) for c in result.requirements]
    stable = result.margins.closed_loop_stable
    cases.append(("closed_loop_stable", stable, "closed loop stable" if stable else "closed loop UNSTABLE"))
    if robust is not None:
        for c in robust.requirements:
            at = ", ".join(f"{k}={v:.4g}" for k, v in robust.worst.get(c.name, {}).items())
            cases.append((f"robust_{c.name}", c.passed,
                           f"worst case over {robust.count} variants ({robust.unstable_count} unstable): required "
                           f"{c.sense} {c.required:g} {c.unit}, achieved {c.achieved:.4g} {c.unit}"
                           + ("" if c.passed else f", short by {c.shortfall:.3g} {c.unit}") + f"; at {at}"))
    return cases


def robustness_spec(scene, varies: dict, samples):
    """The scene's ``[robustness]`` with the command line's ranges and sample count, or None
    when neither asks for a robustness study."""
    from dataclasses import replace

    from ..errors import SceneError
    from ..scene import Robustness
    base = scene.robustness
    if base is None and not varies:
        return None
    spec = base if base is not None else Robustness(load_inertia=None, stiffness=None)
    spec = replace(spec, **varies)
    if samples is not None:
        if samples < 1:
            raise SceneError("samples", f"must be at least 1 (got {samples})")
        spec = replace(spec, samples=samples)
    return spec


def write_junit(path, entries) -> None:
    """JUnit XML: a testsuite per scene, a testcase per requirement."""
    root = ET.Element("testsuites", name="servo-toolkit check")
    for name, cases in entries:
        suite = ET.SubElement(root, "testsuite", name=name, tests=str(len(cases)),
                              failures=str(sum(not ok for _, ok, _ in cases)))
        for test, ok, message in cases:
            case = ET.SubElement(suite, "testcase", classname=name, name=test)
            if ok:
                ET.SubElement(case, "system-out").text = message
            else:
                ET.SubElement(case, "failure", message=message, type="RequirementNotMet").text = message
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)


def run(args) -> int:
    """Run the command."""
    from ..loop.robustness import parse_vary, robustness
    varies = dict(parse_vary(text) for text in args.vary)
    scenes = [load_scene(path) for path in args.scenes]  # bad input -> exit 2 before any design
    specs = [robustness_spec(scene, varies, args.samples) for scene in scenes]
    entries, out, all_ok = [], [], True
    for path, scene, spec in zip(args.scenes, scenes, specs):
        result = design_from_args(scene, args, spec)
        robust = result.robustness
        if robust is None and spec is not None:
            robust = robustness(scene, result, spec=spec, progress=False)
        cases = _cases(scene.name, result, robust)
        ok = all(c[1] for c in cases)
        all_ok &= ok
        entries.append((scene.name, cases))
        d = result.to_dict()
        d["source"] = str(path)
        d["passed"] = ok
        if robust is not None:
            d["robustness"] = robust.to_dict()
        out.append(d)
        if not args.json:
            print(f"{scene.name} ({path}): {'PASS' if ok else 'FAIL'}")
            print(requirements_table(result.requirements))
            stable = result.margins.closed_loop_stable
            print(f"  {'closed_loop_stable':<24}{'yes':>14}{'yes' if stable else 'NO':>12}  "
                  f"{'ok' if stable else 'FAIL'}")
            if robust is not None:
                print(robust.table())
            for n in result.notes:
                print(f"  note: {n}")
    if args.junit:
        write_junit(args.junit, entries)
    if args.json:
        sys.stdout.write(to_json({"passed": all_ok, "scenes": out}) + "\n")
    else:
        print("all requirements met" if all_ok else "some requirements NOT met")
    return 0 if all_ok else 1
