"""The register-held RK4 loop takes the same steps as the array form of the same RK4."""

import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.integrators import NCARRY, _paper, _rk4, scratch
from servo_toolkit.sim.reference import fill, initial_state


@pytest.mark.parametrize("mode", ["sampled", "continuous"])
def test_scalar_loop_matches_array_loop(mode):
    scene = load_scene()
    controller, _ = controller_for(scene)
    model = build_model(scene, controller, ModelOptions(controller_mode=mode))
    P = fill(model, Reference.sine(math.radians(2.0), 8.0))
    x0 = initial_state(model, P)
    dt, n = 2e-5, 5000
    sub = int(round(model.sample_time / dt)) if mode == "sampled" else 0
    runs = []
    fig, snap = np.zeros(lo.NFIG), np.zeros((lo.NSNAP, model.nx + 2))
    for loop, extra, tail in ((_rk4, (), (fig, snap)), (_paper, (False,), ())):
        x = x0.copy()
        out = (np.empty(60), np.empty((60, model.nx)), np.empty((60, lo.NAUX)))
        work = scratch(model.nx, P.size) if loop is _rk4 else ()
        status = loop(x, P, model.T, 0.0, dt, 0, n, n, sub, 0.0, *extra, 100, *out, *tail, np.zeros(NCARRY), *work)
        runs.append((x, status, out))
    (xa, sa, oa), (xb, sb, ob) = runs
    assert sa[:3] == sb[:3] == (lo.OK, n, 51)
    assert np.array_equal(oa[0][:51], ob[0][:51])
    xa_rec, xb_rec = oa[1][:51], ob[1][:51]
    scale = np.maximum(np.max(np.abs(xb_rec), axis=0), 1e-300)
    assert np.max(np.abs(xa_rec - xb_rec) / scale) < 1e-10  # rounding only (fast-math order)
    assert np.max(np.abs(oa[2][:51] - ob[2][:51])) < 1e-10 * np.max(np.abs(ob[2][:51]))
    assert sa[3] == pytest.approx(sb[3], rel=1e-12)
    assert np.allclose(xa, xb, rtol=1e-10, atol=1e-14)
    assert abs(xa[2] - x0[2]) > 1e-4  # it moved
