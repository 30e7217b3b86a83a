"""servo_toolkit.lti against python-control: the same matrices, polynomials and figures."""

from __future__ import annotations

import subprocess
import sys
import warnings

import control as ct
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from servo_toolkit.lti.analysis import bandwidth, stability_margins
from servo_toolkit.lti.connect import AlgebraicLoopError, feedback, interconnect
from servo_toolkit.lti.convert import pade, sample_tustin, ss2tf, ss2zpk_zeros, tf2ss
from servo_toolkit.lti.system import StateSpace, as_system, ss

SETTINGS = settings(max_examples=40, deadline=None)
seeds = st.integers(0, 2**32 - 1)


def _random(seed: int, n: int, inputs: int = 1, outputs: int = 1, stable: bool = False, feedthrough=True):
    """A random continuous block (python-control system) drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    if stable and n:
        A -= (np.max(np.linalg.eigvals(A).real) + rng.uniform(0.1, 2.0)) * np.eye(n)
    B, C = rng.normal(size=(n, inputs)), rng.normal(size=(outputs, n))
    D = rng.normal(size=(outputs, inputs)) if feedthrough and rng.uniform() < 0.5 else np.zeros((outputs, inputs))
    return ct.ss(A, B, C, D)


def _same(ours, theirs):
    for k in "ABCD":
        np.testing.assert_array_equal(getattr(ours, k), getattr(theirs, k), err_msg=k)


def _poly(rng, degree: int, zero_lead: bool):
    p = rng.normal(size=degree + 1)
    if zero_lead and degree:
        p[0] = 0.0
    return p


@SETTINGS
@given(seeds, st.integers(0, 5), st.integers(0, 5), st.booleans())
def test_tf2ss_is_python_controls_ss_of_tf(seed, nd, nn, zero_lead):
    rng = np.random.default_rng(seed)
    num, den = _poly(rng, min(nn, nd), zero_lead), _poly(rng, nd, zero_lead and seed % 2 == 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = ct.ss(ct.tf(num, den), inputs=["a"], outputs=["b"])
        got = tf2ss(num, den, inputs=["a"], outputs=["b"])
    _same(got, want)
    assert got.inputs == ("a",) and got.outputs == ("b",) and got.states == tuple(want.state_labels)


def test_tf2ss_refuses_improper_and_zero_denominator():
    with pytest.raises(ValueError):
        tf2ss([1, 2, 3], [1, 2])
    with pytest.raises(ValueError):
        tf2ss([1], [0, 0])


@SETTINGS
@given(seeds, st.integers(0, 6), st.booleans())
def test_ss2tf_is_python_controls(seed, n, stable):
    sys_ = _random(seed, n, stable=stable)
    tf = ct.ss2tf(sys_)
    num, den = ss2tf(as_system(sys_))
    np.testing.assert_array_equal(num, tf.num[0][0])
    np.testing.assert_array_equal(den, tf.den[0][0])


@SETTINGS
@given(seeds, st.integers(1, 6), st.booleans())
def test_ss2zpk_zeros_are_scipys(seed, n, stable):
    from scipy.signal import ss2zpk
    g = _random(seed, n, stable=stable)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        np.testing.assert_array_equal(ss2zpk_zeros(g.A, g.B, g.C, g.D), ss2zpk(g.A, g.B, g.C, g.D)[0])


@pytest.mark.parametrize("T, n, numdeg", [(0.1, 1, None), (1, 3, -2), (1e-3, 5, 2), (0, 2, None), (2.5, 4, 0), (3e-4, 2, None)])
def test_pade_is_python_controls(T, n, numdeg):
    assert pade(T, n, numdeg) == ct.pade(T, n, numdeg)


def test_pade_first_order_is_the_closed_form():
    num, den = pade(0.2, 1)
    np.testing.assert_allclose(num, [-1.0, 10.0], rtol=1e-15)
    np.testing.assert_allclose(den, [1.0, 10.0], rtol=1e-15)


@SETTINGS
@given(seeds, st.integers(0, 5), st.integers(1, 3), st.floats(1e-5, 0.5))
def test_sample_tustin_is_python_controls(seed, n, m, Ts):
    sys_ = ct.ss(*(getattr(_random(seed, n, m, 2), k) for k in "ABCD"), name="blk",
                 inputs=[f"in{k}" for k in range(m)], outputs=["p", "q"])
    want = ct.sample_system(sys_, Ts, method="tustin")
    got = sample_tustin(as_system(sys_), Ts)
    _same(got, want)
    assert got.dt == want.dt == Ts and got.name == want.name
    assert got.inputs == tuple(want.input_labels) and got.states == tuple(want.state_labels)


def _loop_blocks(seed):
    """Plant (u, d -> y, v), PI (e -> u), delay (y -> ym), comparison (r, ym -> e)."""
    rng = np.random.default_rng(seed)
    g = _random(seed, int(rng.integers(1, 5)), 2, 2, feedthrough=False)
    g = ct.ss(g.A, g.B, g.C, g.D, inputs=["u", "d"], outputs=["y", "v"], name="plant")
    kp, ki = rng.uniform(0.1, 3.0, size=2)
    pi = ct.ss(ct.tf([kp, ki], [1, 0]), inputs=["e"], outputs=["u"], name="pi")
    dly = ct.ss(ct.tf(*ct.pade(rng.uniform(1e-3, 0.1), int(rng.integers(1, 4)))), inputs=["y"], outputs=["ym"], name="delay")
    cmp_ = ct.ss([], [], [], [[1.0, -1.0]], inputs=["r", "ym"], outputs=["e"], name="compare")
    return [g, pi, dly, cmp_]


@SETTINGS
@given(seeds)
def test_interconnect_of_a_named_loop_is_python_controls(seed):
    blocks = _loop_blocks(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = ct.interconnect(blocks, inplist=["r", "d"], outlist=["y", "-u", "e"],
                               inputs=["r", "d"], outputs=["y", "minus_u", "e"], name="cl")
    got = interconnect([as_system(b) for b in blocks], ["r", "d"], ["y", "-u", "e"],
                       inputs=["r", "d"], outputs=["y", "minus_u", "e"], name="cl")
    _same(got, want)
    assert got.states == tuple(want.state_labels) and got.outputs == ("y", "minus_u", "e")


@SETTINGS
@given(seeds)
def test_interconnect_default_names_and_block_input_as_output(seed):
    blocks = _loop_blocks(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = ct.interconnect(blocks, inplist=["r"], outlist=["plant.u", "ym"])
    got = interconnect([as_system(b) for b in blocks], ["r"], ["plant.u", "ym"])
    _same(got, want)
    assert got.inputs == tuple(want.input_labels) and got.outputs == tuple(want.output_labels)


def test_interconnect_refuses_unknown_signal_and_algebraic_loop():
    a = ss([], [], [], [[0.5]], inputs="x", outputs="y", name="a")
    b = ss([], [], [], [[1.0]], inputs="y", outputs="x", name="b")
    with pytest.raises(ValueError, match="could not find signal"):
        interconnect([a, b], ["nothing"], ["y"])
    with pytest.raises(ValueError, match="could not find signal"):
        interconnect([a], ["x"], ["x"])  # a bare name in outlist is an output only (as python-control)
    c = ss([], [], [], [[0.5, 1.0]], inputs=["x", "r"], outputs="y", name="c")
    with pytest.raises(AlgebraicLoopError, match="algebraic loop"):
        interconnect([c, b], ["r"], ["y"])
    with pytest.raises(RuntimeError, match="algebraic loop"):
        ct.interconnect([c.to_control(), b.to_control()], inplist=["r"], outlist=["y"])


@SETTINGS
@given(seeds, st.integers(0, 5), st.integers(0, 3), st.sampled_from([-1, 1]))
def test_feedback_is_python_controls(seed, n1, n2, sign):
    """Each way round and with a static gain on either side: python-control's numbers."""
    g, h = _random(seed, n1), _random(seed + 1, n2)
    for a, b in ((g, h), (g, 1.0), (1.0, g), (g, 2.5)):
        want = (ct.ss([], [], [], [[a]]) if isinstance(a, float) else a).feedback(b, sign=sign)
        _same(feedback(a if isinstance(a, float) else as_system(a), b if isinstance(b, float) else as_system(b),
                       sign), want)


