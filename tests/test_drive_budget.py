"""One rule for what the actuator can follow: the command's reach (loop.reach) and the
default sine's followable amplitude (studies.actuator.spec) are the same drive budget
(loop.drive_budget), checked against closed forms of the motor equations."""

import math
import tomllib

import pytest
from hypothesis import given, settings, strategies as st

from servo_toolkit import load_scene
from servo_toolkit.drivetrain.operating_point import operating_point
from servo_toolkit.errors import SceneError
from servo_toolkit.loop.drive_budget import drive_budget
from servo_toolkit.loop.reach import reach
from servo_toolkit.scene.loader import scene_from_dict
from servo_toolkit.studies.actuator.spec import FOLLOW_SHARE, followable_amplitude

from .conftest import SCENES

SHIPPED = ("ema_reference.toml", "emps.toml", "linear_roller_screw_actuator.toml")
_SCENES = {name: load_scene(SCENES / name) for name in SHIPPED}
# EMPS: 10 mm lead, Kt = Ke = 0.013984, 0.25 ohm, 40 A, 10 V, rotor 2e-5 kg*m^2, cart 87.21322 kg
N, KT, R, IMAX, VMAX, JROT, MLOAD = 2 * math.pi / 0.01, 0.013984, 0.25, 40.0, 10.0, 2e-5, 87.21322


def _emps(efficiency=1.0, load_coulomb=0.0, volts=None):
    """The EMPS axis without friction or offset (unless asked), of ``efficiency``; ``volts``:
    another voltage limit (at 10 V and 40 A the resistance takes the whole voltage: the
    voltage binds at every frequency)."""
    data = tomllib.loads((SCENES / "emps.toml").read_text())
    if volts is not None:
        data["motor"]["voltage_limit"] = f"{volts} V"
    data["motor"].pop("coulomb_friction")
    data["load"].pop("hinge_moment")
    data["load"].pop("damping")
    data["drivetrain"][0]["efficiency"] = efficiency
    if load_coulomb:
        data["load"]["coulomb_friction"] = f"{load_coulomb} N"
    return scene_from_dict(data, "emps.toml")


@settings(max_examples=40, deadline=None)
@given(name=st.sampled_from(SHIPPED), f=st.floats(0.2, 40.0), share=st.floats(0.05, 3.0))
def test_reach_and_followable_amplitude_agree(name, f, share):
    """A sine at f of amplitude A lies within the followable amplitude exactly when the drive
    budget the reach is made of, with the same share of the limits and the loads left to the
    other share, over the stroke the sine sweeps, allows its peak speed A w and peak
    acceleration A w^2; with no loads the reach itself says the same."""
    scene = _SCENES[name]
    q0 = operating_point(scene)[0]
    top = followable_amplitude(scene, q0, f)
    amp = top * share
    w = 2 * math.pi * f

    def allowed(a):
        return drive_budget(scene, q0 - a, q0 + a, FOLLOW_SHARE, loads=False).allows(a * w, a * w * w)
    if abs(share - 1.0) > 1e-6:
        assert allowed(amp) == (share < 1.0)
    assert allowed(top)


@settings(max_examples=20, deadline=None)
@given(f=st.floats(0.2, 40.0), share=st.floats(0.05, 3.0))
def test_without_loads_the_reach_and_the_followable_amplitude_are_one_rule(f, share):
    scene = _emps(0.8)
    top = followable_amplitude(scene, 0.0, f)
    w = 2 * math.pi * f

    def allowed(a):
        try:
            r = reach(scene, -a, bandwidth_hz=1.0, fraction=FOLLOW_SHARE, to=a)
        except SceneError:
            return False
        return r.allows(a * w, a * w * w)
    if abs(share - 1.0) > 1e-6:
        assert allowed(top * share) == (share < 1.0)
    assert allowed(top)


