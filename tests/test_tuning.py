"""Hand tuning as a pure function (checked against python-control), design files, and the
ipywidgets tuner driven from code."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import control as ct
import numpy as np
import pytest

from servo_toolkit import SceneError, load_scene
from servo_toolkit.cli import main
from servo_toolkit.loop.tuning import (LoopTuning, base_design, load_design, save_design, tuned_design,
                                       tuning_of)

from .conftest import SCENES

EMA = SCENES / "ema_reference.toml"


@pytest.fixture(scope="module")
def ema():
    return load_scene(EMA)


@pytest.fixture(scope="module")
def base(ema):
    return base_design(ema)


def test_the_design_s_own_values_reproduce_it(ema, base):
    d = tuned_design(ema, tuning_of(base), base=base)
    for key in ("gain_margin_db", "phase_margin_deg", "sensitivity_peak_db", "bandwidth_hz", "disk_margin"):
        assert getattr(d.margins, key) == pytest.approx(getattr(base.margins, key), rel=1e-9), key
    assert [c.passed for c in d.requirements] == [c.passed for c in base.requirements]
    assert "no change" in d.notes[0]


def test_position_gain_scales_the_loop(ema, base):
    """The loop broken at the position error is linear in kp: x1.5 lowers the gain margin by
    20 log10 1.5 dB exactly (same phase crossover), and python-control agrees."""
    t = tuning_of(base)
    d = tuned_design(ema, replace(t, kp=1.5 * t.kp), base=base)
    assert d.margins.gain_margin_db == pytest.approx(base.margins.gain_margin_db - 20 * math.log10(1.5), abs=1e-3)
    w = 2 * np.pi * np.logspace(-1, 3, 20)
    ratio = ct.frequency_response(d.loop, w).complex.ravel() / ct.frequency_response(base.loop, w).complex.ravel()
    assert np.allclose(ratio, 1.5, rtol=1e-9)
    # a gain margin g: g L has closed-loop poles on the imaginary axis
    g = 10 ** (d.margins.gain_margin_db / 20)
    poles = ct.feedback(g * d.loop, 1).poles()
    assert np.min(np.abs(poles.real)) < 1e-3 * np.max(np.abs(poles))
    assert "kp" in d.notes[0] and d.motion.gains["kp"] == pytest.approx(1.5 * t.kp)


def test_filter_and_operating_point(ema, base):
    t = tuning_of(base)
    d = tuned_design(ema, replace(t, resonance_filter="notch", filter_hz=30.0, depth_db=-20.0, width=0.4), base=base)
    fp = d.motion.filter_params
    assert d.motion.filter == "notch" and fp["wn"] == pytest.approx(2 * math.pi * 30.0)
    assert 20 * math.log10(fp["zeta_zero"] / fp["zeta_pole"]) == pytest.approx(-20.0)
    none = tuned_design(ema, replace(t, resonance_filter="none"), base=base)
    assert none.motion.filter == "none" and none.margins.gain_margin_db != d.margins.gain_margin_db
    moved = tuned_design(ema, replace(t, q0=math.radians(20.0)), base=base)
    assert moved.q0 == pytest.approx(math.radians(20.0)) and moved.parameters.J1 != base.parameters.J1
    with pytest.raises(SceneError, match="tuning.kp"):
        tuned_design(ema, replace(t, kp=-1.0), base=base)


def test_design_file_round_trip_and_the_cli(ema, base, tmp_path, capsys):
    t = tuning_of(base)
    d = tuned_design(ema, replace(t, kp=1.5 * t.kp), base=base)
    path = save_design(d, tmp_path / "tuned.json")
    again = load_design(ema, path)
    assert again.margins.gain_margin_db == pytest.approx(d.margins.gain_margin_db, rel=1e-9)
    code = main(["check", str(EMA), "--design", str(path), "--linear-only", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == (0 if again.passed else 1) and out["passed"] == again.passed
    assert out["scenes"][0]["gain_margin_db"] == pytest.approx(d.margins.gain_margin_db, rel=1e-9)
    assert main(["export", str(EMA), "--design", str(path), "-o", str(tmp_path / "c"), "--json"]) in (0, 1)
    exported = json.loads(capsys.readouterr().out)
    assert exported["design"]["gain_margin_db"] == pytest.approx(d.margins.gain_margin_db, rel=1e-9)
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert main(["check", str(EMA), "--design", str(bad)]) == 2
    assert "--design" in capsys.readouterr().err
    with pytest.raises(SceneError, match="refusing to overwrite the input"):
        save_design(d, EMA.with_suffix(".json") if EMA.with_suffix(".json").exists() else path, inputs=[path])


def test_check_reads_one_design_file_once_for_every_scene(base, tmp_path, capsys, monkeypatch):
    """``check --design`` checks every scene against the file as it was read before any
    work: it is read once, so a file rewritten between two scenes' designs changes
    neither verdict."""
    import servo_toolkit.loop.tuning as tuning
    path = save_design(base, tmp_path / "base.json")
    reads = []
    read = tuning.read_design_text

    def counting(p):
        reads.append(p)
        text = read(p)
        path.write_text("{}")  # rewritten after the one read: a second read would fail the check
        return text
    monkeypatch.setattr(tuning, "read_design_text", counting)
    code = main(["check", str(EMA), str(EMA), "--design", str(path), "--linear-only", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert len(reads) == 1 and code == (0 if base.passed else 1)
    assert [s["gain_margin_db"] for s in out["scenes"]] == [pytest.approx(base.margins.gain_margin_db, rel=1e-9)] * 2


def test_tuner_driven_from_code(ema, base):
    pytest.importorskip("ipywidgets")
    from servo_toolkit.tuner import tune
    tuner = tune(ema, base=base)
    assert tuner.current.margins.gain_margin_db == pytest.approx(base.margins.gain_margin_db, rel=1e-9)
    tuner.controls["kp"].value = tuner.controls["kp"].value * 1.5
    expected = tuned_design(ema, tuner.values(), base=base)
    assert tuner.current.margins.gain_margin_db == pytest.approx(expected.margins.gain_margin_db, rel=1e-12)
    assert "<svg" in tuner.views.value and "requirement" in tuner.table.value
    taken = tuner.use()
    assert taken is tuner.result is tuner.current
    assert isinstance(tuner.values(), LoopTuning) and "Tuner" in repr(tuner)