def test_feedback_refuses_a_loop_without_solution():
    with pytest.raises(ValueError, match="singular"):
        feedback(ss([], [], [], [[1.0]]), 1.0, sign=1)  # y = u + y


def _ema_blocks(ema):
    from servo_toolkit.loop.closed_loop import DELAY_SAMPLES
    from servo_toolkit.plant.current_loop import current_controller, sample_delay
    from servo_toolkit.plant.linear import plant
    scene, controller = ema
    g = plant(scene, None, inductance=True)
    cur = current_controller(controller.current_kp, controller.current_ki, scene.motor)
    dly = sample_delay(controller.sample_time, DELAY_SAMPLES)
    return scene, controller, g, cur, dly


def test_the_toolkits_closed_and_open_loop_are_python_controls(ema):
    from servo_toolkit.loop.closed_loop import linear_closed_loop, open_loop_of
    scene, controller, g, cur, dly = _ema_blocks(ema)
    names = ["theta", "i", "omega_m", "u", "omega"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = linear_closed_loop(scene, controller)
        want_open = open_loop_of(g, controller, scene.motor)
    got = interconnect([as_system(b) for b in (g, cur, dly, controller.motion)], ["theta_ref", "tau_ext"], names,
                       inputs=["theta_ref", "tau_ext"], outputs=names, name="closed_loop")
    _same(got, want)
    assert got.states == tuple(want.state_labels)
    m = controller.motion
    cut = ss(m.A, m.B, m.C, m.D, inputs=["theta_ref", "theta_meas", "omega_m"], outputs=["i_ref"], name="motion_cut")
    o = interconnect([as_system(g), as_system(cur), as_system(dly), cut], ["theta_meas"], ["theta"], check_unused=False)
    _same(ss(o.A, -o.B, o.C, -o.D), want_open)
    # the loop's figures from these blocks are python-control's, number for number
    loop = as_system(want_open)
    for a, b in zip(stability_margins(loop, returnall=True), ct.stability_margins(want_open, returnall=True)):
        np.testing.assert_array_equal(a, b)
    assert bandwidth(got["theta", "theta_ref"]) == ct.bandwidth(want["theta", "theta_ref"])
    # and they are a loop's: the closed loop is stable, the margins positive
    assert np.all(got.poles().real < 0)
    gm, pm, *_ = stability_margins(loop)
    assert gm > 1 and pm > 0


@SETTINGS
@given(seeds, st.integers(1, 6), st.booleans(), st.booleans())
def test_stability_margins_are_python_controls(seed, n, stable, returnall):
    sys_ = _random(seed, n, stable=stable)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = ct.stability_margins(sys_, returnall=returnall)
        got = stability_margins(as_system(sys_), returnall=returnall)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)


