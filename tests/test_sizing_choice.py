"""The ratio choice of the sizing: motor candidates (their rotor in the torque and in the
bandwidth), a swept screw lead (its lives), the bandwidth estimate against the closed form
of a two-mass chain (against the scene's design: tests/test_sizing_closed_loop.py, which
designs the reference EMA once), the sweep's figure and the sizing scene's shared tables."""

from __future__ import annotations

import copy
import math
import tomllib
import numpy as np
import pytest

from servo_toolkit.scene.loader import scene_from_dict
from servo_toolkit.studies.sizing import size

from .conftest import SCENES
from .test_sizing import J_L, J_M, N, inertia_scene, trapezoid_cycle

K_GEAR = 2.0e4           # N*m/rad at the gear's output
BIG_ROTOR = 10 * J_M


def two_mass_scene(**duty) -> dict:
    """The inertia scene with a compliant gear mesh: rotor -> N, spring at the output -> J_L;
    a candidate motor with ten times the rotor."""
    data = inertia_scene(trapezoid_cycle(), start="0 deg", ratio_range=[0.5, 2.0], ratio_points=3, **duty)
    data["drivetrain"][0]["torsional_stiffness"] = K_GEAR
    big = dict(data["motor"], rotor_inertia=BIG_ROTOR, name="big rotor")
    data["duty_cycle"]["motors"] = [big]
    return data


def _closed_form_bandwidth(rotor: float, factor: float) -> float:
    """min(f_r / 3, f_a / 2) of rotor -> spring K_GEAR -> J_L with the ratio N * factor."""
    j1 = rotor * (N * factor) ** 2
    fr = math.sqrt(K_GEAR * (1 / j1 + 1 / J_L)) / (2 * math.pi)
    fa = math.sqrt(K_GEAR / J_L) / (2 * math.pi)
    return min(fr / 3, fa / 2)


def test_a_motor_candidate_has_its_own_rotor_in_the_torque_and_the_bandwidth():
    data = two_mass_scene()
    sweep = size(scene_from_dict(data)).sweep
    assert sweep.motors == ("scene motor", "big rotor") and np.allclose(sweep.factors, [0.5, 1.0, 2.0])
    for m, rotor in enumerate((J_M, BIG_ROTOR)):
        for i, s in enumerate(sweep.factors):
            assert sweep.bandwidth[m, i] == pytest.approx(_closed_form_bandwidth(rotor, s), rel=1e-9)
    assert sweep.bandwidth[1, 1] < sweep.bandwidth[0, 1]     # ten times the rotor: a lower resonance
    # the candidate's row at s = 1 is the sizing of the scene with that motor
    alone = copy.deepcopy(data)
    alone["motor"]["rotor_inertia"] = BIG_ROTOR
    own = size(scene_from_dict(alone), sweep=False)
    assert sweep.rms_torque[1, 1] == pytest.approx(own.rms_torque, rel=1e-9)
    assert sweep.peak_torque[1, 1] == pytest.approx(float(np.abs(own.motor_torque).max()), rel=1e-9)
    # and at twice the ratio, the sizing of a scene with the gear ratio doubled
    double = copy.deepcopy(alone)
    double["drivetrain"][0]["ratio"] = 2 * N
    own2 = size(scene_from_dict(double), sweep=False)
    assert sweep.rms_torque[1, 2] == pytest.approx(own2.rms_torque, rel=1e-9)
    assert sweep.peak_speed[1, 2] == pytest.approx(float(np.abs(own2.motor_speed).max()), rel=1e-9)


def screw_scene(lead: float = 5e-3, required_life: str | None = None) -> dict:
    """A motor driving a ball screw (the first stage) and a mass, with the screw's ratings."""
    segments = [{"kind": "ramp", "to": "20 mm", "duration": "0.4 s", "accel_time": "0.1 s", "load": "3 kN"},
                {"kind": "dwell", "duration": "0.2 s", "load": "3 kN"},
                {"kind": "ramp", "to": "0 mm", "duration": "0.4 s", "accel_time": "0.1 s", "load": "-1 kN"},
                {"kind": "dwell", "duration": "0.2 s"}]
    duty = {"segments": segments, "start": "0 mm", "ratio_range": [0.5, 2.0], "ratio_points": 3}
    if required_life:
        duty["required_life"] = required_life
    return {"name": "screw", "motor": {"resistance": "0.5 ohm", "torque_constant": "0.2 N*m/A",
                                       "back_emf_constant": "0.2 V*s/rad", "rotor_inertia": J_M},
            "drivetrain": [{"kind": "ball_screw", "lead": lead, "screw_inertia": 1e-5, "nut_mass": 0.5,
                            "efficiency": 0.9, "dynamic_load_rating": "20 kN",
                            "bearing_dynamic_load_rating": "30 kN"}],
            "load": {"inertia": "40 kg"}, "duty_cycle": duty}


