"""An unstable closed loop says so everywhere: header, requirements table, JSON, check rows.

The reference EMA's designed cascade sampled at 1 s (a design file's ``sample_time_s``): the
sampling delay turns the loop unstable. A margin measures how far a stable loop is from
instability, so the unstable loop has none; every requirement row fails with the reason (the
closed-loop poles in the right half-plane), never with a placeholder figure (0 dB, -inf deg,
inf dB). The count of unstable poles is checked against the Nyquist count of the open loop's
encirclements of -1, an independent route to the same number."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from servo_toolkit.cli import main

from .conftest import SCENES

#: the reference EMA's automatic design (cascade with its notch), its sample time set to 1 s
DESIGN = {"servo_toolkit_design": 1, "scene": "ema_reference", "q0_rad": 0.0, "structure": "cascade",
          "gains": {"kp": 35.58523640577714, "kv": 42.68137893896361, "wvi": 37.69911184307752},
          "filter": "notch", "filter_params": {"wn": 173.3850753755059, "zeta_zero": 0.14, "zeta_pole": 0.7},
          "ratio": 138.85839528866887, "current_kp_v_per_a": 3.141592653589793,
          "current_ki_v_per_a_s": 3141.592653589793, "sample_time_s": 1.0}
POINT_ROWS = ("bandwidth", "phase_lag_at_bandwidth", "gain_margin", "phase_margin", "sensitivity_peak")
STROKE_ROWS = ("gain_margin_over_stroke", "phase_margin_over_stroke", "sensitivity_peak_over_stroke")


@pytest.fixture(scope="module")
def sampled(tmp_path_factory):
    """(scene path, design file path, DesignResult) of the 1 s sampled loop."""
    from servo_toolkit.loop.tuning import load_design
    from servo_toolkit.scene import load_scene
    path = tmp_path_factory.mktemp("sampled") / "design_1s.json"
    path.write_text(json.dumps(DESIGN))
    scene_path = SCENES / "ema_reference.toml"
    return scene_path, path, load_design(load_scene(scene_path), str(path))


def test_the_sampled_loop_is_unstable_and_has_no_margins(sampled):
    m = sampled[2].margins
    assert not m.closed_loop_stable
    # the count of right-half-plane poles agrees with the Nyquist criterion's Z = P + N
    assert m.unstable_closed_loop_poles == m.nyquist_rhp_closed_loop_poles > 0
    for name in ("gain_margin_db", "phase_margin_deg", "delay_margin_s", "disk_margin", "sensitivity_peak_db",
                 "bandwidth_hz", "lower_gain_margin_db", "upper_gain_margin_db"):
        assert math.isnan(getattr(m, name)), name
    assert all(math.isnan(x) for x in m.delay_margins_s)
    assert f"{m.unstable_closed_loop_poles} closed-loop poles in the right half-plane" in m.unstable_reason
    # the crossings of L are still where L is: real and negative, of unit magnitude
    from servo_toolkit.loop.crossings import response_of
    L = response_of(sampled[2].loop)
    for f, g in zip(m.phase_crossover_hz, m.gain_margins_db):
        lw = L(np.array([2j * math.pi * f]))[0]
        assert lw.real < 0 and abs(lw.imag) <= 1e-6 * abs(lw) and g == pytest.approx(-20 * math.log10(abs(lw)))


def test_every_requirement_row_fails_with_the_reason_and_no_figure(sampled):
    r = sampled[2]
    rows = {c.name: c for c in r.requirements}
    for name in POINT_ROWS:
        c = rows[name]
        assert not c.passed and math.isnan(c.achieved) and math.isnan(c.shortfall)
        assert c.reason == r.margins.unstable_reason
    for name in STROKE_ROWS:
        c = rows[name]
        assert not c.passed and math.isnan(c.achieved) and "unstable at" in c.reason
    assert not r.passed and {c.name for c in r.failures} >= set(POINT_ROWS + STROKE_ROWS)
    # the Jupyter card and its one-line repr say the same
    assert "right half-plane" in r._repr_line() and "GM" not in r._repr_line()
    assert "unstable (closed loop unstable" in r._repr_card()


def test_design_header_table_and_json_agree(sampled, capsys):
    scene, design_file, _ = sampled
    assert main(["design", str(scene), "--design", str(design_file), "--linear-only"]) == 1
    out = capsys.readouterr().out
    header = out.split("\n\n")[0]
    assert "closed loop stable: NO" in header and "right half-plane" in header
    assert "margins: none" in header and "GM " not in header and "PM " not in header
    assert not re.search(r"\bnan\b|\binf\b", header)
    table = out.split("\n\n")[1].split("command options")[0]
    for name in POINT_ROWS + STROKE_ROWS:
        line = next(x for x in table.splitlines() if x.strip().startswith(name + " "))
        assert "unstable" in line and "FAIL" in line and "inf" not in line and " 0 dB" not in line, line
    assert "FAIL bandwidth, phase_lag_at_bandwidth, gain_margin, phase_margin, sensitivity_peak: closed loop " \
           "unstable:" in table

    assert main(["design", str(scene), "--design", str(design_file), "--linear-only", "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert d["closed_loop_stable"] is False and d["requirements_met"] is False
    assert "right half-plane" in d["unstable_reason"]
    for key in ("gain_margin_db", "phase_margin_deg", "delay_margin_s", "disk_margin", "sensitivity_peak_db",
                "bandwidth_hz"):
        assert d[key] is None, key
    assert d["margins"]["lower_gain_margin_db"] is None and d["margins"]["upper_gain_margin_db"] is None
    for name in POINT_ROWS + STROKE_ROWS:
        row = d["requirements"][name]
        assert row["passed"] is False and row["achieved"] is None and row["shortfall"] is None and row["reason"]
    assert d["requirements"]["gain_margin"]["reason"] == d["unstable_reason"]


def test_check_fails_the_unstable_loop_with_the_reason(sampled, capsys):
    scene, design_file, _ = sampled
    assert main(["check", str(scene), "--design", str(design_file), "--linear-only", "--json"]) == 1
    d = json.loads(capsys.readouterr().out)["scenes"][0]
    rows = {r["id"]: r for r in d["rows"]}
    assert d["passed"] is False and rows["closed_loop_stable"]["status"] == "fail"
    assert "right half-plane" in rows["closed_loop_stable"]["detail"]
    for name in POINT_ROWS + STROKE_ROWS:
        assert rows[name]["status"] == "fail" and rows[name]["achieved"] == "unstable", name
        assert "unstable" in rows[name]["detail"] and rows[name]["shortfall"] == ""
    # the JUnit message of a row
    from servo_toolkit.studies.gate import RequirementRow
    msg = RequirementRow(**rows["gain_margin"]).message()
    assert "achieved unstable; closed loop unstable: " in msg and "short by" not in msg
