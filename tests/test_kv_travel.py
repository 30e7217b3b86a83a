"""A Kv study on an output travel takes its load inertias as masses (kg)."""

import tomllib

import numpy as np
import pytest

from servo_toolkit import run_study
from servo_toolkit.errors import SceneError

from .conftest import SCENES, build


def _with_kv(inertias):
    data = tomllib.loads((SCENES / "linear_roller_screw_actuator.toml").read_text())
    data.setdefault("studies", {})["kv_travel"] = {"kind": "kv", "frequency": "4 Hz", "amplitude": "2 mm",
                                                   "load_inertias": inertias}
    return build(data)


def test_kv_on_a_travel_accepts_masses():
    scene = _with_kv(["0 kg", "20 kg"])
    assert scene.drivetrain.output_is_linear
    result = run_study(scene, "kv_travel")
    cases = result.to_dict()["cases"]
    masses = sorted({c.get("load_mass_kg", c.get("load_inertia_kg_m2")) for c in cases})
    np.testing.assert_allclose(masses, [0.0, 20.0])
    peaks = [c["peak_motor_torque_Nm"] for c in cases]
    assert max(peaks) > min(peaks)  # the 20 kg load needs more torque


def test_kv_on_a_travel_refuses_a_rotary_inertia():
    with pytest.raises(SceneError) as err:
        _with_kv(["20 kg*m^2"])
    assert err.value.key.startswith("studies.kv_travel.load_inertias")
