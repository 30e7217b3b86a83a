"""Identification finds the global optimum within the physical range, and says when the
model cannot follow the data (noise floor from the data) or the data cannot identify."""

import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.identify import FrequencyData, fit
from servo_toolkit.identify.bounds import RANGE_FACTOR, physical_range
from servo_toolkit.identify.features import response_features
from servo_toolkit.identify.fit import _intervals
from servo_toolkit.identify.model import plant_response
from servo_toolkit.identify.params import SceneTemplate
from servo_toolkit.identify.search import global_least_squares, refine
from servo_toolkit.identify.noise import frequency_noise, smoother_sd
from servo_toolkit.identify.residuals import frequency_residual
from servo_toolkit.identify.verdict import judge, scatter_sd

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
KEYS = ["load.inertia", "drivetrain[3].stiffness"]
F = np.logspace(0, np.log10(300), 80)


def noisy(f, h, gain_db_sd, phase_deg_sd, seed):
    rng = np.random.default_rng(seed)
    h = h * 10 ** (rng.normal(0, gain_db_sd, f.size) / 20) * np.exp(1j * np.radians(rng.normal(0, phase_deg_sd, f.size)))
    return FrequencyData.from_complex(f, h)


@pytest.fixture(scope="module")
def scene():
    return load_scene(EMA)


@pytest.fixture(scope="module")
def far_rig(scene):
    """A rig far from its scene: load inertia x1.5, housing stiffness x0.7; 80 points
    1-300 Hz with 0.1 dB / 0.5 deg noise."""
    template = SceneTemplate(scene, KEYS)
    values = np.array(template.initial) * [1.5, 0.7]
    rig = template.scene(values)
    return rig, values, noisy(F, plant_response(rig, F), 0.1, 0.5, seed=0)


def test_a_rig_far_from_its_scene_fits_to_the_noise(scene, far_rig):
    """Started at the scene's values a local optimizer ended at -80 % / -92 % with a 4 dB
    residual; the global search finds the rig within its intervals."""
    _, truth, data = far_rig
    r = fit(scene, data, "plant", KEYS)
    for key, true in zip(KEYS, truth):
        lo, hi = r.ci95[r.keys.index(key)]
        assert lo < true < hi, (key, lo, true, hi)
    assert r.residual_db_rms < 0.15 and r.residual_phase_deg_rms < 0.75
    assert r.verdict == "fits to the noise" and not r.warnings
    assert r.noise_floor == pytest.approx(r.residual_rms, rel=0.5)
    assert r.to_dict()["verdict"] == "fits to the noise"
    assert "verdict: fits to the noise" in r.table()


def test_the_features_give_a_start_near_the_rig(scene, far_rig):
    """The data's own antiresonance and resonance move with sqrt(K/J); their inertia line
    with the total inertia: the features alone place the start within a few per cent."""
    rig, _, data = far_rig
    level, notch, peak = response_features(data.frequency_hz, data.complex)
    exact = response_features(F, plant_response(rig, F))
    assert level == pytest.approx(exact[0], abs=0.02)
    assert math.exp(notch) == pytest.approx(math.exp(exact[1]), rel=0.03)
    assert math.exp(peak) > math.exp(notch)
    base = response_features(F, plant_response(scene, F))
    # a softer housing and a heavier load: the notch moves down (by sqrt(1.5 / 0.7) = 1.46 for
    # a two-mass drive; the chain's other compliances stiffen it a little)
    assert 1.2 < math.exp(base[1] - notch) < 1.5


def test_a_rigid_response_has_no_mode_features(scene):
    f = np.logspace(0, 1, 30)
    level, notch, peak = response_features(f, 100 / (2j * np.pi * f))
    assert level == pytest.approx(math.log(100)) and notch is None and peak is None


def test_the_physical_range_bounds_the_fit(scene):
    template = SceneTemplate(scene, ["load.inertia", "drivetrain[0].efficiency"])
    lower, upper = physical_range(template.parameters)
    assert lower[0] == pytest.approx(1 / RANGE_FACTOR) and upper[0] == pytest.approx(RANGE_FACTOR)
    assert upper[1] == 1.0  # an efficiency never exceeds 1
    # ... nor falls below the 0.01 the scene accepts (0.97 / 100 would)
    assert lower[1] == pytest.approx(0.01)
    # the range a key's model is conditioned for bounds the factor 100 box as well
    from servo_toolkit.identify.params import Parameter
    resistance = Parameter("motor.resistance", "motor", "resistance", "ohm", 5e3, bounds=(1e-3, 1e4))
    hinge = Parameter("load.hinge_moment", "load", "hinge_moment", "N*m", -5e8, rule="finite", bounds=(1e-12, 1e9))
    lo, hi = physical_range([resistance, hinge])
    assert (lo[0], hi[0]) == pytest.approx((50.0, 1e4)) and (lo[1], hi[1]) == pytest.approx((-1e9, 1e9))


