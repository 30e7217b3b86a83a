"""C99 helpers of the exported command options (:mod:`.command`): gain-schedule factors, the
feedforward's current and speed reference, and the command shaper on a ring buffer of past
commands. Plain double arithmetic, no library call; in a fixed-point export the tables hold
the values rounded to the coefficient word (exactly the rounded numbers the export checked).

How they compose with the motion step, once per motion sample::

    servo_schedule(theta, &g_e, &g_w);                       /* with a schedule, else 1, 1 */
    servo_shape(&shaper, r, r_dot, r_ddot, shaped);          /* with a shaper, else r, r', r'' */
    w_ff = servo_feedforward_speed(shaped[0], shaped[1]);    /* N(r) r' */
    i_ref = servo_motion_step_ff(st, g_e * shaped[0], g_e * theta, g_w * (omega_m - w_ff),
                                 servo_feedforward_current(shaped[1], shaped[2]));

``servo_motion_step_ff`` clamps the sum at the current limit and back-calculates the
integrator by the excess, as the simulation does with a feedforward (in a fixed-point export
the feedforward current enters as counts of the current LSB).
"""

from __future__ import annotations


def _f(x: float) -> str:
    text = repr(float(x))
    return text if any(c in text for c in ".eEn") else text + ".0"


def _array(name: str, values) -> str:
    return f"static const double {name}[{len(values)}] = {{" + ", ".join(_f(v) for v in values) + "};\n"


def _interp(name: str, table: str, grid: str, n: int) -> str:
    """A static linear interpolation of ``table`` on the even ``grid`` (ends held)."""
    return f"""static double {name}(double q)
{{
    double s = (q - {grid}[0]) / ({grid}[{n - 1}] - {grid}[0]) * {n - 1}.0;
    int k;
    if (s <= 0.0) {{
        return {table}[0];
    }}
    if (s >= {n - 1}.0) {{
        return {table}[{n - 1}];
    }}
    k = (int)s;
    return {table}[k] + (s - (double)k) * ({table}[k + 1] - {table}[k]);
}}
"""


def header_part(export) -> tuple:
    """``(defines, prototypes)`` lines of the command helpers (empty without any)."""
    if export is None or export.empty:
        return [], []
    defs, proto = [], []
    if export.feedforward is not None:
        defs.append("#define SERVO_HAS_FEEDFORWARD 1")
        proto += ["double servo_feedforward_current(double r_dot, double r_ddot);",
                  "double servo_feedforward_speed(double theta_ref, double r_dot);"]
    if export.schedule is not None:
        defs.append("#define SERVO_HAS_SCHEDULE 1")
        proto.append("void servo_schedule(double theta, double *g_error, double *g_speed);")
    if export.shaper is not None:
        from .command import ring_length
        defs += ["#define SERVO_HAS_SHAPER 1", f"#define SERVO_SHAPER_LENGTH {ring_length(export)}"]
        proto += ["void servo_shaper_init(servo_shaper_t *sh, double r);",
                  "void servo_shape(servo_shaper_t *sh, double r, double r_dot, double r_ddot, double out[3]);"]
    return defs, proto


def shaper_type(export) -> str:
    """The shaper's state type (empty without a shaper)."""
    if export is None or export.shaper is None:
        return ""
    return """typedef struct {
    double history[SERVO_SHAPER_LENGTH][3];  /* past commands r, r', r'' (rad, rad/s, rad/s^2) */
    int head;                                /* index of the newest */
} servo_shaper_t;
"""


def source_part(export) -> str:
    """The helpers' C source (empty without any)."""
    if export is None or export.empty:
        return ""
    out = []
    if export.feedforward is not None:
        ff = export.feedforward
        n = len(ff["ratio"])
        out.append("/* feedforward: the designed gains (A per output rad/s and rad/s^2) and the ratio table of the\n"
                   " * speed reference N(r) r' (motor rad per output rad at evenly spaced output angles) */\n"
                   + _array("SERVO_FF_RATIO_Q", ff["ratio_q"]) + _array("SERVO_FF_RATIO", ff["ratio"])
                   + _interp("servo_ratio", "SERVO_FF_RATIO", "SERVO_FF_RATIO_Q", n)
                   + f"""
double servo_feedforward_current(double r_dot, double r_ddot)
{{
    return {_f(ff['velocity'])} * r_dot + {_f(ff['acceleration'])} * r_ddot;
}}

double servo_feedforward_speed(double theta_ref, double r_dot)
{{
    return servo_ratio(theta_ref) * r_dot;
}}
""")
    if export.schedule is not None:
        s = export.schedule
        n = s.points
        out.append("/* gain schedule: factors on the position error (theta_ref, theta) and on the motor speed at\n"
                   " * evenly spaced output angles; linear between them, the end values held beyond */\n"
                   + _array("SERVO_SCHEDULE_Q", s.q) + _array("SERVO_SCHEDULE_ERROR", s.error_factor)
                   + _array("SERVO_SCHEDULE_SPEED", s.speed_factor)
                   + _interp("servo_schedule_error", "SERVO_SCHEDULE_ERROR", "SERVO_SCHEDULE_Q", n)
                   + _interp("servo_schedule_speed", "SERVO_SCHEDULE_SPEED", "SERVO_SCHEDULE_Q", n)
                   + """
void servo_schedule(double theta, double *g_error, double *g_speed)
{
    *g_error = servo_schedule_error(theta);
    *g_speed = servo_schedule_speed(theta);
}
""")
    if export.shaper is not None:
        sh = export.shaper
        terms = " + ".join(f"{_f(a)} * sh->history[(sh->head + SERVO_SHAPER_LENGTH - {d}) % SERVO_SHAPER_LENGTH][j]"
                           for a, d in zip(sh["amplitudes"], sh["delays_samples"]))
        out.append(f"""/* command shaper ({sh['design'].kind.upper()}): impulses {sh['amplitudes']} at {sh['delays_samples']} motion samples */
void servo_shaper_init(servo_shaper_t *sh, double r)
{{
    int k;
    for (k = 0; k < SERVO_SHAPER_LENGTH; ++k) {{
        sh->history[k][0] = r;
        sh->history[k][1] = 0.0;
        sh->history[k][2] = 0.0;
    }}
    sh->head = 0;
}}

void servo_shape(servo_shaper_t *sh, double r, double r_dot, double r_ddot, double out[3])
{{
    int j;
    sh->head = (sh->head + 1) % SERVO_SHAPER_LENGTH;
    sh->history[sh->head][0] = r;
    sh->history[sh->head][1] = r_dot;
    sh->history[sh->head][2] = r_ddot;
    for (j = 0; j < 3; ++j) {{
        out[j] = {terms};
    }}
}}
""")
    return "\n".join(out)


__all__ = ["header_part", "shaper_type", "source_part"]
