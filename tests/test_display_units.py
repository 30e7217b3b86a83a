"""One unit per quantity: the scene's [display] preference, one number format per column,
and axis labels that read ``quantity [unit]``."""

from __future__ import annotations

import ast
import json
import math
import re
import subprocess
import sys

import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.core.units import UREG
from servo_toolkit.display.html import column
from servo_toolkit.display.units import DisplayUnits
from servo_toolkit.report import sections_drivetrain
from servo_toolkit.report.context import Context
from servo_toolkit.studies.stiffness import stiffness_study

from .conftest import ROOT, SCENES

EMA = SCENES / "ema_reference.toml"
LINEAR = SCENES / "linear_roller_screw_actuator.toml"
#: the housing of the reference EMA: 1696.8 N*m/deg in seed 001, at the output (ratio 1)
HOUSING_DEG = 1696.8
HOUSING_RAD = 97219.48  # 1696.8 * 180 / pi, written out


def _scene(tmp_path, display: str, base=EMA, extra=None):
    text = base.read_text()
    if extra:
        text = extra(text)
    path = tmp_path / "scene.toml"
    path.write_text(text + "\n[display]\n" + display + "\n")
    return path


def _stiffness_cells(table: str, name: str) -> list:
    line = next(line for line in table.splitlines() if line.startswith(name))
    return [c for c in line[28:].split() if not c.endswith("%") and not c.startswith("(")]


def test_the_constant_is_the_seed_value_in_rad():
    assert HOUSING_RAD == pytest.approx(HOUSING_DEG * 180 / math.pi, rel=1e-6)


def test_stiffness_table_default_is_si_and_the_preference_is_shown(tmp_path, capsys):
    assert main(["stiffness", str(EMA)]) == 0
    default = capsys.readouterr().out
    assert "stage [N*m/rad]" in default and "series total [N*m/rad]" in default and "N*m/deg" not in default
    assert [float(c) for c in _stiffness_cells(default, "housing")] == pytest.approx([HOUSING_RAD] * 4, rel=1e-5)

    path = _scene(tmp_path, 'stiffness = "N*m/deg"\ninertia = "kg*cm^2"')
    assert main(["stiffness", str(path)]) == 0
    shown = capsys.readouterr().out
    assert "stage [N*m/deg]" in shown and "reflected inertia [kg*cm^2]" in shown
    assert [float(c) for c in _stiffness_cells(shown, "housing")] == pytest.approx([HOUSING_DEG] * 4, rel=1e-5)
    # the inertia row in kg*cm^2 is 1e4 times the SI one
    si = [float(c) for c in _stiffness_cells(default, "reflected inertia")[1:]]
    cm = [float(c) for c in _stiffness_cells(shown, "reflected inertia")[1:]]
    assert cm == pytest.approx([1e4 * j for j in si], rel=1e-4)


def test_stiffness_table_has_one_number_format_per_block(capsys):
    """The gear train's 46e6 and the housing's 97e3 N*m/rad read alike: all in engineering
    notation, never '804520' beside '1.14698e+06'."""
    assert main(["stiffness", str(EMA)]) == 0
    out = capsys.readouterr().out
    cells = [c for name in ("spur gear train", "ball screw", "link rod and rocker arm", "housing", "series total")
             for c in _stiffness_cells(out, name) if c[0].isdigit()]
    assert len(cells) == 20
    assert all(re.fullmatch(r"\d{1,3}\.\d+e\d+", c) for c in cells), cells
    assert all(len(c.split("e")[0].replace(".", "")) == 5 for c in cells), cells  # 5 significant digits
    assert "e+0" not in out


