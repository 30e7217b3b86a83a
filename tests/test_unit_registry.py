"""pint's registry: its definitions parsed once, read from the user's cache afterwards, with
the same parsing results as a registry parsed from the definitions; a damaged or unwritable
cache is passed over."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from .conftest import ROOT

#: scene values of every kind the scenes use, and the SI unit each is read in
VALUES = [("0.5 mH", "H"), ("1.2 ohm", "ohm"), ("0.08 N*m/A", "N*m/A"), ("3e-5 kg*m^2", "kg*m**2"),
          ("2 deg", "rad"), ("60 rpm", "Hz"), ("100 rad/s", "Hz"), ("8 kHz", "Hz"), ("25 us", "s"),
          ("1.5e8 N*m/rad", "N*m/rad"), ("2 mm", "m"), ("40 kN", "N"), ("0.9", "dimensionless"),
          ("48 V", "V"), ("6 dB", "dB"), ("1e-3 N*m*s/rad", "N*m*s/rad"), ("5 um/s", "m/s")]

_CODE = """
import json, sys
from servo_toolkit.core import units, unit_registry
values = json.loads(sys.argv[1])
print(json.dumps({"folder": str(unit_registry.cache_folder()), "used": str(units.UREG.cache_folder),
                  "si": [units.parse_quantity(v, u, "k") for v, u in values],
                  "base": [units.parse_si(v, "k") for v, _ in values]}))
"""


def _registry_run(cache_home) -> dict:
    env = {**os.environ, "XDG_CACHE_HOME": str(cache_home)}
    proc = subprocess.run([sys.executable, "-c", _CODE, json.dumps(VALUES)], capture_output=True, text=True,
                          cwd=ROOT, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _parsed_without_cache() -> dict:
    """The same values through a registry that pint builds from its definitions file."""
    import pint

    from servo_toolkit.core import units
    saved = units.UREG
    units.UREG = pint.UnitRegistry()
    try:
        return {"si": [units.parse_quantity(v, u, "k") for v, u in VALUES],
                "base": [units.parse_si(v, "k") for v, _ in VALUES]}
    finally:
        units.UREG = saved


def test_the_definitions_are_parsed_once_then_read_from_the_cache(tmp_path):
    first = _registry_run(tmp_path)
    folder = first["folder"]
    assert folder.startswith(str(tmp_path / "servo_toolkit" / "pint"))
    assert first["used"] != folder and os.listdir(folder)  # parsed here, published for the next process
    second = _registry_run(tmp_path)
    assert second["used"] == folder  # read from the cache
    plain = _parsed_without_cache()
    assert first["si"] == second["si"] == plain["si"]
    assert first["base"] == second["base"] == plain["base"]
    assert [name for name in os.listdir(tmp_path / "servo_toolkit" / "pint")] == [os.path.basename(folder)]


def test_a_damaged_cache_is_passed_over(tmp_path):
    folder = _registry_run(tmp_path)["folder"]
    for name in os.listdir(folder):
        with open(os.path.join(folder, name), "wb") as fh:
            fh.write(b"not a pickle")
    run = _registry_run(tmp_path)
    assert run["si"] == _parsed_without_cache()["si"]


def test_an_unwritable_cache_is_passed_over(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("the cache root is a file: nothing can be written under it")
    run = _registry_run(blocker)
    assert run["si"] == _parsed_without_cache()["si"]