def test_the_search_finds_the_deepest_of_many_valleys():
    """A residual with a local minimum in every period; the global one at z = 2.2."""
    def residuals(z):
        return np.array([np.sin(4 * (z[0] - 2.2)) * 2, 0.3 * (z[0] - 2.2)])
    sol = global_least_squares(residuals, [-4.0], [4.0], [-3.0])
    assert sol.z[0] == pytest.approx(2.2, abs=1e-6)
    assert len(sol.ends) >= 2 and sol.ends[0] < 1e-12 < sol.ends[-1]
    # without scattered starts it stays in the valley of the initial values
    alone = global_least_squares(residuals, [-4.0], [4.0], [-3.0], starts=0)
    assert abs(alone.z[0] - 2.2) > 1


def test_the_noise_floor_is_the_scatter_of_the_data():
    x = np.linspace(0, 3, 80)
    smooth = 20 * np.log10(1 + x ** 2) + 3 * np.sin(x)
    draws = [smooth + np.random.default_rng(s).normal(0, 0.1, x.size) for s in range(20)]
    assert np.mean([scatter_sd(d) for d in draws]) == pytest.approx(0.1, rel=0.1)  # third differences (traces)
    assert np.mean([smoother_sd(x, d) for d in draws]) == pytest.approx(0.1, rel=0.1)  # local fit (responses)
    assert scatter_sd(smooth[:8]) is None and smoother_sd(x[:8], smooth[:8]) is None
    assert judge(0.1, None, 10, 12, True) == "noise floor unknown"
    assert judge(0.5, 0.1, 10, 12, True) == "model mismatch"
    assert judge(0.1, 0.1, 10, 12, False) == "not identifiable"


@pytest.mark.parametrize("points", [30, 40, 80])
def test_a_sharp_resonance_on_a_coarse_grid_is_not_noise(scene, points):
    """Third differences of the noiseless reference EMA read its resonance as noise: a floor
    of 1.43 at 30 points, 0.42 at 40 (0.017 at 80), against 0.1 dB of real noise. The local
    fit's robust scale leaves the few points the quadratic cannot follow out, and finds the
    noise that is there: none, and 0.1 dB / 0.5 deg when it is added."""
    f = np.logspace(0, np.log10(300), points)
    h = plant_response(scene, f)
    clean = frequency_noise(FrequencyData.from_complex(f, h))
    assert clean.gain_db.max() < 0.02 and clean.phase_deg.max() < 0.02, clean.basis
    sd = np.array([[n.gain_db[0], n.phase_deg[0]] for n in
                   (frequency_noise(noisy(f, h, 0.1, 0.5, seed)) for seed in range(12))])
    assert sd.mean(axis=0) == pytest.approx([0.1, 0.5], rel=0.3)


def test_a_grid_too_coarse_has_no_noise_floor(scene):
    f = np.logspace(0, np.log10(300), 20)  # 8 points per decade
    data = FrequencyData.from_complex(f, plant_response(scene, f))
    noise = frequency_noise(data)
    assert not noise.known and "per decade" in noise.basis
    r = fit(scene, data, "plant", KEYS[:1], starts=0)
    assert r.verdict == "noise floor unknown" and "per decade" in r.verdict_text()


@pytest.fixture(scope="module")
def coarse(scene):
    """A rig whose housing is 15 % softer, measured without noise on 30 and 40 points: a
    fit of the load inertia alone cannot follow it; a fit of both finds it exactly."""
    template = SceneTemplate(scene, KEYS)
    rig = template.scene(np.array(template.initial) * [1.0, 0.85])
    out = {}
    for n in (30, 40):
        f = np.logspace(0, np.log10(300), n)
        data = FrequencyData.from_complex(f, plant_response(rig, f))
        out[n] = (fit(scene, data, "plant", KEYS[:1], starts=0), fit(rig, data, "plant", KEYS, starts=0))
    return out


@pytest.mark.parametrize("points", [30, 40])
def test_a_mismatch_on_a_coarse_grid_is_named(coarse, points):
    """Third differences called this mismatch (0.18 dB, 0.3-0.7 deg RMS) 'fits to the noise'
    at 30 and 40 points."""
    r, _ = coarse[points]
    assert r.verdict == "model mismatch", r.verdict_text()
    assert 0.1 < r.residual_db_rms < 0.4


@pytest.mark.parametrize("points", [30, 40])
def test_a_noiseless_exact_model_fits_to_the_noise(coarse, points):
    """The fit of both parameters starts on the truth's load inertia (z = -1e-10 after the
    fit of the features): a finite-difference step relative to z (scipy's ``diff_step``, 1e-16
    there) changed no model and read the load inertia as having no influence at 30 points."""
    _, r = coarse[points]
    assert r.verdict == "fits to the noise", r.verdict_text()
    assert r.residual_db_rms < 1e-6 and not r.warnings


