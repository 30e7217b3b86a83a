"""A study kind from an installed package: registered by its entry point alone, it runs from
a scene, from the command line and in the report, and its table's keys are checked when the
scene loads, without editing any module of the toolkit.

The fixture kind, ``energy``, is the kinetic energy of the load at the peak speed of a sine,
E = J (2 pi f A)^2 / 2, a closed form the test checks.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap

import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.scene.study_kind import study_kinds

from .conftest import ROOT

PLUGIN = '''
"""A study kind of another package: the load's kinetic energy at the peak speed of a sine."""

import math
from dataclasses import dataclass

from servo_toolkit.scene.study_kind import StudyKind
from servo_toolkit.scene.study_schema import SINE_KEYS

ENERGY = StudyKind(name="energy", summary="kinetic energy of the load at the peak speed of a sine",
                   schema=dict(SINE_KEYS), run="{module}:run", result="{module}:EnergyResult")


@dataclass(frozen=True)
class EnergyResult:
    study: str
    load_inertia: float
    peak_speed: float

    @property
    def energy(self):
        return 0.5 * self.load_inertia * self.peak_speed ** 2

    def to_dict(self):
        return {{"study": self.study, "load_inertia_kg_m2": self.load_inertia,
                "peak_speed_rad_s": self.peak_speed, "energy_J": self.energy}}

    def plot(self, ax=None):
        if ax is None:
            from matplotlib.figure import Figure
            ax = Figure().subplots()
        speeds = [self.peak_speed * k / 20 for k in range(21)]
        ax.plot(speeds, [0.5 * self.load_inertia * w ** 2 for w in speeds], label="E = J w^2 / 2")
        ax.set_xlabel("speed [rad/s]")
        ax.set_ylabel("energy [J]")
        return ax

    def __repr__(self):
        return f"<EnergyResult {{self.study}}: {{self.energy:.4g}} J>"

    def _repr_html_(self):
        return f"<p>{{self.study}}: {{self.energy:.4g}} J</p>"


def run(scene, study, **options):
    frequency = study.get("frequency") or 1.0 / study.get("period")
    peak_speed = 2 * math.pi * frequency * study.get("amplitude")
    return EnergyResult(study.name, scene.load.inertia, peak_speed)
'''

STUDY = '''
[studies.spin]
kind = "energy"
amplitude = "2 deg"
frequency = "8 Hz"
'''


def _install(folder, module: str = "energy_study", kind: str = "energy", attr: str = "ENERGY"):
    """Write the plugin module and its ``*.dist-info`` (METADATA, entry_points.txt) into ``folder``."""
    (folder / f"{module}.py").write_text(PLUGIN.format(module=module), encoding="utf-8")
    info = folder / f"{module.replace('_', '-')}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module.replace('_', '-')}\nVersion: 0.1\n",
                                   encoding="utf-8")
    (info / "entry_points.txt").write_text(f"[servo_toolkit.studies]\n{kind} = {module}:{attr}\n", encoding="utf-8")


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """The plugin on the import path, and a scene (the reference EMA) with an ``energy`` study."""
    _install(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    scene_file = tmp_path / "scene.toml"
    scene_file.write_text((ROOT / "servo_toolkit" / "data" / "ema_reference.toml").read_text(encoding="utf-8") + STUDY,
                          encoding="utf-8")
    return scene_file


def _expected(scene) -> float:
    return 0.5 * scene.load.inertia * (2 * math.pi * 8.0 * math.radians(2.0)) ** 2


def test_the_entry_point_registers_the_kind(plugin):
    kind = study_kinds()["energy"]
    assert kind.origin.startswith("the entry point 'energy'") and kind.command == "study" and kind.section is None


def test_the_registry_follows_the_import_path(tmp_path, monkeypatch):
    assert "energy" not in study_kinds()
    _install(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert "energy" in study_kinds()


def test_it_runs_from_a_scene(plugin):
    import servo_toolkit as st
    scene = st.load_scene(plugin)
    result = st.run_study(scene, "spin")
    assert result.to_dict()["energy_J"] == pytest.approx(_expected(scene), rel=1e-12)
    assert result.to_dict()["energy_J"] > 0 and "J" in repr(result)


def test_a_typo_in_its_table_is_one_line_naming_the_key(plugin):
    import servo_toolkit as st
    plugin.write_text(plugin.read_text(encoding="utf-8").replace('"energy"\namplitude =', '"energy"\namplitud ='),
                      encoding="utf-8")
    with pytest.raises(SceneError) as err:
        st.load_scene(plugin)
    assert f"{plugin}: studies.spin.amplitud: unknown key" in str(err.value) and "\n" not in str(err.value)


def test_a_wrong_unit_in_its_table_names_the_key(plugin):
    import servo_toolkit as st
    plugin.write_text(plugin.read_text(encoding="utf-8").replace('deg"\nfrequency = "8 Hz"', 'deg"\nfrequency = "8 m"'),
                      encoding="utf-8")
    with pytest.raises(SceneError, match=r": studies\.spin\.frequency: "):
        st.load_scene(plugin)


def test_it_runs_from_the_command_line(plugin, tmp_path):
    import servo_toolkit as st
    out = tmp_path / "spin.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", "study", str(plugin), "spin", "--json", str(out)],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("Study spin (energy) of ema_reference")
    row = next(line.split() for line in proc.stdout.splitlines() if line.startswith("energy_J"))
    expected = _expected(st.load_scene(plugin))
    assert float(row[1]) == pytest.approx(expected, rel=1e-5) and row[2] == "J"
    assert json.loads(out.read_text(encoding="utf-8"))["energy_J"] == pytest.approx(expected, rel=1e-12)
    bad = subprocess.run([sys.executable, "-m", "servo_toolkit", "study", str(plugin), "spun"],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "studies.spun" in bad.stderr


def test_it_appears_in_the_report(plugin):
    import servo_toolkit as st
    from servo_toolkit.report.builder import KIND_SECTIONS_BEFORE, Report, run_section, sections_of
    from servo_toolkit.report.context import Context
    from servo_toolkit.report.html_writer import render_html
    scene = st.load_scene(plugin)
    keys = [key for key, _, _ in sections_of(None, scene)]
    assert keys.index("energy") == keys.index(KIND_SECTIONS_BEFORE) - 1
    assert "energy" not in [key for key, _, _ in sections_of(None, st.load_scene())]  # only with such studies
    key, title, builder = next(s for s in sections_of(None, scene) if s[0] == "energy")
    section = run_section(key, title, builder, Context(scene))
    assert section.status == "info", section.reason
    assert len(section.figures) == 1 and not section.layout
    assert "energy_J" in section.html and "<td>J</td>" in section.html.replace(" ", "")
    html = render_html(Report(scene.name, "", (section,), ()))
    assert "Studies of kind energy" in html and f"{_expected(scene):.6g}" in html
    section.figures[0].figure.clear()


def test_two_kinds_of_one_name_are_a_clear_error(tmp_path, monkeypatch):
    _install(tmp_path, module="other_kv", kind="kv")
    (tmp_path / "other_kv.py").write_text(textwrap.dedent(PLUGIN.format(module="other_kv")).replace(
        'name="energy"', 'name="kv"'), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ValueError, match=r"study kind 'kv' is registered twice: by servo_toolkit\.studies\.kv\.kind"):
        study_kinds()
