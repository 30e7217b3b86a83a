"""Generate the scene-file reference from the loader itself.

Every shipped scene is loaded with :func:`servo_toolkit.core.fields.recording_reads`, which
collects each key the loader reads: its table, unit, default, rule and choices, and the
value a shipped scene writes for it. Descriptions come from the numpydoc ``Parameters`` of
the component each table builds. What the loader does not read cannot appear, and what it
reads cannot be missing.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from generated import page_generator
from scene_key_text import key_text

#: the generated page, inside the documentation's source folder; kept in the repository (a
#: test fails when it differs from what the loader reads) so that it is read without a build
PAGE = "reference/scene_keys.md"
#: reader names, most specific first (a number is read as a dimensionless quantity too)
_PRIORITY = ("number", "integer", "text", "quantity list", "quantity", "value", "optional")
_ORDER = ("motor", "drivetrain[]", "load", "sensors", "requirements", "robustness", "tolerances", "studies.*",
          "duty_cycle", "duty_cycle.segments[]", "duty_cycle.motors[]", "mechanism", "stages[]",
          "drivetrain[].stages[]", "operating", "display")


def scene_files(root: Path | None = None) -> list:
    """The scene files the reference is generated from: every ``scenes/*.toml`` and the
    examples in ``scenes/examples/``."""
    root = root or Path(__file__).resolve().parents[2]
    return sorted((root / "scenes").glob("*.toml")) + sorted((root / "scenes" / "examples").glob("*.toml"))


def collect(paths=None) -> list:
    """Every key the loader reads from ``paths`` (default: the shipped scenes)."""
    from servo_toolkit.core.fields import recording_reads
    from servo_toolkit.scene.loader import load_scene
    with recording_reads() as reads:
        for path in paths or scene_files():
            load_scene(path)
    return list(reads)


def _pattern(table: str) -> str:
    table = re.sub(r"\[\d+\]", "[]", table)
    return "studies.*" if table.startswith("studies.") else table


def grouped(reads) -> dict:
    """(table pattern, kind) -> {key: merged description dict}, in reading order."""
    groups: dict = {}
    for r in reads:
        if r.key == "kind" and r.table != "":
            pass
        group = groups.setdefault((_pattern(r.table), r.kind), {})
        d = group.setdefault(r.key, {"readers": set(), "unit": None, "rule": None, "choices": None,
                                     "default": None, "required": True, "written": None, "bounds": None})
        d["readers"].add(r.reader)
        d["unit"] = d["unit"] or (r.unit if r.reader != "number" else None)
        d["rule"] = d["rule"] or r.rule
        d["bounds"] = d["bounds"] or getattr(r, "bounds", None)
        d["choices"] = d["choices"] or r.choices
        if not r.required and r.default is not None:
            d["default"] = r.default if d["default"] is None else d["default"]
        if r.reader == "optional" or not r.required:
            d["required"] = False
        if d["written"] is None and r.written is not None:
            d["written"] = r.written
    return groups


def _component(pattern: str, kind):
    from servo_toolkit.scene import loader as sc
    from servo_toolkit.components.compliance import Load
    from servo_toolkit.components.motor import DCMotor
    from servo_toolkit.components.roller_screw.stages import RollerScrewOperating, RollerScrewStage
    from servo_toolkit.scene.duty_cycle import DutyCycle, Segment
    from servo_toolkit.display.units import DisplayUnits
    from servo_toolkit.scene.tolerances import Tolerances
    table = {"tolerances": Tolerances, "display": DisplayUnits, "duty_cycle": DutyCycle, "duty_cycle.segments[]": Segment, "duty_cycle.motors[]": DCMotor,
             "motor": DCMotor, "load": Load, "sensors": sc.Sensors, "requirements": sc.Requirements,
             "robustness": sc.Robustness, "stages[]": RollerScrewStage,
             "drivetrain[].stages[]": RollerScrewStage, "operating": RollerScrewOperating}
    if pattern == "drivetrain[]":
        return sc.STAGE_KINDS.get(kind)
    if pattern == "mechanism":
        return sc.MECHANISM_KINDS.get(kind)
    return table.get(pattern)


def descriptions(cls) -> dict:
    """name -> one-line description from the class's numpydoc Parameters/Attributes."""
    from numpydoc.docscrape import NumpyDocString
    if cls is None or not cls.__doc__:
        return {}
    doc = NumpyDocString(cls.__doc__)
    out = {}
    for section in ("Parameters", "Attributes"):
        for p in doc[section]:
            text = " ".join(" ".join(p.desc).split())
            for name in p.name.split(","):
                out.setdefault(name.strip(), text)
    return out


def _fmt(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float) and math.isinf(value):
        return "unlimited" if value > 0 else "-inf"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_fmt(v)}" for k, v in value.items()) + "}"
    return repr(value) if isinstance(value, str) else f"{value:g}" if isinstance(value, float) else str(value)


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _reader(d) -> str:
    reader = next(r for r in _PRIORITY if r in d["readers"])
    if reader in ("quantity", "quantity list") and d["unit"]:
        unit = "dimensionless" if d["unit"] == "dimensionless" else f"`{d['unit']}`"
        return f"{reader} in {unit}" if reader == "quantity" else f"list of {unit}"
    return {"value": "as written", "optional": "quantity"}.get(reader, reader)


def _title(pattern: str, kind) -> str:
    names = {"motor": "`[motor]`", "load": "`[load]`", "sensors": "`[sensors]`",
             "requirements": "`[requirements]`", "robustness": "`[robustness]`",
             "tolerances": "`[tolerances]` (settings; every other key is a scene key path with its distribution, "
                           "see the tolerances guide)",
             "operating": "`[operating]` (roller-screw scene)", "stages[]": "`[[stages]]` (roller-screw scene)",
             "drivetrain[].stages[]": "`stages` of a `roller_screw` stage", "duty_cycle": "`[duty_cycle]`",
             "duty_cycle.segments[]": "`[[duty_cycle.segments]]`", "display": "`[display]`",
             "duty_cycle.motors[]": "`[[duty_cycle.motors]]` (motor candidates: the keys of `[motor]`)"}
    if pattern == "drivetrain[]":
        return f"`[[drivetrain]]` kind = `{kind}`"
    if pattern == "studies.*":
        return (f"`[studies.NAME]` kind = `{kind}`" if kind else
                "`[studies.NAME]` inline tables (`frequencies = {start, stop, points, spacing}`, "
                "`external_moments = {x, y}`)")
    if pattern == "mechanism":
        return f"`[mechanism]` kind = `{kind}`"
    if pattern == "duty_cycle.segments[]":
        return f"`[[duty_cycle.segments]]` kind = `{kind}`"
    return names.get(pattern, f"`[{pattern}]`")


def scene_markdown(reads=None) -> str:
    """The scene-file reference as Markdown."""
    from servo_toolkit.scene import loader as sc
    groups = grouped(collect() if reads is None else reads)
    out = ["# Scene-file reference", "",
           "A scene is a TOML file. A quantity is a bare SI number or a string with units parsed "
           "by pint (`\"0.5 mH\"`, `\"1696.8 N*m/deg\"`, `\"6 dB\"`); it is converted to the unit "
           "in the *type* column. Generated from the loader: every key below is one the loader "
           "reads, with the default it applies and the rule it checks; any other key is an error "
           "naming it. Examples are values the shipped scenes (`scenes/`) write.", "",
           "## Top level", "", "| key | meaning |", "| --- | --- |"]
    top = {"name": "Scene name (a non-empty string; required).",
           "description": "Free text.",
           "motor": "The DC motor, `[motor]`.",
           "drivetrain": "Stages from the motor to the load, `[[drivetrain]]` in order.",
           "load": "The load at the output, `[load]`.",
           "sensors": "Encoders, sample time and speed estimator, `[sensors]`.",
           "requirements": "What the loop must achieve, `[requirements]`.",
           "studies": "Named studies, `[studies.NAME]` with a `kind`.",
           "mechanism": "A multi-axis mechanism instead of a drivetrain, `[mechanism]`.",
           "stages": "Stages of a stand-alone roller-screw scene, `[[stages]]`.",
           "operating": "Operating point of a stand-alone roller-screw scene, `[operating]`.",
           "robustness": "Parameter variations the loop must tolerate, `[robustness]`.",
           "tolerances": "How the built actuators differ: any numeric scene key with a distribution, the "
                         "sampling and the required yield, `[tolerances]`.",
           "duty_cycle": "The motion the actuator repeats in service, for `servo-toolkit size`, `[duty_cycle]`.",
           "display": "Units a reader is shown for a stiffness and an inertia at the output, `[display]` "
                      "(default SI; JSON stays SI)."}
    for key in sorted(sc._TOP_KEYS):
        out.append(f"| `{key}` | {_cell(top.get(key, ''))} |")
    out.append("")

    def order(item):
        (pattern, kind), _ = item
        return (_ORDER.index(pattern) if pattern in _ORDER else len(_ORDER), str(kind))

    for (pattern, kind), keys in sorted(groups.items(), key=order):
        desc = descriptions(_component(pattern, kind))
        if pattern == "drivetrain[]" and kind != "cam":  # every stage's output friction
            from servo_toolkit.components.stage_friction import StageFriction
            desc = {**descriptions(StageFriction), **desc}
        if pattern == "duty_cycle.segments[]":  # a segment kind takes its own keys; the loader refuses the others
            from servo_toolkit.scene.duty_cycle import _KEYS, REQUIRED_KEYS
            keys = {k: ({**d, "required": True} if k in REQUIRED_KEYS.get(kind, ()) else d)
                    for k, d in keys.items() if k not in _KEYS or kind in _KEYS[k][2]}
        out += [f"## {_title(pattern, kind)}", "",
                "| key | type | default | rule | example | meaning |", "| --- | --- | --- | --- | --- | --- |"]
        for key, d in keys.items():
            default = "required" if d["required"] else (_fmt(d["default"]) or "absent: not used")
            rule = d["rule"] or ""
            if d["bounds"] is not None:
                low, high = d["bounds"]
                span = f"|x| <= {high:g}" if rule == "finite" else f"{low:g} .. {high:g}"
                rule = f"{rule}, {span}" if rule else span
            if d["choices"]:
                rule = "one of " + ", ".join(f"`{c}`" for c in d["choices"])
            example = f"`{_fmt(d['written'])}`" if d["written"] is not None else ""
            out.append(f"| `{key}` | {_reader(d)} | {_cell(default)} | {_cell(rule)} | {_cell(example)} | "
                       f"{_cell(key_text(pattern, key, desc.get(key, '')))} |")
        out.append("")
        out += _NOTES.get(pattern, [])
    return "\n".join(out)


#: what a table holds besides its fixed keys, below that table's rows
_NOTES = {"tolerances": [
    "Every other key of `[tolerances]` is the path of a numeric scene key (`motor.resistance`, "
    "`\"drivetrain[3].stiffness\"`, `load.hinge_moment`, `sensors.output_encoder_bits`; the virtual key "
    "`drivetrain.stiffness_scale` is a factor on the drivetrain's series stiffness, nominal 1) with its "
    "distribution:", "",
    "| form | distribution |", "| --- | --- |",
    "| `\"lo:hi\"`, `[lo, hi]`, `{min = lo, max = hi}` | uniform over the range (each end a quantity in the "
    "key's unit, or `xF` a factor of the scene's value); log-uniform when positive and wider than a decade |",
    "| `\"+-5 %\"`, `\"+-0.1 ohm\"` | uniform about the scene's value |",
    "| `{sigma = \"2 %\"}`, `{sigma = \"0.02 ohm\", mean = ..., min = ..., max = ...}` | normal about `mean` "
    "(default the scene's value), truncated to `min`/`max` and to the key's physical range; without `min` "
    "(`max`) the physical range may cut at most 0.1 % of it (3.09 sigma), else give the end; a mean at `min` "
    "or `max` is a half-normal |", "",
    "Each range end, and a normal's truncation, must obey the key's rule in the tables above (its sign and "
    "the range its model is conditioned for); an unknown key, a list or text key, a requirement, a malformed "
    "distribution, a sigma that is not positive, a spread below 1e-9 of the value or a percentage of a value of "
    "0 is one line naming `tolerances.<key>` (exit 2), as is `sensors.sample_time` (the design's sample time, "
    "not a tolerance); `min_yield` is below 1 (no sample shows a yield of 1). "
    "Integer keys "
    "are rounded. `[robustness]`'s `load_inertia` and `stiffness` ranges are the tolerances `load.inertia` and "
    "`drivetrain.stiffness_scale`.", ""]}


def setup(app):
    """Sphinx extension entry point."""
    app.connect("config-inited", page_generator(PAGE, scene_markdown))
    return {"parallel_read_safe": True, "version": "1"}


if __name__ == "__main__":  # python docs/_ext/scene_reference.py: the page, written where it is kept
    from generated import write_if_changed
    write_if_changed(Path(__file__).resolve().parents[1] / PAGE, scene_markdown())
