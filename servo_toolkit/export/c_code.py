"""Portable C99 sources of the exported controller (``servo_controller.h`` / ``.c``).

No dynamic memory, no library call (not even libm): the state is a caller-owned struct,
the coefficients are ``static const`` tables. Floating point uses ``double``; the
fixed-point motion controller uses ``int16_t``/``int32_t`` coefficients, ``int32_t``
signals and ``int64_t`` states and products, with portable rounding shifts (no right shift
of a negative number, no left shift at all).
"""

from __future__ import annotations

import math

from .c_antiwindup import back_calculation_comment, back_calculation_source
from .c_command import header_part, shaper_type, source_part
from .quantize import FORMATS

HEADER_NAME = "servo_controller.h"
SOURCE_NAME = "servo_controller.c"


def _f(x: float) -> str:
    """A double literal that reads back to the same double."""
    text = repr(float(x))
    return text if any(c in text for c in ".eEn") else text + ".0"


def _units_comment(blocks, quantized) -> str:
    fixed = quantized is not None
    unit = blocks.output_unit
    what = "angle" if unit == "rad" else "position"
    lines = ["Signals (engineering units):",
             f"  theta_ref, theta   output {what} command and measurement, {unit}"
             + (f" (fixed point: counts of SERVO_THETA_LSB_{unit.upper()})" if fixed else ""),
             "  omega_m            motor speed, rad/s" + (" (counts of SERVO_OMEGA_LSB_RAD_S)" if fixed else ""),
             "  i_ref              current command, A" + (" (counts of SERVO_CURRENT_LSB_A)" if fixed else "")
             + f", clamped at +-{blocks.current_limit:g} A",
             "  i_ff               feedforward current added before the clamp, A"
             + (" (counts of SERVO_CURRENT_LSB_A, saturated at twice the full scale)" if fixed else ""),
             "  i                  measured armature current, A",
             "  v                  armature voltage command, V, clamped at "
             f"+-{blocks.current.voltage_limit:g} V"]
    if fixed:
        lines += _scales_comment(blocks, quantized)
    if blocks.estimator.kind != "ideal":
        lines.append("  motor_angle        motor encoder angle (counts * 2 pi / counts per rev), rad")
        if fixed:
            lines.append("servo_speed_estimate returns rad/s (double): divide by SERVO_OMEGA_LSB_RAD_S and round")
            lines.append("to get the omega_m counts of servo_motion_step.")
    lines += ["Call servo_motion_step every SERVO_MOTION_SAMPLE_TIME_S and servo_current_step every",
              "SERVO_CURRENT_SAMPLE_TIME_S (SERVO_CURRENT_STEPS_PER_MOTION times per motion sample)."]
    return "\n".join(" * " + line for line in lines)


def _scale_defines(blocks, quantized) -> list:
    """The fixed-point signals' full scales (value of 2^SERVO_SIGNAL_BITS counts, a power of
    two: its exponent too) and LSBs, each in its unit."""
    fs = quantized.full_scale
    out = [f"#define SERVO_SIGNAL_BITS {quantized.signal_bits}",
           f"#define SERVO_SIGNAL_MAX {2**quantized.signal_bits - 1}L"]
    for name, unit, key in (("THETA", blocks.output_unit.upper(), "theta"), ("OMEGA", "RAD_S", "omega"),
                            ("CURRENT", "A", "current")):
        out += [f"#define SERVO_{name}_FULL_SCALE_{unit} {_f(fs[key])}",
                f"#define SERVO_{name}_FULL_SCALE_LOG2 {int(round(math.log2(fs[key])))}",
                f"#define SERVO_{name}_LSB_{unit} {_f(quantized.lsb[key])}"]
    return out


def _scales_comment(blocks, quantized) -> list:
    unit = blocks.output_unit
    fs = quantized.full_scale
    rows = (("theta_ref, theta", "SERVO_THETA", unit, fs["theta"], "from the stroke "
             f"{blocks.stroke[0]:.6g} .. {blocks.stroke[1]:.6g} {unit}"),
            ("omega_m", "SERVO_OMEGA", "rad/s", fs["omega"], "from the no-load motor speed"),
            ("i_ref", "SERVO_CURRENT", "A", fs["current"], f"above the {blocks.current_limit:g} A current limit"))
    lines = [f"Fixed point: a signal is counts of full scale / 2^SERVO_SIGNAL_BITS ({quantized.signal_bits}); each "
             "full scale is a",
             "power of two (its _FULL_SCALE_LOG2), so value = counts * 2^(LOG2 - SERVO_SIGNAL_BITS) is a shift:"]
    lines += [f"  {name:<18} full scale {full:.6g} {u} = 2^{int(round(math.log2(full)))} {u} "
              f"({define}_FULL_SCALE_*), {why}" for name, define, u, full, why in rows]
    return lines