def test_stability_margins_of_a_textbook_loop():
    # L = 4 / (s + 1)^3: phase -180 deg at w = sqrt(3), |L| = 4 / 8 there -> gm = 2
    gm, pm, sm, wpc, wgc, wms = stability_margins(tf2ss([4.0], [1.0, 3.0, 3.0, 1.0]))
    assert gm == pytest.approx(2.0, rel=1e-12) and wpc == pytest.approx(np.sqrt(3.0), rel=1e-12)
    wc = np.sqrt(4.0 ** (2 / 3) - 1.0)  # |L| = 1
    assert wgc == pytest.approx(wc, rel=1e-12)
    assert pm == pytest.approx(180.0 - 3 * np.degrees(np.arctan(wc)), rel=1e-12)


def test_stability_margins_raise_where_python_control_does_on_overflow():
    big = ct.ss(np.diag([-1e160, -2e160, -3e160]), np.ones((3, 1)), np.ones((1, 3)), [[0.0]])
    kinds = []
    for f, s in ((ct.stability_margins, big), (stability_margins, as_system(big))):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                f(s, returnall=True)
            kinds.append(None)
        except (np.linalg.LinAlgError, ValueError) as e:
            kinds.append(type(e))
    assert kinds[0] is not None and kinds[0] is kinds[1]


