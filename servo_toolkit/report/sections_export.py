"""Section on the exported controller: the coefficients the C code and controller.json carry."""

from __future__ import annotations

from .section import NotApplicable, Section, esc, fmt, para, table

#: fixed-point formats shown with their cost
FORMATS = ("q31", "q15")


def _coefficient_rows(blocks):
    rows = [(s.name, *(fmt(v, 10) for v in (*s.b, *s.a)), f"{s.input_unit} -> {s.output_unit}")
            for s in blocks.sections()]
    cur = blocks.current
    bc = blocks.back_calculation()
    extra = [("current limit", f"{fmt(blocks.current_limit)} A"),
             ("anti-windup at the current clamp", "none (no integrator)" if bc is None else bc.describe()),
             ("current loop", f"{cur.mode}: kp {fmt(cur.kp)} V/A, ki {fmt(cur.ki)} V/(A s), anti-windup "
                              f"{fmt(cur.kaw)} 1/s, every {fmt(cur.sample_time * 1e6)} us, clamp "
                              f"{fmt(cur.voltage_limit)} V"),
             ("speed estimator", blocks.estimator.kind)]
    return rows, extra


def _quantized_row(ctx, d, fmt_name):
    from ..errors import SceneError
    try:
        from ..export import export
        res = export(d, ctx.scene, fixed_point=fmt_name)
    except SceneError as exc:  # e.g. a speed estimator the fixed-point code does not cover
        return (fmt_name, "-", "-", "-", "-", "-", exc.rule)
    m = res.quantized_design.margins
    shift = ", ".join(f"{r['what']} {fmt(100 * r['shift_relative'], 3)} %" for r in res.filters) or "-"
    return (fmt_name, f"{fmt(m.gain_margin_db)} dB", f"{fmt(m.phase_margin_deg)} deg", fmt(m.closed_loop_stable),
            shift, f"{fmt(res.error_bound, 3)} A", "ok" if res.passed else "; ".join(res.failures))


def exported_coefficients(ctx) -> Section:
    """Coefficients of ``servo-toolkit export`` and the cost of fixed point."""
    scene = ctx.scene
    ctx.require_drivetrain("the controller export")
    if scene.sensors.sample_time <= 0:
        raise NotApplicable("the scene gives no sample time: the controller is continuous, nothing to export")
    d = ctx.design()
    from ..export import export
    res = export(d, scene)
    rows, extra = _coefficient_rows(res.blocks)
    head = ("section", "b0", "b1", "b2", "a1", "a2", "units")
    d_m = d.margins
    qrows = [("float64", f"{fmt(d_m.gain_margin_db)} dB", f"{fmt(d_m.phase_margin_deg)} deg",
              fmt(d_m.closed_loop_stable), "-", "-", "design")]
    qrows += [_quantized_row(ctx, d, name) for name in FORMATS]
    text = para(f"servo-toolkit export {esc(scene.name)} -o DIR writes these coefficients into controller.json "
                f"and servo_controller.h/.c (C99): biquads in direct form II transposed, a0 = 1, sampled "
                f"every {fmt(res.blocks.sample_time * 1e3)} ms by Tustin, exactly the controller the "
                "simulation runs.")
    text += table(head, rows) + table(("item", "value"), extra)
    text += para("Fixed point (--fixed-point): each section stored about z = 1 (the coefficients of N(1 + w) and "
                 "D(1 + w), z = 1 + w, each in its own Q format, so that a filter far below the sample rate keeps "
                 "its frequency); margins recomputed with the quantized coefficients, the shift of each filter's "
                 "natural frequency and the bound on the i_ref rounding error over 0.1 s.")
    text += table(("format", "gain margin", "phase margin", "stable", "filter shift", "rounding bound", "verdict"),
                  qrows)
    return Section("Exported controller coefficients", text, key="export")
