"""The stiffness command and the CLI error contract."""

import json
import math
import subprocess
import sys
import tomllib

import numpy as np
import pytest

from servo_toolkit.cli import main

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
LINEAR = str(SCENES / "linear_roller_screw_actuator.toml")


def strict_json(text):
    """Parse JSON that must not contain NaN or Infinity (nor strings standing for them)."""
    def refuse(token):
        raise ValueError(f"non-standard JSON constant {token}")
    data = json.loads(text, parse_constant=refuse)
    assert '"inf"' not in text and '"nan"' not in text.lower()
    return data


def test_stiffness_json(capsys):
    assert main(["stiffness", EMA, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["angles_deg"] == [-30, 0, 10, 30]
    assert {"angles_deg", "stages", "total_Nm_per_rad", "total_Nm_per_deg", "ratio",
            "reflected_inertia_kg_m2"} <= set(data)
    names = [s["name"] for s in data["stages"]]
    assert names == ["spur gear train", "ball screw", "link rod and rocker arm", "housing"]
    for i in range(4):
        assert sum(s["share"][i] for s in data["stages"]) == pytest.approx(1)
        assert data["total_Nm_per_deg"][i] == pytest.approx(data["total_Nm_per_rad"][i] * 3.141592653589793 / 180)
        # per stage: stiffness at the output; compliances add up to the series total
        assert all({"name", "stiffness_Nm_per_rad", "share"} <= set(s) for s in data["stages"])
        compliance = sum(1 / s["stiffness_Nm_per_rad"][i] for s in data["stages"])
        assert 1 / compliance == pytest.approx(data["total_Nm_per_rad"][i], rel=1e-12)
        for s in data["stages"]:
            assert s["share"][i] == pytest.approx(data["total_Nm_per_rad"][i] / s["stiffness_Nm_per_rad"][i])
    # housing: 1696.8 N*m/deg at every angle (seed 001)
    assert data["stages"][3]["stiffness_Nm_per_rad"] == pytest.approx([1696.8 * 180 / math.pi] * 4)
    # seed 001's criterion: the gear train may be neglected, the later stages may not
    assert data["output_unit"] == "rad" and data["rigid"] is False
    assert [s["seed_negligible"] for s in data["stages"]] == [True, False, False, False]
    assert [s["later_ratio_large"] for s in data["stages"]] == [True, False, False, False]
    gear = data["stages"][0]
    assert gear["native_stiffness"] == 1.6e4 and gear["native_unit"] == "N*m/rad"
    # own ratio of the gear mesh (screw shaft rad per output rad) squared times its stiffness
    assert gear["stiffness_Nm_per_rad"] == pytest.approx(
        [1.6e4 * n**2 for n in gear["native_ratio_to_output"]], rel=1e-12)
    assert gear["ratio_to_output"] == gear["native_ratio_to_output"]
    assert gear["stiffness_comparable"] and gear["stiffness_to_later"] > 0.1
    assert data["stages"][3]["stiffness_to_later"] is None and data["stages"][3]["later_ratio"] == [None] * 4


def test_stiffness_table_with_angles(capsys):
    assert main(["stiffness", EMA, "--angle", "5", "--angle", "-5"]) == 0
    out = capsys.readouterr().out
    assert "+5.0 deg" in out and "-5.0 deg" in out and "series total" in out
    assert "seed 001 neglect criterion" in out
    # SI by default, as `design` and the JSON: N*m/rad (a scene's [display] may choose N*m/deg)
    assert "stage [N*m/rad]" in out and "series total [N*m/rad]" in out and "N*m/deg" not in out
    rows = {line.split("  ")[0]: line for line in out.splitlines()[-7:]}
    assert rows["spur gear train"].rstrip().endswith("YES (ratio yes, K yes)")
    assert rows["ball screw"].rstrip().endswith("no (ratio no, K yes)")


def test_bad_scene_exits_2_with_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENES / "ema_reference.toml").read_text().replace('lead = "5 mm"', 'lead = "0 mm"'))
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", "stiffness", str(bad)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "drivetrain[1].lead" in lines[0] and "must be positive" in lines[0]