@SETTINGS
@given(seeds, st.integers(1, 6), st.booleans())
def test_bandwidth_is_python_controls(seed, n, stable):
    sys_ = _random(seed, n, stable=stable)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = ct.bandwidth(sys_)
        got = bandwidth(as_system(sys_))
    np.testing.assert_array_equal(got, want)


def test_bandwidth_of_a_first_order_lag_and_degenerate_cases():
    # 10 / (s + 10) is 3 dB down where (w / 10)^2 = 10^0.3 - 1
    assert bandwidth(tf2ss([10.0], [1.0, 10.0])) == pytest.approx(10.0 * np.sqrt(10 ** 0.3 - 1), rel=1e-9)
    assert np.isnan(bandwidth(tf2ss([1.0], [1.0, 0.0])))  # integrator: infinite DC gain
    assert bandwidth(tf2ss([1.0, 0.0], [1.0, 1.0])) == np.inf  # never drops below its (zero) DC gain
    with pytest.raises(ValueError):
        bandwidth(tf2ss([1.0], [1.0, 1.0]), dbdrop=3)
    with pytest.raises(TypeError):
        bandwidth(as_system(_random(0, 2, 2, 1)))


@SETTINGS
@given(seeds, st.integers(1, 5), st.integers(1, 3), st.integers(1, 3))
def test_state_space_matches_python_control(seed, n, m, p):
    sys_ = ct.ss(*(getattr(_random(seed, n, m, p), k) for k in "ABCD"), name="blk",
                 inputs=[f"u{k}" for k in range(m)], outputs=[f"y{k}" for k in range(p)])
    ours = as_system(sys_)
    np.testing.assert_array_equal(np.sort_complex(ours.poles()), np.sort_complex(sys_.poles()))
    if m == p:
        np.testing.assert_allclose(np.sort_complex(ours.zeros()), np.sort_complex(sys_.zeros()), rtol=1e-9, atol=1e-9)
    s = 1j * np.logspace(-2, 2, 7)
    np.testing.assert_allclose(ours(s), sys_(s), rtol=1e-12, atol=1e-14)
    sub, sub_ct = ours["y0", ["u0"]], sys_["y0", ["u0"]]
    _same(sub, sub_ct)
    assert sub.inputs == ("u0",) and sub.outputs == ("y0",)
    back = ours.to_control()
    _same(as_system(back), sys_)
    assert back.input_labels == sys_.input_labels and back.state_labels == sys_.state_labels and back.name == "blk"


def test_lti_imports_no_python_control_matplotlib_or_signal():
    code = """
import sys, numpy as np
from servo_toolkit.lti.system import ss
from servo_toolkit.lti.convert import tf2ss, ss2tf, pade, sample_tustin
from servo_toolkit.lti.connect import interconnect
from servo_toolkit.lti.analysis import stability_margins, bandwidth
g = tf2ss(*pade(0.01, 2), inputs="u", outputs="y")
k = ss([[0.0]], [[1.0]], [[2.0]], [[1.0]], inputs="e", outputs="u")
loop = interconnect([g, k], ["e"], ["y"])
ss2tf(loop); stability_margins(loop); stability_margins(loop, returnall=True); bandwidth(g); sample_tustin(loop, 1e-3)
loop.poles(); loop.zeros(); loop(1j)
bad = sorted(m for m in sys.modules if m.split('.')[0] in ('control', 'matplotlib') or m.startswith('scipy.signal'))
print(','.join(bad))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