def header(blocks, quantized=None, scene_name: str = "", version: str = "", command=None) -> str:
    """Text of ``servo_controller.h`` (with the command helpers of ``command``, a
    :class:`.command.CommandExport`, when it has any)."""
    fixed = quantized is not None
    sig = "int32_t" if fixed else "double"
    st = "int64_t" if fixed else "double"
    npos = len(blocks.position)
    steps = max(1, round(blocks.sample_time / blocks.current.sample_time))
    defs = [f"#define SERVO_MOTION_SAMPLE_TIME_S {_f(blocks.sample_time)}",
            f"#define SERVO_CURRENT_SAMPLE_TIME_S {_f(blocks.current.sample_time)}",
            f"#define SERVO_CURRENT_STEPS_PER_MOTION {steps}",
            f"#define SERVO_N_POSITION_SECTIONS {npos}",
            f"#define SERVO_HAS_SPEED_LOOP {0 if blocks.speed is None else 1}",
            f"#define SERVO_FIXED_POINT {1 if fixed else 0}",
            f"#define SERVO_CURRENT_LIMIT_A {_f(blocks.current_limit)}",
            f"#define SERVO_VOLTAGE_LIMIT_V {_f(blocks.current.voltage_limit)}",
            f"#define SERVO_HAS_BACK_CALCULATION {0 if blocks.back_calculation() is None else 1}"]
    if fixed:
        defs += _scale_defines(blocks, quantized)
    est = blocks.estimator.kind
    proto = ["void servo_init(servo_state_t *st, double motor_angle_rad);",
             f"{sig} servo_motion_step(servo_state_t *st, {sig} theta_ref, {sig} theta, {sig} omega_m);",
             f"{sig} servo_motion_step_ff(servo_state_t *st, {sig} theta_ref, {sig} theta, {sig} omega_m, "
             f"{sig} i_ff);",
             "double servo_current_step(servo_state_t *st, double i_ref, double i, double omega_m);"]
    if est != "ideal":
        proto.insert(1, "double servo_speed_estimate(servo_state_t *st, double motor_angle_rad);")
    cdefs, cproto = header_part(command)
    defs += cdefs
    proto += cproto
    fmt = f"fixed point {quantized.fmt} (coefficients int{quantized.word + 1}_t)" if fixed else "double precision"
    return f"""/*
 * {HEADER_NAME}: sampled servo cascade of scene "{scene_name}", {fmt}.
 * Generated by servo_toolkit {version} (servo-toolkit export); C99, no dynamic memory,
 * no library calls.
 *
 * Motion controller ({blocks.structure}): position path = {npos} biquad(s) (direct form II
 * transposed) on theta_ref - theta{"; speed PI on the motor speed error" if blocks.speed is not None else ""}.
{back_calculation_comment(blocks, quantized)}
 * servo_motion_step is servo_motion_step_ff with i_ff = 0.
 * Current loop ({blocks.current.mode}): PI with back-calculation anti-windup at the voltage limit.
 * Speed estimator: {est}.
 *
{_units_comment(blocks, quantized)}
 */
#ifndef SERVO_CONTROLLER_H
#define SERVO_CONTROLLER_H

#include <stdint.h>

{chr(10).join(defs)}

typedef struct {{
    {st} position[{npos}][2];  /* biquad states */
    {st} speed[2];           /* speed PI state */
    double current_integral;   /* current PI integral, V */
    double estimator[3];       /* speed estimator: angle rad, speed rad/s, acceleration rad/s^2 */
}} servo_state_t;
{shaper_type(command)}
/* servo_init: zero states; the speed estimator starts at motor_angle_rad, at rest. */
{chr(10).join(proto)}

#endif
"""


def _float_tables(blocks) -> str:
    rows = ",\n".join("    {" + ", ".join(_f(v) for v in (*s.b, *s.a)) + "}" + f"  /* {s.name} */"
                      for s in blocks.position)
    out = ("/* position path sections: b0, b1, b2, a1, a2 (a0 = 1) */\n"
           f"static const double SERVO_POSITION[{len(blocks.position)}][5] = {{\n{rows}\n}};\n")
    if blocks.speed is not None:
        s = blocks.speed
        out += ("/* speed PI (A per motor rad/s): b0, b1, b2, a1, a2 */\nstatic const double SERVO_SPEED_PI[5] = {"
                + ", ".join(_f(v) for v in (*s.b, *s.a)) + "};\n")
    return out