def test_a_swept_lead_divides_the_screws_life_and_bounds_the_feasible_range():
    base = size(scene_from_dict(screw_scene()))
    sweep = base.sweep
    assert sweep.swept.startswith("1 / lead")
    hours = dict(sweep.lives)
    screw = next(life for life in base.lives if "(screw)" in life.part)
    assert hours[screw.part] == pytest.approx(screw.hours / sweep.factors, rel=1e-12)
    # s = 2 is the screw of half the lead: the same thrust, twice the revolutions
    half = size(scene_from_dict(screw_scene(lead=2.5e-3)), sweep=False)
    for life in half.lives:
        assert hours[life.part][2] == pytest.approx(life.hours, rel=1e-9)
    assert sweep.rms_torque[0, 2] == pytest.approx(half.rms_torque, rel=1e-9)
    # a required life between the lives at s = 1 and s = 2 leaves s = 2 out (the motor has no limits)
    need = 0.75 * screw.hours
    limited = size(scene_from_dict(screw_scene(required_life=f"{need} h"))).sweep
    assert limited.feasible[0].tolist() == [True, True, False]
    assert size(scene_from_dict(screw_scene())).sweep.feasible[0].all()


def test_a_gear_in_front_of_the_screw_leaves_its_lives_out_of_the_sweep():
    sweep = size(SCENES / "ema_sizing.toml").sweep
    assert sweep.swept == "ratio of spur gear train" and sweep.lives == ()
    assert sweep.feasible_range() is not None


def test_a_life_no_gear_ratio_changes_leaves_no_ratio_feasible():
    # the screw's L10 behind a gear is the same at every gear ratio: short of the required
    # life there, it is short at every ratio, and no ratio of the sweep is feasible
    data = tomllib.loads((SCENES / "ema_sizing.toml").read_text())
    data["duty_cycle"]["required_life"] = "100000 h"
    res = size(scene_from_dict(data))
    screw = next(life for life in res.lives if "(screw)" in life.part)
    assert screw.hours < 1e5 and not res.passed
    assert not res.sweep.feasible.any() and res.sweep.feasible_range() is None
    assert "feasible overall ratio none" in res.table()


def test_the_sweep_figure_draws_every_figure_against_its_limit():
    import matplotlib
    matplotlib.use("Agg")
    res = size(scene_from_dict(screw_scene(required_life="1 h")))
    axes = res.plot_sweep()
    labels = [ax.get_ylabel() for ax in axes if ax.get_ylabel()]
    assert labels[:7] == ["RMS current [A]", "peak motor torque [N*m]", "peak motor speed [rad/s]",
                          "peak voltage (hot winding) [V]", "peak winding temperature [degC]",
                          "achievable bandwidth (estimate) [Hz]", "output stiffness [N/m]"]
    assert any(lab.startswith("L10") and lab.endswith("[h]") for lab in labels)
    assert axes[0].get_xlabel() == "" or "overall ratio [rad/m]" in {ax.get_xlabel() for ax in axes}
    # the feasible ratios shaded and the scene's ratio marked on every panel
    for ax in axes[:len(labels)]:
        assert ax.patches and any(np.allclose(line.get_xdata(), res.sweep.scene_ratio) for line in ax.lines)
    import matplotlib.pyplot as plt
    plt.close("all")


def _curves_in_view(ax) -> bool:
    """Whether every line's finite values (the curves and the dashed bound) lie within the
    panel's y range (the scene's ratio, a vertical line in axes' units, aside)."""
    lo, hi = sorted(ax.get_ylim())
    for line in ax.lines:
        if np.ptp(np.asarray(line.get_xdata(), float)) == 0:
            continue
        y = np.asarray(line.get_ydata(), float)
        y = y[np.isfinite(y)]
        if y.size and not (lo <= y.min() and y.max() <= hi):
            return False
    return True


def test_a_panel_held_to_a_lower_bound_shows_its_values_far_above_it():
    # bandwidth estimates of 11-16 Hz against 1 Hz required, lives of 1e4-2e5 h against 1 h:
    # what is asked lies far below the values, and the panel spans both
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    data = two_mass_scene()
    data["requirements"] = {"bandwidth": "1 Hz"}
    for res, wanted in ((size(scene_from_dict(data)), "achievable bandwidth"),
                        (size(scene_from_dict(screw_scene(required_life="1 h"))), "L10")):
        axes = res.plot_sweep()
        shown = [ax for ax in axes if ax.get_ylabel().startswith(wanted)]
        assert shown
        for ax in shown:
            assert len(ax.lines) >= 3 and _curves_in_view(ax)        # curves, the bound, the scene's ratio
            assert ax.get_yscale() == "log"                           # more than a decade between them
        plt.close("all")
    # a bound within a decade of the values: a linear axis still spanning both
    data["requirements"] = {"bandwidth": "5 Hz"}
    axes = size(scene_from_dict(data)).plot_sweep()
    ax = next(ax for ax in axes if ax.get_ylabel().startswith("achievable bandwidth"))
    assert ax.get_yscale() == "linear" and _curves_in_view(ax) and min(ax.get_ylim()) < 5
    plt.close("all")