@pytest.mark.parametrize("value", ["200", "-31", "nan", "inf", "-inf"])
def test_angle_outside_stroke_or_not_finite_exits_2(capsys, value):
    assert main(["stiffness", EMA, "--angle", "10", f"--angle={value}"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "angle:" in lines[0]
    assert ("stroke [-30, 30] deg" if value in ("200", "-31") else "finite") in lines[0]


def test_stroke_ends_accepted(capsys):
    assert main(["stiffness", EMA, "--angle", "-30", "--angle", "30", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["angles_deg"] == [-30, 30]


def test_rigid_chain_json_has_null_totals(capsys):
    """The cam chain declares no stiffness: JSON has no infinity, so the totals are null."""
    assert main(["stiffness", str(SCENES / "cam_follower.toml"), "--json"]) == 0
    data = strict_json(capsys.readouterr().out)
    assert data["rigid"] is True and data["stages"] == []
    assert data["total_Nm_per_rad"] == [None] * 4 and data["total_Nm_per_deg"] == [None] * 4
    # a cam law is periodic: any finite cam angle is accepted
    assert main(["stiffness", str(SCENES / "cam_follower.toml"), "--angle", "400"]) == 0
    assert "rigid" in capsys.readouterr().out


def test_linear_output_table_units(capsys):
    assert main(["stiffness", LINEAR]) == 0
    out = capsys.readouterr().out
    assert "ratio N [rad/m]" in out and "reflected mass [kg]" in out and "+0.00 mm" in out
    assert "series total [N/m]" in out
    assert "rad/rad" not in out and "kg*m^2" not in out and "N*m" not in out


def test_linear_output_json_with_a_gear_mesh_spring(tmp_path, capsys):
    """A gear mesh (N*m/rad at the screw shaft) reflected to the nut travel: k (2 pi / sum L)^2 N/m."""
    text = open(LINEAR).read().replace('ratio = 2.0', 'ratio = 2.0\ntorsional_stiffness = "1000 N*m/rad"')
    scene = tmp_path / "lin.toml"
    scene.write_text(text)
    assert main(["stiffness", str(scene), "--position", "5", "--position", "-12.5", "--json"]) == 0
    data = strict_json(capsys.readouterr().out)
    k = 1000 * (2 * math.pi / 0.020) ** 2
    assert data["output_unit"] == "m" and data["positions_mm"] == [5, -12.5]
    assert data["angles_deg"] == [None, None] and data["total_Nm_per_deg"] == [None, None]
    assert data["total_N_per_m"] == pytest.approx([k, k]) and data["total_Nm_per_rad"] == data["total_N_per_m"]
    assert data["total_N_per_mm"] == pytest.approx([k / 1e3] * 2)
    assert data["stages"][0]["stiffness_N_per_m"] == pytest.approx([k, k])
    assert data["ratio_rad_per_m"] == pytest.approx([2 * 2 * math.pi / 0.020] * 2)
    assert data["reflected_mass_kg"] == data["reflected_inertia_kg_m2"]
    assert data["stages"][0]["native_unit"] == "N*m/rad"


@pytest.mark.parametrize("scene, args, key", [
    (LINEAR, ["--angle", "5"], "angle"),
    (LINEAR, ["--position", "nan"], "position"),
    (LINEAR, ["--position", "1e5"], "position"),
    (EMA, ["--position", "5"], "position"),
])
def test_wrong_coordinate_kind_exits_2(capsys, scene, args, key):
    assert main(["stiffness", scene, *args]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and f"{key}:" in lines[0]


PLATFORM = SCENES / "deflection_platform.toml"
#: (scene, text to replace, replacement, key path, rule) -- one per SceneError rule
BAD = [
    (EMA, 'nut_mass = "0.60 kg"', 'nut_mass = "-0.60 kg"', "drivetrain[1].nut_mass", "must not be negative"),
    (EMA, 'lead = "5 mm"', 'lead = "0 mm"', "drivetrain[1].lead", "must be positive"),
    (EMA, 'rod_length = "120 mm"', 'rod_length = "5 mm"', "drivetrain[2].rod_length", "rod too short"),
    (EMA, 'resistance = "0.5 ohm"', 'resistance = "nan ohm"', "motor.resistance", "NaN"),
    (EMA, 'resistance = "0.5 ohm"', 'resistance = nan', "motor.resistance", "NaN"),
    (EMA, 'resistance = "0.5 ohm"\n', '', "motor.resistance", "missing key"),
    (EMA, 'resistance = "0.5 ohm"', 'resistance = "0.5 ohmz"', "motor.resistance", "unknown unit"),
    (EMA, 'lead = "5 mm"', 'lead = "5 kg"', "drivetrain[1].lead", "dimension mismatch"),
    (PLATFORM, '"0 kg*mm^2"', '"-46826.13 kg*mm^2"', "mechanism.platform_inertia", "not positive definite"),
]


@pytest.mark.parametrize("scene, old, new, key, rule", BAD, ids=[b[4] for b in BAD])
def test_every_error_rule_exits_2_with_one_line(tmp_path, capsys, scene, old, new, key, rule):
    text = open(scene).read()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new))
    assert main(["stiffness", str(bad)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, lines
    assert f"{key}:" in lines[0] and rule in lines[0]
    assert tomllib.loads(bad.read_text())  # still valid TOML: the rule, not the syntax, failed


THREE_STAGES = """
name = "three_stages"
[motor]
kind = "dc"
resistance = "0.5 ohm"
torque_constant = "0.2 N*m/A"
back_emf_constant = "0.2 V*s/rad"
rotor_inertia = "2.0e-4 kg*m^2"
voltage_limit = "270 V"
current_limit = "60 A"
[[drivetrain]]
kind = "gear"
name = "g1"
ratio = 3.0
torsional_stiffness = "1000 N*m/rad"
[[drivetrain]]
kind = "gear"
name = "g2"
ratio = 2.0
torsional_stiffness = "5000 N*m/rad"
[[drivetrain]]
kind = "ball_screw"
name = "screw"
lead = "5 mm"
axial_stiffness = "2.0e8 N/m"
[load]
inertia = "10 kg"
"""


def test_three_stage_series_stiffness_by_hand(tmp_path, capsys):
    """1/K = sum (1/k_i) / n_i^2 at the nut: g1's shaft turns 2 * 2 pi / lead per metre, g2's
    2 pi / lead, the nut 1: 6.3165e9, 7.8957e9 and 2e8 N/m, total 1.8922e8 N/m; each share
    K / K_i."""
    path = tmp_path / "three.toml"
    path.write_text(THREE_STAGES)
    assert main(["stiffness", str(path), "--json"]) == 0
    data = strict_json(capsys.readouterr().out)
    n_s = 2 * math.pi / 5e-3
    k = [1000 * (2 * n_s) ** 2, 5000 * n_s**2, 2e8]
    total = 1 / sum(1 / ki for ki in k)
    assert [st["stiffness_N_per_m"][0] for st in data["stages"]] == pytest.approx(k, rel=1e-12)
    assert [st["share"][0] for st in data["stages"]] == pytest.approx([total / ki for ki in k], rel=1e-12)
    assert data["total_N_per_m"][0] == pytest.approx(total, rel=1e-12)
    assert data["ratio_rad_per_m"][0] == pytest.approx(6 * n_s, rel=1e-12)


def test_seed001_criterion_keeps_the_gear_ratio_between_two_meshes_of_a_linear_chain(tmp_path):
    """Two gear meshes before the screw of a linear chain: between them the ratio is the
    second gear's (2, or 20); expressed at N/m through one lever (the last mesh's 2 pi / lead)
    the first mesh's own K is k1 (2 pi / lead)^2. With a 20:1 second gear the first mesh
    meets both of seed 001's conditions (ratio 20 >= 10, 1000 >= 5000 / 10) and its share
    is below 1e-3, as the conditions bound it (within / ratio^2 = 0.025 of the second's)."""
    from servo_toolkit.scene.loader import load_scene
    path = tmp_path / "three.toml"
    c = 2 * math.pi / 5e-3
    for gear, negligible in ((2.0, False), (20.0, True)):
        path.write_text(THREE_STAGES.replace("ratio = 2.0", f"ratio = {gear}"))
        chain = load_scene(path).drivetrain.stiffness(np.array([0.0]))
        crit = chain.criterion()
        assert crit.own_stiffness == pytest.approx([1000 * c**2, 5000 * c**2, 2e8], rel=1e-12)
        assert crit.later_ratio[0] == pytest.approx([gear], rel=1e-12)
        assert bool(crit.negligible[0]) is negligible and not crit.negligible[1:].any()
        assert crit.own_stiffness[:, None] * crit.ratio**2 == pytest.approx(chain.stage_stiffness, rel=1e-12)
    assert chain.shares[0, 0] <= 10 / 20**2 * chain.shares[1, 0]