def _fixed_tables(quantized) -> str:
    ctype = f"int{quantized.word + 1}_t"

    def ints(values):
        return "{" + ", ".join(str(v) for v in values) + "}"

    def row(s):
        return "{" + ", ".join(ints(v) for v in (s.b_int, s.a_int, s.fb, s.fa)) + "}"

    out = (f"typedef struct {{ {ctype} b[3]; {ctype} a[2]; int fb[3]; int fa[2]; }} servo_sos_t;\n"
           "/* each section about z = 1 (z = 1 + w): b = n0, n1, n2 of N(1 + w) = n0 w^2 + n1 w + n2\n"
           " * (counts out per count in), a = d1, d2 of D(1 + w) = w^2 + d1 w + d2; coefficient k in\n"
           " * Q(W-f[k]).(f[k]), each in its own format. Direct form: b0 = n0, b1 = n1 - 2 n0,\n"
           " * b2 = n2 - n1 + n0, a1 = d1 - 2, a2 = d2 - d1 + 1. */\n"
           f"static const servo_sos_t SERVO_POSITION[{len(quantized.position)}] = {{\n"
           + ",\n".join(f"    {row(s)}  /* {s.name} */" for s in quantized.position) + "\n};\n")
    if quantized.speed is not None:
        out += f"static const servo_sos_t SERVO_SPEED_PI = {row(quantized.speed)};\n"
    return out


_FLOAT_CORE = """static double servo_clamp(double v, double lim)
{
    return v > lim ? lim : (v < -lim ? -lim : v);
}

static double servo_biquad(const double c[5], double s[2], double x)
{
    double y = c[0] * x + s[0];
    s[0] = c[1] * x - c[3] * y + s[1];
    s[1] = c[2] * x - c[4] * y;
    return y;
}
"""

_FIXED_CORE = """#define SERVO_GUARD {guard}
#define SERVO_STATE_MAX (SERVO_SIGNAL_MAX * ((int64_t)1 << SERVO_GUARD))

static double servo_clamp(double v, double lim)
{{
    return v > lim ? lim : (v < -lim ? -lim : v);
}}

/* v * 2^-k rounded half away from zero (k > 0), v * 2^-k exactly (k <= 0) */
static int64_t servo_shift(int64_t v, int k)
{{
    int64_t h;
    if (k <= 0) {{
        return v * ((int64_t)1 << (-k));
    }}
    h = (int64_t)1 << (k - 1);
    return v >= 0 ? (v + h) >> k : -((-v + h) >> k);
}}

static int64_t servo_sat(int64_t v, int64_t lim)
{{
    return v > lim ? lim : (v < -lim ? -lim : v);
}}

/* DF2T with states in 2^-SERVO_GUARD counts; the recursion uses the unrounded output. The
 * coefficients about z = 1 enter through the direct form's (b1 = n1 - 2 n0, ...), whose integer
 * parts (2 y, y) are added exactly */
static int32_t servo_biquad(const servo_sos_t *c, int64_t s[2], int32_t x)
{{
    int64_t p0 = servo_shift((int64_t)c->b[0] * x, c->fb[0] - SERVO_GUARD);
    int64_t p1 = servo_shift((int64_t)c->b[1] * x, c->fb[1] - SERVO_GUARD);
    int64_t p2 = servo_shift((int64_t)c->b[2] * x, c->fb[2] - SERVO_GUARD);
    int64_t y = servo_sat(p0 + s[0], SERVO_STATE_MAX);
    int64_t q1 = servo_shift((int64_t)c->a[0] * y, c->fa[0]);
    int64_t q2 = servo_shift((int64_t)c->a[1] * y, c->fa[1]);
    s[0] = p1 - 2 * p0 - q1 + 2 * y + s[1];
    s[1] = p2 - p1 + p0 - q2 + q1 - y;
    return (int32_t)servo_sat(servo_shift(y, SERVO_GUARD), SERVO_SIGNAL_MAX);
}}
"""


def _init(blocks) -> str:
    npos = len(blocks.position)
    return f"""void servo_init(servo_state_t *st, double motor_angle_rad)
{{
    int k;
    for (k = 0; k < {npos}; ++k) {{
        st->position[k][0] = 0;
        st->position[k][1] = 0;
    }}
    st->speed[0] = 0;
    st->speed[1] = 0;
    st->current_integral = 0.0;
    st->estimator[0] = motor_angle_rad;
    st->estimator[1] = 0.0;
    st->estimator[2] = 0.0;
}}
"""


