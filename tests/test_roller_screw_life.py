"""Load ratings and L10 life of a planetary roller screw along a duty cycle."""

from __future__ import annotations

import copy
import tomllib

import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.scene.loader import load_scene, scene_from_dict
from servo_toolkit.studies.gate import sizing_rows
from servo_toolkit.studies.sizing import size

from .conftest import SCENES

LINEAR = tomllib.loads((SCENES / "linear_roller_screw_actuator.toml").read_text())
C, C0, C_BEARING, F = 60e3, 90e3, 80e3, 5e3


def rated(**ratings) -> dict:
    """The linear roller-screw actuator with load ratings and a duty cycle: out and back
    50 mm at 5 kN, then a rest without load."""
    data = copy.deepcopy(LINEAR)
    data["drivetrain"][1].update(ratings)
    data["duty_cycle"] = {"start": "0 mm", "required_life": "100 h", "segments": [
        {"kind": "ramp", "to": "50 mm", "duration": "1 s", "accel_time": "0.25 s", "load": "5 kN"},
        {"kind": "ramp", "to": "0 mm", "duration": "1 s", "accel_time": "0.25 s", "load": "5 kN"},
        {"kind": "dwell", "duration": "2 s", "load": "0 N"}]}
    return data


def test_existing_roller_screw_scene_loads_without_ratings():
    stage = load_scene(SCENES / "linear_roller_screw_actuator.toml").drivetrain.stages[1]
    assert stage.dynamic_load_rating is None and stage.static_load_rating is None
    assert stage.bearing_dynamic_load_rating is None and stage.bearing_kind == "ball"


def test_roller_screw_l10_is_the_standard_formula_on_the_cycle():
    scene = scene_from_dict(rated(dynamic_load_rating="60 kN", static_load_rating="90 kN",
                                  bearing_dynamic_load_rating="80 kN", bearing_kind="roller"), "rs.toml")
    res = size(scene, sweep=False)
    screw, bearing = res.lives
    # the thrust on the last nut is the load, but for its nut's inertia along the slow ramps
    assert screw.equivalent_load == pytest.approx(F, rel=1e-3)
    assert screw.revolutions == pytest.approx((C / screw.equivalent_load) ** 3 * 1e6, rel=1e-12)
    revs_per_hour = 2 * 0.05 / 0.020 * 3600 / 4.0      # 100 mm per cycle, 20 mm per screw turn, 4 s cycle
    assert screw.hours == pytest.approx(screw.revolutions / revs_per_hour, rel=1e-3)
    assert bearing.revolutions == pytest.approx((C_BEARING / bearing.equivalent_load) ** (10 / 3) * 1e6, rel=1e-12)
    static = next(m for m in res.margins if m.name.startswith("static load"))
    assert static.limit == C0 and static.value == pytest.approx(F, rel=1e-2)
    ids = [r.id for r in sizing_rows(res)]
    assert "static_load_two_stage_roller_screw" in ids and "life_two_stage_roller_screw_screw" in ids
    assert "life_two_stage_roller_screw_bearing" in ids


def test_static_rating_below_the_peak_thrust_is_exceeded():
    res = size(scene_from_dict(rated(static_load_rating="4 kN"), "rs.toml"), sweep=False)
    static = next(m for m in res.margins if m.name.startswith("static load"))
    assert not static.passed and res.lives == ()


@pytest.mark.parametrize("key, value", [("dynamic_load_rating", "-1 kN"), ("static_load_rating", "3 N*m"),
                                        ("bearing_dynamic_load_rating", 0), ("bearing_kind", "needle")])
def test_bad_rating_names_its_key(key, value):
    with pytest.raises(SceneError) as info:
        scene_from_dict(rated(**{key: value}), "rs.toml")
    assert info.value.key == f"drivetrain[1].{key}", str(info.value)