def test_a_rigid_lossless_drive_reaches_the_closed_forms():
    """Without losses or friction: current-limited A = s Kt I_max N / (J w^2), J the rotor's
    J_m N^2 and the cart's mass; voltage-limited (R i + Ke N v within s V_max, i = J A w^2 /
    (N Kt), v = A w) A = s V / (w (R J w / (N Kt) + Ke N)); reach's a_max = s Kt I N / J."""
    scene = _emps()
    j = JROT * N**2 + MLOAD
    s = FOLLOW_SHARE
    for f in (0.5, 3.0, 10.0, 30.0):
        w = 2 * math.pi * f
        a_i = s * KT * IMAX * N / (j * w * w)
        a_v = s * VMAX / (w * (R * j * w / (N * KT) + KT * N))
        assert followable_amplitude(scene, 0.0, f) == pytest.approx(min(a_i, a_v), rel=1e-10)
    assert reach(scene, 0.0, 1.0).a_max == pytest.approx(0.8 * KT * IMAX * N / j, rel=1e-12)


def test_efficiency_lowers_the_current_limited_amplitude_by_its_factor():
    """With a screw of efficiency eta the motor's torque reaches the cart as eta N Kt i while
    the rotor, before the loss, is accelerated in full: the current-limited amplitude is
    eta J / (eta J_rotor + M) of the lossless one (0.747 at eta 0.7)."""
    eta, j_rot = 0.7, JROT * N**2
    factor = eta * (j_rot + MLOAD) / (eta * j_rot + MLOAD)
    f = 30.0  # current-limited at 100 V
    lossless, lossy = followable_amplitude(_emps(volts=100), 0.0, f), followable_amplitude(_emps(eta, volts=100), 0.0, f)
    w = 2 * math.pi * f
    assert lossless == pytest.approx(FOLLOW_SHARE * KT * IMAX * N / ((j_rot + MLOAD) * w * w), rel=1e-10)
    assert lossy == pytest.approx(factor * lossless, rel=1e-10)
    assert reach(_emps(eta), 0.0, 1.0).a_max == pytest.approx(factor * reach(_emps(), 0.0, 1.0).a_max, rel=1e-12)


def test_coulomb_friction_lowers_the_reach_by_its_share_and_is_the_loops_for_a_sine():
    """The cart's Coulomb friction F takes F / (0.8 N Kt I_max) of the reach's current share;
    the followable sine leaves it (as the hinge moment) to the loop's share, and its amplitude
    counts it only when asked (``loads=True``), by F / (s N Kt I_max)."""
    from servo_toolkit.loop.drive_budget import followable_sine
    f, fc = 30.0, 50.0
    clean = followable_amplitude(_emps(volts=100), 0.0, f)
    assert followable_amplitude(_emps(load_coulomb=fc, volts=100), 0.0, f) == clean
    rubbing = followable_sine(_emps(load_coulomb=fc, volts=100), 0.0, f, FOLLOW_SHARE, loads=True)
    assert rubbing == pytest.approx(clean * (1 - fc / (FOLLOW_SHARE * N * KT * IMAX)), rel=1e-10)
    r0, r1 = reach(_emps(), 0.0, 1.0), reach(_emps(load_coulomb=fc), 0.0, 1.0)
    assert r1.a_max == pytest.approx(r0.a_max * (1 - fc / (0.8 * N * KT * IMAX)), rel=1e-12)


def test_the_motor_friction_counts_through_the_drivetrain():
    """The EMPS motor's Coulomb friction 0.0324573 N*m is 20.39 N at the cart (N Fm): it
    lowers reach's acceleration as the cart's friction of that size would."""
    data = tomllib.loads((SCENES / "emps.toml").read_text())
    with_motor = scene_from_dict(data, "emps.toml")
    data["motor"].pop("coulomb_friction")
    data["load"]["coulomb_friction"] = f"{0.0324573 * N} N"
    at_load = scene_from_dict(data, "emps.toml")
    assert reach(with_motor, 0.0, 1.0).a_max == pytest.approx(reach(at_load, 0.0, 1.0).a_max, rel=1e-12)