def _motion(blocks, quantized) -> str:
    npos = len(blocks.position)
    if quantized is None:
        sig, first = "double", "double u = theta_ref - theta;"
        pos = "u = servo_biquad(SERVO_POSITION[k], st->position[k], u);"
        speed = "u = servo_biquad(SERVO_SPEED_PI, st->speed, u - omega_m);"
        out, zero = "double y, i_ref;", "0.0"
        clamp = "y = u + i_ff;\n    i_ref = servo_clamp(y, SERVO_CURRENT_LIMIT_A);"
        ret = "return i_ref;"
    else:
        sig, first = "int32_t", "int32_t u = (int32_t)servo_sat((int64_t)theta_ref - theta, SERVO_SIGNAL_MAX);"
        pos = "u = servo_biquad(&SERVO_POSITION[k], st->position[k], u);"
        speed = ("u = servo_biquad(&SERVO_SPEED_PI, st->speed,\n"
                 "                     (int32_t)servo_sat((int64_t)u - omega_m, SERVO_SIGNAL_MAX));")
        out, zero = "int64_t y, i_ref;", "0"
        clamp = (f"y = (int64_t)u + servo_sat(i_ff, 2 * SERVO_SIGNAL_MAX);\n"
                 f"    i_ref = servo_sat(y, {quantized.current_limit_counts});")
        ret = "return (int32_t)i_ref;"
    body = speed if blocks.speed is not None else "(void)omega_m;"
    return f"""/* i_ref from the output angle command and measurement and the motor speed, plus the
 * feedforward current i_ff, clamped at the current limit (back-calculation at the clamp) */
{sig} servo_motion_step_ff(servo_state_t *st, {sig} theta_ref, {sig} theta, {sig} omega_m, {sig} i_ff)
{{
    {first}
    {out}
    int k;
    for (k = 0; k < {npos}; ++k) {{
        {pos}
    }}
    {body}
    {clamp}{back_calculation_source(blocks, quantized)}
    {ret}
}}

{sig} servo_motion_step(servo_state_t *st, {sig} theta_ref, {sig} theta, {sig} omega_m)
{{
    return servo_motion_step_ff(st, theta_ref, theta, omega_m, {zero});
}}
"""


def _current(cur) -> str:
    if cur.mode == "ideal":
        return f"""/* no inductance: the voltage that drives i_ref through R against the back EMF */
double servo_current_step(servo_state_t *st, double i_ref, double i, double omega_m)
{{
    (void)st;
    (void)i;
    return servo_clamp({_f(cur.resistance)} * i_ref + {_f(cur.back_emf_constant)} * omega_m, SERVO_VOLTAGE_LIMIT_V);
}}
"""
    return f"""/* current PI, back-calculation anti-windup: xi += Ts (Ki e + Kaw (v - vc)) */
double servo_current_step(servo_state_t *st, double i_ref, double i, double omega_m)
{{
    double e = i_ref - i;
    double vc = {_f(cur.kp)} * e + st->current_integral;
    double v = servo_clamp(vc, SERVO_VOLTAGE_LIMIT_V);
    (void)omega_m;
    st->current_integral += {_f(cur.sample_time)} * ({_f(cur.ki)} * e + {_f(cur.kaw)} * (v - vc));
    return v;
}}
"""


def _estimator(est, sample_time: float) -> str:
    if est.kind == "ideal":
        return ""
    if est.kind == "difference":
        return f"""/* motor speed, rad/s: backward difference of the motor encoder angle */
double servo_speed_estimate(servo_state_t *st, double motor_angle_rad)
{{
    double w = (motor_angle_rad - st->estimator[0]) * {_f(1.0 / sample_time)};
    st->estimator[0] = motor_angle_rad;
    st->estimator[1] = w;
    return w;
}}
"""
    F, K = est.F, est.K
    pred = "\n".join(f"    double p{r} = {_f(F[r][0])} * st->estimator[0] + {_f(F[r][1])} * st->estimator[1]"
                     f" + {_f(F[r][2])} * st->estimator[2];" for r in range(3))
    upd = "\n".join(f"    st->estimator[{r}] = p{r} + {_f(K[r])} * innovation;" for r in range(3))
    return f"""/* motor speed, rad/s: constant-gain Kalman filter (constant acceleration) on the encoder angle */
double servo_speed_estimate(servo_state_t *st, double motor_angle_rad)
{{
{pred}
    double innovation = motor_angle_rad - p0;
{upd}
    return st->estimator[1];
}}
"""


def source(blocks, quantized=None, command=None) -> str:
    """Text of ``servo_controller.c`` (with the command helpers of ``command``)."""
    if quantized is None:
        core, tables = _FLOAT_CORE, _float_tables(blocks)
    else:
        core, tables = _FIXED_CORE.format(guard=FORMATS[quantized.fmt][2]), _fixed_tables(quantized)
    parts = [f'#include "{HEADER_NAME}"\n', tables, core, _init(blocks), _motion(blocks, quantized),
             _current(blocks.current), _estimator(blocks.estimator, blocks.sample_time), source_part(command)]
    return "\n".join(p for p in parts if p)
