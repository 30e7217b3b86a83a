"""C99 of the current clamp's back-calculation (:mod:`.antiwindup`) in the exported motion
step: the header's lines on the clamp and the gains with their units, and the statements that
move the integrator's states by the clamp's excess (floating point with the gains of
:mod:`.antiwindup`; fixed point in the integrator section's own arithmetic, :mod:`.quantize`)."""

from __future__ import annotations

from .c_command import _f


def _state_name(blocks, k: int, j: int) -> str:
    """The C lvalue of state j of section k (signal order)."""
    return f"st->position[{k}][{j}]" if k < len(blocks.position) else f"st->speed[{j}]"


def back_calculation_comment(blocks, quantized) -> str:
    """The header's lines on the clamp and its back-calculation, with the gains and units."""
    limit = (quantized.blocks if quantized is not None else blocks).current_limit
    lines = [f"i_ref = the controller's output plus i_ff, clamped at +-{limit:.9g} A (SERVO_CURRENT_LIMIT_A"
             + (f", {quantized.current_limit_counts} counts" if quantized is not None else "") + ")."]
    bc = (quantized.blocks if quantized is not None else blocks).back_calculation()
    if bc is None:
        lines.append("No integrator: the clamp needs no anti-windup.")
        return "\n".join(" * " + line for line in lines)
    lines += ["Anti-windup, the simulation's back-calculation: when the clamp cuts i_ref, its excess",
              "e = clamped - unclamped i_ref (A) moves the integrator, so that the next output starts at",
              f"the limit (integrator: {bc.integrator}; gains in the section's output unit per A):"]
    sections = blocks.sections()
    lines += [f"  {sections[k].name} state s{j} += {g:.9g} {unit} * e" for k, j, g, unit in bc.gains]
    if quantized is not None:
        lines += ["In fixed point e is the excess of the rounded i_ref in the states' 2^-SERVO_GUARD counts, and",
                  "s1's gain -a2 is computed as the section's recursion computes it, d1 e - d2 e - e (its stored",
                  "d1, d2), so that the states move along the integer recursion's own integrator direction."]
    return "\n".join(" * " + line for line in lines)


def back_calculation_source(blocks, quantized) -> str:
    """The statements that move the integrator by the clamp's excess (empty without one)."""
    if quantized is None:
        bc = blocks.back_calculation()
        if bc is None:
            return ""
        moves = [f"{_state_name(blocks, k, j)} += {_f(g)} * excess;  /* {unit} */" for k, j, g, unit in bc.gains]
        kind = "double"
    else:
        k = quantized.integrator
        if k is None:
            return ""
        sec = f"SERVO_POSITION[{k}]" if k < len(blocks.position) else "SERVO_SPEED_PI"
        moves = ["int64_t e = servo_shift(excess, -SERVO_GUARD);  /* in the states' 2^-SERVO_GUARD counts */",
                 f"{_state_name(blocks, k, 0)} += e;"]
        if any(j == 1 for _, j, _, _ in quantized.blocks.back_calculation().gains):  # -a2 != 0
            moves.append(f"{_state_name(blocks, k, 1)} += servo_shift((int64_t){sec}.a[0] * e, {sec}.fa[0])\n"
                         f"            - servo_shift((int64_t){sec}.a[1] * e, {sec}.fa[1]) - e;  /* -a2 e */")
        kind = "int64_t"
    body = "\n        ".join(moves)
    return f"""
    if (i_ref != y) {{
        /* back-calculation: the integrator takes the clamp's excess */
        {kind} excess = i_ref - y;
        {body}
    }}"""


__all__ = ["back_calculation_comment", "back_calculation_source"]
