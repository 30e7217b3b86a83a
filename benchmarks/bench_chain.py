"""Benchmark: a three-compliance chain (gear mesh, ball-screw axial, mounting) moving a mass.

Prints the chain's nodes and modes, the two-mass reduction's resonance against the chain's
lowest mode, the time to build the chain and the n-mass plant, and the compiled model's RK4
rate (open loop, 1 s at 1 us) of the full chain (every compliance, every mode) against its
two-mass reduction, with the step RK4 chooses for each. Every timing is the best of REPEATS
runs.

Run: python3 benchmarks/bench_chain.py
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import control as ct

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from servo_toolkit.components.ball_screw import BallScrew  # noqa: E402
from servo_toolkit.components.compliance import Compliance, Load  # noqa: E402
from servo_toolkit.components.gear import GearTrain  # noqa: E402
from servo_toolkit.components.motor import DCMotor  # noqa: E402
from servo_toolkit.plant.chain_plant import chain_plant  # noqa: E402
from servo_toolkit.scene.loader import Scene  # noqa: E402
from servo_toolkit.sim import ModelOptions, Reference, build_model, run  # noqa: E402

REPEATS = 5


def three_compliance_scene() -> Scene:
    """Motor -> gear 3:1 with a mesh spring -> 5 mm ball screw with its axial spring -> a
    mounting spring -> 30 kg, stiffnesses chosen so that the three compliances are comparable."""
    motor = DCMotor(resistance=0.5, inductance=5e-4, torque_constant=0.2, back_emf_constant=0.2,
                    rotor_inertia=2e-4, viscous_friction=1e-4, coulomb_friction=0.0, voltage_limit=270.0,
                    current_limit=40.0)
    gear = GearTrain("gear", ratio=3.0, inertias=(1e-5, 4e-5), efficiency=0.97, torsional_stiffness=60.0)
    screw = BallScrew("ball screw", lead=0.005, screw_inertia=1.3e-5, nut_mass=0.6, efficiency=0.9,
                      axial_stiffness=1.5e8)
    mount = Compliance("mounting", 1.0e8)
    return Scene("three_compliance_chain", motor=motor, stages=(gear, screw, mount), load=Load(inertia=30.0))


def best_of(call):
    walls, out = [], None
    for _ in range(REPEATS):
        t = time.perf_counter()
        out = call()
        walls.append(time.perf_counter() - t)
    return out, min(walls)


def main():
    scene = three_compliance_scene()
    chain, t_chain = best_of(lambda: replace(scene.drivetrain).chain)
    print("\n".join(chain.describe()))
    modes = chain.eigenfrequencies(0.0) / (2 * math.pi)
    print(f"modes (Hz): {', '.join(f'{f:.1f}' for f in modes)}")
    for name, split in (("two-mass reduction", chain.two_mass([0.0])), ("node split", chain.node_split([0.0]))):
        f2 = math.sqrt(split.stiffness[0] * (1 / split.motor_side[0] + 1 / split.load_side[0])) / (2 * math.pi)
        print(f"{name} (most compliant spring {split.spring[0]!r}): {f2:.1f} Hz, "
              f"{100 * (f2 / modes[0] - 1):+.2f} % against the lowest mode")
    g, t_plant = best_of(lambda: chain_plant(scene, 0.0))
    print(f"chain: {t_chain * 1e3:.2f} ms, n-mass plant ({g.nstates} states): {t_plant * 1e3:.2f} ms")
    ref = Reference.voltage(24.0)
    rates = {}
    for chain_kind in ("two_mass", "full"):
        model = build_model(scene, None, ModelOptions(chain=chain_kind))
        run(model, ref, 0.01)  # compile / load the kernels
        res, wall = best_of(lambda: run(model, ref, 1.0, dt=1e-6, output_dt=1e-3))
        auto = run(model, ref, 0.05, method="auto")
        rates[chain_kind] = 1.0 / wall
        print(f"compiled {chain_kind} model ({model.nx} states), open loop 24 V, 1 s at dt = 1 us (1e6 RK4 steps): "
              f"{wall * 1e3:.1f} ms, {1e6 / wall / 1e6:.2f} M steps/s (wall, stability checks included); "
              f"RK4 chooses dt = {auto.dt_s:.3g} s")
    print(f"full chain step cost / two-mass step cost: {rates['two_mass'] / rates['full']:.2f}")
    print(f"poles of the n-mass plant above 1 Hz: {sorted({round(abs(p) / (2 * math.pi), 1) for p in ct.poles(g) if abs(p.imag) > 1})}")


if __name__ == "__main__":
    main()
