"""A stage's friction lumped onto the two sides of the drivetrain's model.

Friction given at a stage's output (:class:`~servo_toolkit.components.stage_friction.StageFriction`)
acts on the chain's node that carries the stage's output member. The compiled model keeps
friction with its stick law at two places, the motor side and the load, so a stage's friction
goes where its node goes in the two-mass reduction (the rule of the inertia lumping,
:meth:`~servo_toolkit.drivetrain.chain.Chain.node_split`): on a node up to the split's last
motor-side node it joins the motor's friction, reflected to the motor shaft; beyond it, the
load's, reflected to the output; a rigid chain puts it on the motor side (where the load's
friction is summed too). Reflection by the ratio at q0: a level F at the stage's output
coordinate u_k is F u_k' / N at the motor shaft and F u_k' at the output, a viscous
coefficient B is B (u_k' / N)^2 and B u_k'^2, a Stribeck speed v is v N / u_k' and
v / u_k' (u_k' = du_k/dq, N = d(motor angle)/dq, both at q0). The levels add up; the
Stribeck speed of a sum is exact when the parts that drop share it (at the motor: the same
speed once reflected), else the drops' weighted mean (said in the notes). The losses of the
stages between the motor and the node do not scale the lumped friction.

The full chain keeps its intermediate nodes with inertia: a stage whose output node is one
of them keeps its friction there (:func:`node_friction`, reflected to the node's coordinate
by u_k' as the load's is); only a stage whose node is condensed (no inertia), the motor's or
the load's is lumped as above.
"""

from __future__ import annotations

from dataclasses import replace


def stage_output_slope(drive, k: int, q0: float) -> float:
    """du_k/dq at q0: stage k's output coordinate (the input of the stage after it; the
    output q for the last) per output unit. Only the backward stages before a cam."""
    sides, _ = drive.output_sides([q0])
    return float(sides[k].d1[0])


def stage_nodes(chain) -> list[int]:
    """The chain node carrying each stage's output members (its springs come before them)."""
    return [sum(1 for s in chain.springs if s.stage <= k) for k in range(len(chain.drivetrain.stages))]


def _combine(parts):
    """(Tc, Ts, v_st, B) of a sum of frictions, and whether the Stribeck speed is exact."""
    tc = sum(p[0] for p in parts)
    ts = sum(p[1] for p in parts)
    b = sum(p[3] for p in parts)
    drops = [(p[1] - p[0], p[2]) for p in parts if p[1] > p[0]]
    if not drops:
        return tc, ts, 0.0, b, True
    speeds = [v for _, v in drops]
    exact = max(speeds) - min(speeds) <= 1e-9 * max(max(speeds), 1e-300)
    vs = speeds[0] if exact else sum(d * v for d, v in drops) / sum(d for d, _ in drops)
    return tc, ts, vs, b, exact


def node_friction(scene, q0: float, nodes) -> dict:
    """The friction of the stages whose output node is one of ``nodes`` (the full chain's
    intermediate nodes, chain node indices), reflected to the node's coordinate (referred to
    the output, as the full chain's node states are): a level F at the stage's output u_k is
    F u_k' there, a viscous coefficient B u_k'^2, a Stribeck speed v / u_k' (u_k' = du_k/dq
    at q0, the factor by which the chain reflects the stage's output members' inertia,
    squared). Several stages on one node add up as :func:`lumped_friction`'s do.

    Returns
    -------
    dict
        Chain node -> ``(Tc, Ts, v_st, B, exact, stages)``: the levels, the Stribeck speed
        (0: none), the viscous coefficient, whether the Stribeck speed is exact (else the
        drops' weighted mean) and the scene keys of the stages.
    """
    frictions = scene.stage_friction
    if not frictions:
        return {}
    drive = scene.drivetrain
    at = stage_nodes(drive.chain)
    parts, keys = {}, {}
    for k, fr in enumerate(frictions):
        if fr is None or at[k] not in nodes:
            continue
        u = abs(stage_output_slope(drive, k, q0))
        parts.setdefault(at[k], []).append((fr.coulomb_friction * u, fr.breakaway * u, fr.stribeck_speed / u,
                                            fr.viscous_friction * u * u))
        keys.setdefault(at[k], []).append(f"drivetrain[{k}]")
    return {node: _combine(p) + (tuple(keys[node]),) for node, p in parts.items()}


def lumped_friction(scene, q0: float, rigid: bool, notes: list, own=()):
    """The scene's motor and load with every stage's friction lumped onto them.

    Parameters
    ----------
    scene : Scene
    q0 : float
        Operating point of the reflection.
    rigid : bool
        The model is a rigid chain (everything on the motor side).
    notes : list of str
        Receives one line per side that gets a stage's friction.
    own : collection of int
        Chain nodes that carry their stages' friction themselves (the full chain's
        intermediate nodes, :func:`node_friction`): not lumped.

    Returns
    -------
    motor : DCMotor
    load : Load
        With the lumped Coulomb, static, Stribeck and viscous values (the scene's own when no
        stage gives friction).
    """
    motor, load = scene.motor, scene.load
    frictions = scene.stage_friction
    if not frictions or all(f is None for f in frictions):
        return motor, load
    drive = scene.drivetrain
    chain = drive.chain
    n = abs(float(drive.ratio([q0])[0][0]))
    last = -1 if rigid else int(chain.node_split([q0]).last_motor_node[0])
    nodes = stage_nodes(chain)
    m_parts = [(motor.coulomb_friction, motor.breakaway_torque, motor.stribeck_speed, motor.viscous_friction)]
    l_parts = [(load.coulomb_friction, load.breakaway, load.stribeck_speed, load.damping)]
    m_from, l_from = [], []
    for k, fr in enumerate(frictions):
        if fr is None or nodes[k] in own:
            continue
        u = abs(stage_output_slope(drive, k, q0))
        if rigid or nodes[k] <= last:
            g = u / n
            m_parts.append((fr.coulomb_friction * g, fr.breakaway * g, fr.stribeck_speed / g, fr.viscous_friction * g * g))
            m_from.append(f"drivetrain[{k}]")
        else:
            l_parts.append((fr.coulomb_friction * u, fr.breakaway * u, fr.stribeck_speed / u, fr.viscous_friction * u * u))
            l_from.append(f"drivetrain[{k}]")
    if m_from:
        tc, ts, vs, b, exact = _combine(m_parts)
        motor = replace(motor, coulomb_friction=tc, static_friction=ts, stribeck_speed=vs, viscous_friction=b)
        notes.append(f"friction of {', '.join(m_from)} reflected to the motor shaft at q0: Coulomb {tc:.4g} N*m, "
                     f"breakaway {ts:.4g} N*m, viscous {b:.4g} N*m*s/rad with the motor's own"
                     + ("" if exact else f" (Stribeck speeds differ: their drops' weighted mean {vs:.4g} rad/s)"))
    if l_from:
        tc, ts, vs, b, exact = _combine(l_parts)
        load = replace(load, coulomb_friction=tc, static_friction=ts, stribeck_speed=vs, damping=b)
        unit = "N" if drive.output_unit == "m" else "N*m"
        notes.append(f"friction of {', '.join(l_from)} reflected to the output at q0 and lumped with the load's "
                     f"(the load side of the two-mass split): Coulomb {tc:.4g} {unit}, breakaway {ts:.4g} {unit}"
                     + ("" if exact else " (Stribeck speeds differ: their drops' weighted mean)"))
    return motor, load


__all__ = ["lumped_friction", "node_friction", "stage_nodes", "stage_output_slope"]
