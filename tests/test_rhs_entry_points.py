"""The compiled right-hand side's two entry points: :func:`~servo_toolkit.sim.kernel.rhs_phys`
(the physical states' rates at the scalars) is :func:`~servo_toolkit.sim.kernel.rhs` to the
bit at the states tests/test_rhs_transcription.py draws, both read their arrays only (they
accept read-only ones), and both refuse arrays too small for the model."""

from __future__ import annotations

import numpy as np
import pytest

from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import rhs, rhs_phys
from servo_toolkit.sim.reference import initial_state

from .test_rhs_transcription import CASES, Draws, _draw_example, built  # noqa: F401 - built: the cases' fixture


def _rates(t, x, P, T, iref):
    dx, aux = np.full(x.size, np.nan), np.full(lo.NAUX, np.nan)
    rhs(t, x, P, T, iref, dx, aux)
    return np.concatenate([dx, aux])


def _read_only(*arrays):
    out = [a.copy() for a in arrays]
    for a in out:
        a.flags.writeable = False
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_rhs_phys_is_rhs(built, name):
    """rhs_phys's ten results are rhs's dx[0:6] and its current, voltage, current reference and
    motor torque, its dx the same intermediate rates (the held states' left at 0), on read-only
    parameters, tables and state, which neither call changes."""
    model, params, _ = built(name)
    draw = Draws(rng=np.random.default_rng(2))
    for _ in range(20):
        P, x, t, iref = _draw_example(draw, name, model, params)
        P_ro, x_ro, T_ro = _read_only(P, x, model.T)
        want = _rates(t, x_ro, P_ro, T_ro, iref)
        dx = np.zeros(x.size)
        out = rhs_phys(t, *x[:lo.NX_PHYS], P_ro, T_ro, iref, x_ro, dx)
        assert len(out) == 10
        assert np.array_equal(np.array(out[:6]), want[:6], equal_nan=True)
        assert list(out[6:]) == [want[x.size + j] for j in (lo.AUX_I, lo.AUX_V, lo.AUX_IREF, lo.AUX_TAU)]
        assert np.array_equal(dx[lo.NX_PHYS:], want[lo.NX_PHYS:x.size])
        assert np.array_equal(x_ro, x) and np.array_equal(P_ro, P) and np.array_equal(T_ro, model.T)


def test_the_array_sizes_are_checked(built):
    """A derivative or aux array shorter than the state or the aux entries, a state shorter
    than the physical states: a ValueError before anything is written."""
    model, params, _ = built("ema two-mass sampled smooth")
    x = initial_state(model, params[0])
    with pytest.raises(ValueError):
        rhs(0.0, x, params[0], model.T, 0.0, np.zeros(x.size - 1), np.zeros(lo.NAUX))
    with pytest.raises(ValueError):
        rhs(0.0, x, params[0], model.T, 0.0, np.zeros(x.size), np.zeros(lo.NAUX - 1))
    with pytest.raises(ValueError):
        rhs_phys(0.0, *x[:lo.NX_PHYS], params[0], model.T, 0.0, x[:3], np.zeros(3))