@pytest.mark.parametrize("z0, rtol", [(0.0, 1e-9), (-1e-10, 1e-9), (math.log(RANGE_FACTOR) - 1e-7, 1e-6)])
def test_the_refinements_jacobian_steps_a_share_of_the_value_wherever_it_starts(z0, rtol):
    """Residuals exact at z0, linear in the value exp(z): the refinement stops where it starts
    and returns the Jacobian there, the value's derivative times (1, -2, 0.5): by central
    differences to 1e-9 at the scene's value (z = 0) and next to it (where a step relative to
    z, scipy's ``diff_step``, is 1e-16: a column of 0 or 1.1 instead of 1), and within the box
    to 1e-6 beside its upper bound (ln 100), whose side is stepped short."""
    upper = math.log(RANGE_FACTOR)

    def residuals(z):
        assert -upper <= z[0] <= upper
        return (math.exp(z[0]) - math.exp(z0)) * np.array([1.0, -2.0, 0.5])

    sol = refine(residuals, [z0], [-upper], [upper])
    assert sol.x[0] == z0 and sol.cost == 0.0
    np.testing.assert_allclose(sol.jac[:, 0], math.exp(z0) * np.array([1.0, -2.0, 0.5]), rtol=rtol)
    assert sol.evaluations == sol.nfev + 2 * sol.njev


@pytest.fixture(scope="module")
def mismatch(scene, far_rig, tmp_path_factory):
    """The far rig fitted with its load inertia alone: the housing stiffness it lacks moves
    the antiresonance and resonance, which no inertia can follow."""
    _, _, data = far_rig
    path = tmp_path_factory.mktemp("rig") / "rig.csv"
    np.savetxt(path, np.column_stack([data.frequency_hz, data.gain_db, data.phase_deg]), delimiter=",",
               header="frequency_hz,gain_db,phase_deg", comments="", fmt="%.9g")
    return fit(scene, data, "plant", KEYS[:1]), str(path)


def test_a_model_mismatch_is_named_not_blamed_on_the_data(mismatch):
    r, _ = mismatch
    assert r.verdict == "model mismatch" and r.mismatch
    assert r.residual_rms > 3 * r.noise_floor
    assert not any("cannot identify" in w or "combination" in w for w in r.warnings)
    assert r.misses and r.misses[0].endswith("Hz")
    lo, hi = (float(v) for v in r.misses[0].split()[0].split("-"))
    assert lo < 30 and hi > 15  # the antiresonance and resonance of the rig (18 and 24 Hz)
    assert "model mismatch" in r.verdict_text() and r.misses[0] in r.verdict_text()


def test_the_command_exits_1_on_a_model_mismatch(mismatch, capsys):
    _, path = mismatch
    assert main(["fit", EMA, path, "--param", KEYS[0]]) == 1
    out, err = capsys.readouterr()
    assert "verdict: model mismatch" in out
    assert err.count("\n") == 1 and "model mismatch" in err and "Hz" in err
    assert main(["fit", EMA, path, "--param", KEYS[0], "--param", KEYS[1], "--json"]) == 0


def _two_mass(f, j2, k, j1=0.05, c=20.0, kt=10.0):
    """omega_m / i of a two-mass drive (analytic: a cheap model for many fits); the
    antiresonance at 22 Hz, the resonance at 138 Hz, about 5 % damped."""
    s = 2j * np.pi * f
    return kt * (j2 * s ** 2 + c * s + k) / (s * (j1 * j2 * s ** 2 + c * (j1 + j2) * s + k * (j1 + j2)))


@pytest.mark.parametrize("gain_db_sd, phase_deg_sd", [(0.3, 2.0), (0.05, 2.0)])
def test_intervals_cover_the_truth_in_90_to_99_percent_of_200_fits(gain_db_sd, phase_deg_sd):
    """200 noisy data sets of one truth, each fitted with the search, the weighting and the
    intervals the fit uses: the 95 % intervals contain the truth in 90-99 % of them, with
    noise in the gain and the phase alike (0.3 dB is 2 deg of a complex logarithm) and very
    unequal (0.05 dB against 2 deg: weighed as one neper against one radian, the gain's
    information is lost in the phase's noise and the intervals covered 199 of 200)."""
    f = np.logspace(0, np.log10(300), 60)
    truth = np.array([1.5, 3.0e4])
    h0 = _two_mass(f, *truth)
    x0 = np.array([1.0, 5.0e4])
    hits = np.zeros(2)
    for seed in range(200):
        data = noisy(f, h0, gain_db_sd, phase_deg_sd, seed)
        noise = frequency_noise(data)

        def residuals(z):
            return frequency_residual(_two_mass(f, *(x0 * np.exp(z))), data, noise)
        sol = global_least_squares(residuals, [-3.0, -3.0], [3.0, 3.0], [0.0, 0.0], starts=4, seed=seed)
        half, _, singular = _intervals(sol.jac, sol.fun, sol.fun.size - 2)
        assert not singular.any()
        hits += np.abs(sol.z - np.log(truth / x0)) < half
    assert ((hits >= 180) & (hits <= 198)).all(), hits
