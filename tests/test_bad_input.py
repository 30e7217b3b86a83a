"""Every bad input is one stderr line and exit 2, never a traceback or a silently wrong run:
a table of reproduced cases, and property-based mutations of the shipped scenes driven
through the command line."""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from servo_toolkit.cli import main

from .conftest import SCENE_FILES, SCENES

BASE = tomllib.loads((SCENES / "ema_reference.toml").read_text())


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + "}"
    return str(v)


def dumps(data: dict) -> str:
    """TOML text of a scene dict (tables one level deep, arrays of tables, inline the rest)."""
    out = [f"{json.dumps(k)} = {_value(v)}" for k, v in data.items()
           if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))]
    for k, v in data.items():
        if isinstance(v, dict):
            subtables = {a: b for a, b in v.items() if isinstance(b, dict) and k == "studies"}
            out.append(f"[{json.dumps(k)}]")
            out += [f"{json.dumps(a)} = {_value(b)}" for a, b in v.items() if a not in subtables]
            for a, b in subtables.items():
                out.append(f"[{json.dumps(k)}.{json.dumps(a)}]")
                out += [f"{json.dumps(c)} = {_value(e)}" for c, e in b.items()]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                out.append(f"[[{json.dumps(k)}]]")
                out += [f"{json.dumps(a)} = {_value(b)}" for a, b in x.items()]
    return "\n".join(out) + "\n"


def run(argv):
    """(exit code, stderr lines) of the command line, in process."""
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main(argv)
    return code, [ln for ln in err.getvalue().splitlines() if ln.strip()]


def edited(path, value, data=BASE):
    data = copy.deepcopy(data)
    target = data
    for p in path[:-1]:
        target = target[p]
    if value is DELETE:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return data


DELETE = object()
DT = BASE["drivetrain"]
CASES = [  # (name, scene dict, the key the message must name)
    ("teeth not a list", edited(["drivetrain", 0, "teeth"], 5), "drivetrain[0].teeth"),
    ("name not a string", edited(["name"], 5), "name"),
    ("torque constant absurd", edited(["motor", "torque_constant"], 1e300), "motor.torque_constant"),
    ("lead absurd", edited(["drivetrain", 1, "lead"], 1e300), "drivetrain"),
    ("lead tiny", edited(["drivetrain", 1, "lead"], 1e-300), "drivetrain"),
    ("encoder bits absurd", edited(["sensors", "output_encoder_bits"], 2000), "sensors.output_encoder_bits"),
    ("screw after screw", {**BASE, "drivetrain": [DT[0], DT[1], DT[1], *DT[2:]]}, "drivetrain[2].kind"),
    ("linkage on the motor", {**BASE, "drivetrain": [DT[2], *DT[3:]]}, "drivetrain[0].kind"),
    ("gear after a screw", {**BASE, "drivetrain": [DT[1], DT[0], *DT[2:]]}, "drivetrain[1].kind"),
    ("stroke infinite", edited(["drivetrain", 2, "stroke"], ["-inf deg", "inf deg"]), "drivetrain"),
    ("period zero", edited(["studies", "kv_stroke", "period"], "0 s"), "studies.kv_stroke.period"),
    ("frequency zero", edited(["studies", "sweep", "amplitude"], "0 deg"), "studies.sweep.amplitude"),
    ("frequency in kg", edited(["studies", "kv_8hz", "frequency"], "8 kg"), "studies.kv_8hz.frequency"),
    ("amplitude in mm on an angle", edited(["studies", "kv_8hz", "amplitudes"], ["2 mm"]), "studies.kv_8hz.amplitudes"),
    ("amplitude a boolean", edited(["studies", "sweep", "amplitude"], True), "studies.sweep.amplitude"),
    ("amplitude words", edited(["studies", "sweep", "amplitude"], "two degrees"), "studies.sweep.amplitude"),
    ("unknown study key", edited(["studies", "kv_8hz", "load_inertia"], "1 kg*m^2"), "studies.kv_8hz.load_inertia"),
    ("study method", {**BASE, "studies": {"run": {"kind": "simulate", "method": "euler"}}}, "studies.run.method"),
    ("study duration huge", {**BASE, "studies": {"run": {"kind": "simulate", "duration": "1e7 s"}}},
     "studies.run.duration"),
    ("study duration negative", {**BASE, "studies": {"run": {"kind": "simulate", "duration": "-1 s"}}},
     "studies.run.duration"),
    ("study voltage words", {**BASE, "studies": {"run": {"kind": "simulate", "voltage": "lots"}}},
     "studies.run.voltage"),
    ("study sample time negative", {**BASE, "studies": {"run": {"kind": "simulate", "sample_time": "-1 ms"}}},
     "studies.run.sample_time"),
]