def test_the_feasible_ratios_name_the_limits_that_end_them():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    res = size(SCENES / "ema_sizing.toml")
    sw = res.sweep
    low, high = sw.limited_by[0]
    ok = np.flatnonzero(sw.feasible[0])
    a, b = ok[0], ok[-1]
    # the ratio above the highest feasible one exceeds the supply, the highest does not
    assert high == "peak voltage"
    assert sw.peak_voltage[0, b + 1] > sw.limits[0]["voltage"] >= sw.peak_voltage[0, b]
    assert "RMS current" in low and sw.rms_current[0, a - 1] > sw.limits[0]["continuous_current"]
    text = res.table()
    assert f"rad/rad (limited by the {low} below, the peak voltage above); RMS-optimal ratio" in text
    assert sw.to_dict()["feasible_range_limited_by"] == [[low, high]]
    # the legend says it, and the voltage has its own panel
    axes = res.plot_sweep()
    legend = " ".join(t.get_text().replace("\n", " ") for ax in axes if ax.get_legend()
                      for t in ax.get_legend().get_texts())
    assert "limited by the" in legend and "the peak voltage above" in legend
    assert any(ax.get_ylabel() == "peak voltage (hot winding) [V]" for ax in axes)
    plt.close("all")
    # a required life between the lives at s = 1 and s = 2 ends the range at s = 1; the
    # lowest ratio is the sweep's end
    screw = next(life for life in size(scene_from_dict(screw_scene())).lives if "(screw)" in life.part)
    limited = size(scene_from_dict(screw_scene(required_life=f"{0.75 * screw.hours} h"))).sweep
    assert limited.limited_by == ((None, "required life"),)
    assert limited.limits_text() == "limited by the sweep range below, the required life above"


def test_the_sizing_scene_keeps_the_reference_emas_tables():
    """ema_sizing.toml repeats ema_reference.toml (the loader has no include): every table they
    share is the same, the sizing's additions aside."""
    ref = tomllib.loads((SCENES / "ema_reference.toml").read_text())
    siz = tomllib.loads((SCENES / "ema_sizing.toml").read_text())
    added = {"motor": {"thermal_resistance_winding", "thermal_resistance_housing", "thermal_time_constant_winding",
                       "thermal_time_constant_housing", "max_winding_temperature", "ambient_temperature"},
             "ball screw": {"dynamic_load_rating", "bearing_dynamic_load_rating", "bearing_kind"}}
    assert set(siz) - set(ref) == {"duty_cycle"} and set(ref) <= set(siz)
    for key in set(ref) - {"name", "description", "motor", "drivetrain"}:
        assert siz[key] == ref[key], key
    assert {k: v for k, v in siz["motor"].items() if k not in added["motor"]} == ref["motor"]
    assert len(siz["drivetrain"]) == len(ref["drivetrain"])
    for a, b in zip(siz["drivetrain"], ref["drivetrain"]):
        extra = added.get(a.get("name"), set())
        assert {k: v for k, v in a.items() if k not in extra} == b, a.get("name")


def test_a_fine_cycle_and_many_ratios_sweep_in_bounded_memory():
    # 100,000 samples x 200 ratios: the sweep takes the ratios a few at a time, so no array of
    # 20 million elements (160 MB) is built; the figures are those of the ratios one by one
    import tracemalloc
    from servo_toolkit.studies.sizing import sweep as sweep_module
    from servo_toolkit.studies.sizing.loads import cycle_loads
    scene = scene_from_dict(inertia_scene(trapezoid_cycle(), start="0 deg", sample_time="12 us",
                                          ratio_range=[0.5, 2.0], ratio_points=200))
    tracemalloc.start()
    try:
        res = size(scene)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert res.motion.t.size > 100_000 and peak < 100e6, peak
    # each ratio's figures are those of that factor's own (factors x samples) row
    loads = cycle_loads(scene.drivetrain, res.motion)
    rest, shaft, _ = sweep_module.split_torque(scene.drivetrain, res.motion, loads)
    k = 137
    s = res.sweep.factors[k]
    torque = rest / s + s * shaft
    assert res.sweep.rms_torque[0, k] == pytest.approx(res.motion.rms(torque), rel=1e-12)
    assert res.sweep.peak_torque[0, k] == pytest.approx(float(np.abs(torque).max()), rel=1e-12)


def test_a_screw_held_still_has_an_unbounded_life_shown_as_such():
    # a hold turns the screw no revolution: its L10 in hours is unbounded, a margin of inf (not
    # "none", which reads as no margin left)
    data = screw_scene(required_life="1000 h")
    data["duty_cycle"]["segments"] = [{"kind": "dwell", "duration": "1 s", "load": "3 kN"}]
    res = size(scene_from_dict(data), sweep=False)
    assert [life.hours for life in res.lives] == [math.inf, math.inf] and res.passed
    rows = [line for line in res.table().splitlines() if "L10" in line]
    assert len(rows) == 2 and all(line.split()[-2:] == ["inf", "ok"] for line in rows), rows
    assert "none" not in res.table()
