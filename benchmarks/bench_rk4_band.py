"""Benchmark: where the compiled RK4's error on the reference EMA's sine comes from, and what
the smooth signs' band substeps (``servo_toolkit/_physics/integrate.h``, smooth_substeps) do
to it.

The run of ``bench_simulate.py`` (reference EMA, 8 Hz 2 deg sine, continuous controller, 1 s)
and variants of it, each against LSODA at rtol = atol = 1e-12 on the same compiled
right-hand side: max |q - q_ref| over the amplitude on a 1 ms grid, at RK4 steps of 0.2, 0.1
and 0.05 ms. The variants: without the motor's Coulomb torque, without the drivetrain's loss
(every efficiency 1), without both; stroke tables of 257 and 16385 points instead of 1025;
the amplitude a hundredth; the frequency halved. The band's substeps run in every RK4 row
(a step through the band of the smooth signs): the lossless rows, which have fewer or no
smooth signs, show what the run's error is without the switch. The first row also gives the
exponential integrator ETDRK4 (Cox and Matthews 2002) at 0.1 ms on the Jacobian of the moving
loop, which takes every linear mode exactly and the switch as RK4 without substeps did.

Run: python3 benchmarks/bench_rk4_band.py
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from servo_toolkit import load_scene  # noqa: E402
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for, run  # noqa: E402
from servo_toolkit.sim.ivp import make_fun  # noqa: E402
from servo_toolkit.sim.reference import fill, initial_state  # noqa: E402

AMP, FREQ, DURATION = math.radians(2.0), 8.0, 1.0
STEPS = (2e-4, 1e-4, 5e-5)


def _lossless(scene):
    return replace(scene, stages=tuple(replace(s, efficiency=1.0) if hasattr(s, "efficiency") else s
                                       for s in scene.stages))


def _truth(model, ref):
    P = fill(model, ref)
    x0 = initial_state(model, P)
    fun = make_fun(model, P, [0.0])
    t = np.linspace(0.0, DURATION, int(round(DURATION / 1e-3)) + 1)
    return fun, x0, t, solve_ivp(fun, (0.0, DURATION), x0, method="LSODA", t_eval=t, rtol=1e-12, atol=1e-12).y[2]


def _etdrk4(fun, x0, t_out, dt):
    """ETDRK4 with L the Jacobian at a moving state (the Coulomb torque's and the loss's
    zero-speed slope left out), N = f - L x explicit; the output angle on t_out."""
    n = len(x0)
    x1 = x0.copy()
    x1[1] = 0.3
    L = np.zeros((n, n))
    for j in range(n):
        h = 1e-7 * max(1.0, abs(x1[j]))
        xp, xm = x1.copy(), x1.copy()
        xp[j] += h
        xm[j] -= h
        L[:, j] = (fun(0.0, xp) - fun(0.0, xm)) / (2 * h)

    def phis(Z):
        m = Z.shape[0]
        B = np.zeros((4 * m, 4 * m))
        B[:m, :m] = Z
        for i in range(3):
            B[i * m:(i + 1) * m, (i + 1) * m:(i + 2) * m] = np.eye(m)
        E = expm(B)
        return [E[:m, :m]] + [E[:m, i * m:(i + 1) * m] for i in range(1, 4)]

    E, p1, p2, p3 = phis(dt * L)
    E2, q1 = phis(dt * L / 2)[:2]
    Q = dt / 2 * q1
    f1, f2, f3 = dt * (p1 - 3 * p2 + 4 * p3), dt * (2 * p2 - 4 * p3), dt * (-p2 + 4 * p3)

    def N(t, u):
        return fun(t, u) - L @ u

    every = int(round((t_out[1] - t_out[0]) / dt))
    u, out = x0.copy(), [x0[2]]
    for i in range(int(round(DURATION / dt))):
        t = i * dt
        Nu = N(t, u)
        a = E2 @ u + Q @ Nu
        Na = N(t + dt / 2, a)
        b = E2 @ u + Q @ Na
        Nb = N(t + dt / 2, b)
        c = E2 @ a + Q @ (2 * Nb - Nu)
        u = E @ u + f1 @ Nu + f2 @ (Na + Nb) + f3 @ N(t + dt, c)
        if (i + 1) % every == 0:
            out.append(u[2])
    return np.array(out)


def case(name, scene, controller, amp=AMP, freq=FREQ, points=1025, etd=False):
    model = build_model(scene, controller, ModelOptions(controller_mode="continuous", table_points=points))
    ref = Reference.sine(amp, freq)
    fun, x0, t, truth = _truth(model, ref)
    errs = [np.max(np.abs(run(model, ref, DURATION, "rk4", dt, output_dt=1e-3).output_angle - truth)) / amp
            for dt in STEPS]
    row = f"{name:44s}" + "".join(f"{e:12.3g}" for e in errs)
    if etd:
        row += f"   ETDRK4 at 0.1 ms: {np.max(np.abs(_etdrk4(fun, x0, t, 1e-4) - truth)) / amp:.3g}"
    print(row, flush=True)


def main():
    scene = load_scene()
    controller, _ = controller_for(scene)
    frictionless = replace(scene, motor=replace(scene.motor, coulomb_friction=0.0))
    print("RK4 error / amplitude against LSODA at 1e-12, reference EMA, continuous controller, 1 s")
    print(f"{'case':44s}" + "".join(f"{f'dt={dt * 1e3:g} ms':>12s}" for dt in STEPS))
    case("8 Hz, 2 deg (bench_simulate's run)", scene, controller, etd=True)
    case("without the motor's Coulomb torque", frictionless, controller)
    case("without the drivetrain's loss", _lossless(scene), controller)
    case("without both (no smooth sign)", _lossless(frictionless), controller)
    case("stroke tables of 257 points", scene, controller, points=257)
    case("stroke tables of 16385 points", scene, controller, points=16385)
    case("amplitude 0.02 deg", scene, controller, amp=AMP / 100)
    case("4 Hz", scene, controller, freq=4.0)


if __name__ == "__main__":
    main()