@pytest.mark.parametrize("name, data, key", CASES, ids=[c[0] for c in CASES])
def test_reproduced_bad_scenes_are_one_line_and_exit_2(name, data, key, tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(dumps(data))
    code, lines = run(["stiffness", str(path)])
    assert code == 2, lines
    assert len(lines) == 1 and key in lines[0] and "Traceback" not in lines[0], lines


@pytest.mark.parametrize("text, rule", [(b"name = 'x'\n\xff\xfe\n", "UTF-8"),
                                        (("a = " + "[" * 50_000 + "]" * 50_000 + "\n").encode(), "nested"),
                                        (("name = 'x'\nn = " + "9" * 5000 + "\n").encode(), "TOML")])
def test_unreadable_files_are_one_line(text, rule, tmp_path):
    path = tmp_path / "scene.toml"
    path.write_bytes(text)
    code, lines = run(["stiffness", str(path)])
    assert code == 2 and len(lines) == 1 and rule in lines[0]


def test_a_device_is_not_read():
    code, lines = run(["stiffness", "/dev/zero"])
    assert code == 2 and len(lines) == 1 and "regular file" in lines[0]


EMA = str(SCENES / "ema_reference.toml")
OPTIONS = [["simulate", EMA, "--dt", "0"], ["simulate", EMA, "--dt", "nan"], ["simulate", EMA, "--dt", "10"],
           ["simulate", EMA, "--dt", "inf"], ["sweep", EMA, "--workers", "0"],
           ["report", "--section-time-limit", "-5"], ["check", EMA, "--samples", "100000000"]]


@pytest.mark.parametrize("argv", OPTIONS, ids=[" ".join(a[:1] + a[2:]) for a in OPTIONS])
def test_bad_option_values_are_one_line_and_exit_2(argv):
    with pytest.raises(SystemExit) as stop:
        run(argv)  # argparse stops with the exit code
    assert stop.value.code == 2


@pytest.mark.parametrize("command", ["sweep", "simulate", "montecarlo"])
def test_an_amplitude_is_read_in_the_output_unit_before_any_work(command):
    """An amplitude needs the scene (deg for an angle, mm for a travel): read right after it."""
    code, lines = run([command, EMA, "--amplitude", "1000"])
    assert code == 2 and len(lines) == 1 and "--amplitude" in lines[0] and "at most 180 deg" in lines[0]


def test_output_paths_are_checked_before_any_work(tmp_path):
    code, lines = run(["sweep", EMA, "--plot", str(tmp_path / "x.xyz")])
    assert code == 2 and len(lines) == 1 and "--plot" in lines[0]
    (tmp_path / "dir.csv").mkdir()
    code, lines = run(["simulate", EMA, "-o", str(tmp_path / "dir.csv")])
    assert code == 2 and "--output" in lines[-1]
    keep = tmp_path / "notes"
    keep.mkdir()
    (keep / "mine.txt").write_text("mine")
    code, lines = run(["report", "-o", str(keep)])
    assert code == 2 and len(lines) == 1 and (keep / "mine.txt").read_text() == "mine"
    code, lines = run(["report", "-o", str(tmp_path / "no" / "such" / "dir")])
    assert code == 2 and len(lines) == 1


def test_stiffness_defaults_lie_in_a_short_stroke(tmp_path):
    path = tmp_path / "short.toml"
    short = edited(["drivetrain", 2, "stroke"], ["-20 deg", "20 deg"])  # the kv sine follows the stroke
    path.write_text(dumps(edited(["studies", "kv_stroke", "amplitude"], "20 deg", short)))
    code, lines = run(["stiffness", str(path)])
    assert code == 0, lines


# --- property-based: mutated scenes through the command line --------------------------------

def _leaves(data, prefix=()):
    if isinstance(data, dict):
        for k, v in data.items():
            yield from _leaves(v, prefix + (k,))
    elif isinstance(data, list) and data and all(isinstance(x, dict) for x in data):
        for i, v in enumerate(data):
            yield from _leaves(v, prefix + (i,))
    else:
        yield prefix


SHIPPED = {p.name: tomllib.loads(p.read_text()) for p in SCENE_FILES}
JUNK = st.sampled_from([True, 0, -1, 1e300, 1e-300, float("nan"), float("inf"), "lots", "8 kg", "2 mm", "-3 deg",
                        [], {}, ["1 s", "x"], {"a": 1}, "0 s", 5, "", DELETE])


@st.composite
def mutated(draw):
    name = draw(st.sampled_from(sorted(SHIPPED)))
    data = copy.deepcopy(SHIPPED[name])
    for _ in range(draw(st.integers(1, 2))):
        kind = draw(st.sampled_from(["value", "value", "extra", "stages"]))
        leaves = list(_leaves(data))
        if kind == "value" and leaves:
            data = edited(list(draw(st.sampled_from(leaves))), draw(JUNK), data)
        elif kind == "extra":
            table = draw(st.sampled_from([k for k, v in data.items() if isinstance(v, dict)] or ["motor"]))
            data.setdefault(table, {})["typo_key"] = 1
        elif isinstance(data.get("drivetrain"), list) and len(data["drivetrain"]) > 1:
            stages = data["drivetrain"]
            i, j = draw(st.integers(0, len(stages) - 1)), draw(st.integers(0, len(stages) - 1))
            stages[i], stages[j] = stages[j], stages[i]
    return name, data


def _one_line_or_success(code, lines, ok=(0,)):
    assert code in (*ok, 2), (code, lines)
    assert not any("Traceback" in ln for ln in lines), lines
    if code == 2:
        assert len([ln for ln in lines if ln.startswith("servo-toolkit: ")]) == 1, lines


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(mutated())
def test_mutated_scenes_load_or_say_why(tmp_path_factory, case):
    _, data = case
    path = tmp_path_factory.mktemp("m") / "scene.toml"
    path.write_text(dumps(data))
    code, lines = run(["stiffness", str(path)])
    _one_line_or_success(code, lines)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(mutated())
def test_mutated_scenes_design_check_and_simulate_or_say_why(tmp_path_factory, case):
    _, data = case
    path = tmp_path_factory.mktemp("m") / "scene.toml"
    path.write_text(dumps(data))
    code, lines = run(["stiffness", str(path)])
    _one_line_or_success(code, lines)
    if code == 2:
        return
    code, lines = run(["check", str(path), "--linear-only"])
    _one_line_or_success(code, lines, ok=(0, 1))
    code, lines = run(["simulate", str(path), "--method", "rk4"])
    _one_line_or_success(code, lines)