def test_json_stays_si_and_names_the_display_units(tmp_path, capsys):
    assert main(["stiffness", str(EMA), "--json"]) == 0
    default = json.loads(capsys.readouterr().out)
    path = _scene(tmp_path, 'stiffness = "N*m/deg"')
    assert main(["stiffness", str(path), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["display_units"] == {"stiffness": "N*m/deg", "inertia": "kg*m^2"}
    assert default["display_units"] == {"stiffness": "N*m/rad", "inertia": "kg*m^2"}
    for key in ("total_Nm_per_rad", "total_Nm_per_deg", "reflected_inertia_kg_m2"):
        assert shown[key] == default[key]
    assert shown["stages"][3]["stiffness_Nm_per_rad"] == pytest.approx([HOUSING_RAD] * 4, rel=1e-5)


def _report_table(scene):
    body = sections_drivetrain.stiffness_chain(Context(scene)).html
    block = re.search(r'<table id="stiffness-table">(.*?)</table>', body, re.S).group(1)
    head = re.findall(r"<th>([^<]*)</th>", block)
    rows = {r[0]: r[1:] for r in (re.findall(r"<td>([^<]*)</td>", tr) for tr in re.findall(r"<tr>(.*?)</tr>", block))
            if r}
    return head, rows


def test_report_stiffness_table_in_the_scene_unit(tmp_path):
    head, rows = _report_table(load_scene(_scene(tmp_path, 'stiffness = "N*m/deg"')))
    assert head[1] == "-30 deg: k [N*m/deg]"
    assert [float(c) for c in rows["housing"][:4]] == pytest.approx([HOUSING_DEG] * 4, rel=1e-6)
    head, rows = _report_table(load_scene(EMA))
    assert head[1] == "-30 deg: k [N*m/rad]"
    assert [float(c) for c in rows["housing"][:4]] == pytest.approx([HOUSING_RAD] * 4, rel=1e-5)
    # one format for every stiffness cell of the table
    cells = [c for name, r in rows.items() for c in r[:4] if name != "series total" or c]
    assert all("e" in c for c in cells), cells


def test_report_inertia_table_in_the_scene_unit(tmp_path):
    def rows(scene):
        body = sections_drivetrain.ratio_and_inertia(Context(scene)).html
        return {r[0]: r[1:] for r in (re.findall(r"<td>([^<]*)</td>", tr) for tr in re.findall(r"<tr>(.*?)</tr>", body))
                if r}
    si = rows(load_scene(EMA))["inertia at the output J"]
    cm = rows(load_scene(_scene(tmp_path, 'inertia = "kg*cm^2"')))["inertia at the output J"]
    assert si[-1] == "kg*m^2" and cm[-1] == "kg*cm^2"
    assert float(cm[0]) == pytest.approx(1e4 * float(si[0]), rel=1e-3)


def test_linear_output_takes_a_force_per_length(tmp_path, capsys):
    """A gear mesh of 1000 N*m/rad reflected to the nut travel: k (2 pi / 20 mm)^2 N/m, shown in N/um."""
    def spring(text):
        return text.replace("ratio = 2.0", 'ratio = 2.0\ntorsional_stiffness = "1000 N*m/rad"')
    path = _scene(tmp_path, 'stiffness = "N/um"\ninertia = "g"', LINEAR, spring)
    assert main(["stiffness", str(path)]) == 0
    out = capsys.readouterr().out
    k = 1000 * (2 * math.pi / 0.020) ** 2
    assert "stage [N/um]" in out and "reflected mass [g]" in out
    assert float(_stiffness_cells(out, "series total")[0]) == pytest.approx(k * 1e-6, rel=1e-4)


@pytest.mark.parametrize("base, display, key, words", [
    (EMA, 'stiffness = "N/mm"', "display.stiffness", "torque per angle"),
    (EMA, 'stiffness = "N*m"', "display.stiffness", "torque per angle"),
    (EMA, 'stiffness = "furlong"', "display.stiffness", "torque per angle"),
    (EMA, 'stiffness = "N*m/dgree"', "display.stiffness", "unknown unit"),
    (EMA, 'inertia = "kg"', "display.inertia", "moment of inertia"),
    (EMA, 'angle = "rad"', "display.angle", "unknown key"),
    (LINEAR, 'stiffness = "N*m/deg"', "display.stiffness", "force per length"),
])
def test_a_unit_of_the_wrong_dimension_exits_2_with_one_line(tmp_path, capsys, base, display, key, words):
    path = _scene(tmp_path, display, base)
    assert main(["stiffness", str(path)]) == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1 and lines[0].startswith("servo-toolkit: error: ")
    assert f"{key}: " in lines[0] and words in lines[0], lines[0]
    assert "(got" in lines[0] or words == "unknown key", lines[0]


def test_a_bad_display_unit_is_one_line_from_the_command(tmp_path):
    path = _scene(tmp_path, 'stiffness = "N/mm"')
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", "stiffness", str(path)],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert "display.stiffness: expected a unit of stiffness at an output angle, a torque per angle" in proc.stderr


def test_display_units_convert():
    d = DisplayUnits(stiffness="kN*m/rad", inertia="kg*cm^2")
    assert d.show("stiffness", 2500.0) == pytest.approx(2.5)
    assert d.show("inertia", 1.0) == pytest.approx(1e4)
    assert DisplayUnits().show("stiffness", 2500.0) == 2500.0
    assert DisplayUnits().to_dict(linear=True) == {"stiffness": "N/m", "inertia": "kg"}


def test_column_uses_one_format():
    assert column([804520, 1.14698e6, 6368.35, 710.943], 5) == ["804.52e3", "1.1470e6", "6.3684e3", "710.94e0"]
    assert column([6368.35, 710.943, 1696.8, 136.9], 5) == ["6368.4", "710.94", "1696.8", "136.90"]
    assert column([97219.4, float("inf"), 0.0, float("nan")], 5) == ["97.219e3", "inf", "0", "n/a"]


def test_scene_card_and_design_text_use_the_preference(tmp_path):
    scene = load_scene(_scene(tmp_path, 'stiffness = "N*m/deg"\ninertia = "kg*cm^2"'))
    assert "kg*cm^2" in scene._repr_html_()
    assert "N*m/deg at its lowest" in repr(stiffness_study(scene))


def test_design_text_shows_the_preference_and_json_stays_si(tmp_path, capsys):
    path = _scene(tmp_path, 'stiffness = "N*m/deg"\ninertia = "kg*cm^2"')
    main(["design", str(path), "--json"])
    data = json.loads(capsys.readouterr().out)
    main(["design", str(path)])
    text = capsys.readouterr().out
    plant = data["plant"]
    assert data["display_units"] == {"stiffness": "N*m/deg", "inertia": "kg*cm^2"}
    m = re.search(r"J1 = (\S+), J2 = (\S+) kg\*cm\^2, K = (\S+) N\*m/deg", text)
    assert m, text
    assert float(m.group(1)) == pytest.approx(plant["motor_side_inertia_kg_m2"] * 1e4, rel=1e-3)
    assert float(m.group(3)) == pytest.approx(plant["stiffness_n_m_per_rad"] * math.pi / 180, rel=1e-3)


# -- axis labels ------------------------------------------------------------------------------

_LABEL_CALLS = {"set_xlabel", "set_ylabel", "set_zlabel"}
_LABEL_KEYWORDS = {"xlabel", "ylabel", "zlabel"}


def _text(node) -> str | None:
    """A label's literal text; an f-string's fields become ``{}``."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
    if isinstance(node, ast.IfExp):
        return " | ".join(t for t in (_text(node.body), _text(node.orelse)) if t)
    return None


def _labels():
    for path in sorted((ROOT / "servo_toolkit").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Call) or not isinstance(node.func, ast.Attribute):
                continue
            name = node.func.attr
            if name in _LABEL_CALLS:
                args = node.args[:1]
            elif name == "set":
                args = [k.value for k in node.keywords if k.arg in _LABEL_KEYWORDS]
            elif name == "colorbar":
                args = [k.value for k in node.keywords if k.arg == "label"]
            else:
                continue
            for arg in args:
                text = _text(arg)
                if text is not None:
                    yield f"{path.relative_to(ROOT)}:{node.lineno}", text


def _unit_in_parentheses(text: str) -> str | None:
    """The first ``(...)`` of ``text`` that holds a unit (or a unit field ``{}``)."""
    for inner in re.findall(r"\(([^()]*)\)", text):
        inner = inner.strip()
        if "{}" in inner:
            return inner
        try:
            unit = UREG.parse_units(inner.replace(" ", "*"))
        except Exception:  # noqa: BLE001 - not a unit: words in parentheses
            continue
        if inner and str(unit) != "dimensionless":
            return inner
    return None


def test_axis_labels_put_units_in_brackets():
    labels = list(_labels())
    assert len(labels) > 40  # the scan itself works
    wrong = [(where, text) for where, text in labels if _unit_in_parentheses(text)]
    assert not wrong, f"axis labels with a unit in parentheses (write 'quantity [unit]'): {wrong}"
    assert _unit_in_parentheses("gain (dB)") == "dB" and _unit_in_parentheses("time ({})") == "{}"
    assert _unit_in_parentheses("efficiency (eq 32)") is None


def test_kv_table_shows_the_load_inertia_in_the_scene_unit(tmp_path, capsys):
    assert main(["kv", str(EMA)]) == 0
    default = capsys.readouterr().out
    assert main(["kv", str(_scene(tmp_path, 'inertia = "kg*cm^2"'))]) == 0
    shown = capsys.readouterr().out
    assert "[kg*m^2]" in default and "[kg*cm^2]" in shown and "[kg*m^2]" not in shown

    def loads(text):
        return [float(line.split()[1]) for line in text.splitlines() if re.match(r"\s+\d+\s+\d", line)]
    assert loads(shown) and loads(shown) == pytest.approx([1e4 * j for j in loads(default)])


def test_robustness_and_monte_carlo_show_the_load_inertia_in_the_scene_unit():
    """Variants are SI (kg*m^2); the text and the plot show them in the scene's unit."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from servo_toolkit.loop.robustness import RobustnessResult
    from servo_toolkit.studies.montecarlo import MonteCarloResult
    import numpy as np
    values = {"load_inertia": np.array([0.0, 4.0]), "stiffness": np.array([0.7, 1.3])}
    cm = DisplayUnits(inertia="kg*cm^2")
    robust = RobustnessResult("x", values, {"stable": np.array([True, True]), "phase_margin_deg": np.array([50.0, 45.0])},
                              [], {}, display=cm)
    assert "load_inertia 0..40e3 kg*cm^2" in robust.table()
    ax = robust.plot(Figure().subplots())
    assert ax.get_xlabel() == "load inertia [kg*cm^2]" and max(ax.collections[0].get_offsets()[:, 0]) == 4e4
    mc = MonteCarloResult("x", values, np.array([1e-3, 2e-3]), np.array([1.0, 2.0]), np.array([False, False]),
                          np.array([False, False]), ("", ""), np.array([0.1, 0.1]), 0.1, 1e-4, 10, 1.0, display=cm)
    assert mc.ranges_text() == "load_inertia 0..40e3 kg*cm^2, stiffness 0.7..1.3 x nominal"
    assert mc.values["load_inertia"][1] == 4.0 and "load_inertia = 40e3 kg*cm^2, stiffness = 1.3 x nominal" in mc.table()
    axes = mc.plot(Figure().subplots(1, 2))
    assert axes[0].get_xlabel() == "load inertia [kg*cm^2]"
    si = MonteCarloResult("x", values, np.array([1e-3, 2e-3]), np.array([1.0, 2.0]), np.array([False, False]),
                          np.array([False, False]), ("", ""), np.array([0.1, 0.1]), 0.1, 1e-4, 10, 1.0)
    assert si.ranges_text() == "load_inertia 0..4 kg*m^2, stiffness 0.7..1.3 x nominal"
