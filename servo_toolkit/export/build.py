"""``export(design_result, scene, ...)``: the designed controller as JSON and C99 sources."""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import control as ct
import numpy as np

from ..core.json_text import to_json
from ..core.version import __version__
from ..loop.controller import CascadeController
from ..errors import SceneError
from .blocks import blocks_of, tustin_to_continuous
from .c_code import HEADER_NAME, SOURCE_NAME, header, source
from .command import command_export
from .position_count import position_count
from .quantize import filter_shifts, quantize
from .result import ExportResult
from .sensitivity import coefficient_sensitivity
from .writer import check_directory, write_files


def quantized_controller(design_result, quantized) -> CascadeController:
    """The quantized motion controller as a :class:`CascadeController` that the simulation
    and the loop analysis run: the continuous system whose Tustin sampling is the quantized
    discrete controller, with the design's current loop."""
    c = design_result.controller
    motion = tustin_to_continuous(quantized.blocks.state_space())
    return CascadeController(motion, c.current_kp, c.current_ki, c.sample_time,
                             f"{c.description} [quantized {quantized.fmt}]")


def _requirements(design_result):
    from ..loop.requirements import SPECS, Requirement
    return [Requirement(c.name, c.sense, c.required, c.unit, c.source)
            for c in design_result.requirements if c.name in SPECS]


def evaluate_quantized(scene, design_result, controller):
    """The quantized controller analysed like the design (:func:`servo_toolkit.loop.design.evaluate`);
    when that analysis breaks down on a degenerate loop (e.g. a notch whose zeros became real
    and a closed-loop pole at the origin), the margins and stability from python-control
    from :func:`servo_toolkit.loop.margins.loop_margins` on the loop itself (the loop's own
    crossings), every requirement counted as missed, and the reason."""
    from ..loop.closed_loop import linear_closed_loop, open_loop
    from ..loop.design import evaluate
    from ..loop.margins import loop_margins
    try:
        return evaluate(scene, controller, design_result.q0, reqs=_requirements(design_result),
                        phase_hz=design_result.margins.phase_at_hz), None
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        reason = (f"the loop analysis of the quantized controller breaks down (python-control: {exc}); "
                  "its closed loop has no usable bandwidth")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cl = linear_closed_loop(scene, controller, design_result.q0)["theta", "theta_ref"]
        try:
            margins = replace(loop_margins(open_loop(scene, controller, design_result.q0), cl,
                                           phase_hz=design_result.margins.phase_at_hz), bandwidth_hz=math.nan)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            poles = ct.poles(cl)
            margins = replace(design_result.margins, gain_margin_db=math.nan, phase_margin_deg=math.nan,
                              closed_loop_stable=bool(np.all(poles.real < 0)), bandwidth_hz=math.nan,
                              max_closed_loop_pole_real=float(np.max(poles.real)),
                              unstable_closed_loop_poles=int(np.sum(poles.real >= 0)))
    checks = [replace(c, achieved=math.nan, passed=False) for c in design_result.requirements]
    return replace(design_result, controller=controller, margins=margins, requirements=checks,
                   closed_loop=cl, motion=None, notes=(reason,)), reason


def _failures(design_result, qdesign, reason=None) -> tuple:
    """Every requirement the quantized controller's loop misses (rows named, figures given),
    each saying whether the un-quantized design already misses it; and the requirements the
    design itself misses that the quantized loop happens to meet (the export carries a design
    that fails them)."""
    out = [reason] if reason else []
    if not qdesign.margins.closed_loop_stable:
        out.append(f"the closed loop with the quantized controller is unstable ({qdesign.margins.instability})")
    designed = {c.name: c for c in design_result.requirements}
    for c in qdesign.requirements:
        if c.passed or (reason and math.isnan(c.achieved)) or getattr(c, "reason", ""):
            continue  # no figure: the loop's instability (or the reason) already says why
        d = designed.get(c.name)
        why = ("quantization costs it" if d is None or d.passed else
               f"the design without quantization already misses it ({d.achieved:.4g} {d.unit})")
        out.append(f"{c.name}: {c.achieved:.4g} {c.unit} with the quantized controller, required {c.sense} "
                   f"{c.required:g} {c.unit}: {why}")
    missed_q = {c.name for c in qdesign.requirements if not c.passed}
    return tuple(out) + requirement_failures(design_result, skip=missed_q)


def requirement_failures(design_result, skip=(), quantized: bool = True) -> tuple:
    """Each requirement of the scene the design itself misses (robustness rows named
    ``robust_<name>``), named with its figure, in either number format: the exported
    controller carries a design that fails them. Rows without a figure (an unstable loop's)
    are left to :func:`design_failures`; ``skip`` names rows already reported; ``quantized``:
    the export also has a quantized loop (the row then says the design misses it without
    quantization)."""
    who = "the design without quantization" if quantized else "the design"
    return tuple(f"{d.name}: {who} misses it ({d.achieved:.4g} {d.unit}, required "
                 f"{d.sense} {d.required:g} {d.unit})"
                 for d in design_result.failures if not d.reason and d.name not in skip)


def design_failures(design_result) -> tuple:
    """The design's own closed loop, unstable: the exported controller does not hold the
    plant, whatever the number format (an export of it is never silent)."""
    m = design_result.margins
    if m.closed_loop_stable:
        return ()
    return (f"the designed closed loop (without quantization) is unstable ({m.instability}): the exported "
            "controller does not stabilise the plant",)


def resolution_failures(result) -> tuple:
    """The fixed-point code's worst-case i_ref rounding error over the stated horizon at or
    beyond the current limit: its signals are too coarse for the loop's gains (the half count
    of the position error alone, through the position gain and the speed PI's integral, can
    command the whole current range), and the margins of the quantized coefficients say
    nothing about it."""
    q = result.quantized
    bound, limit = result.error_bound, result.blocks.current_limit
    if not bound >= limit:
        return ()
    hint = "; q31 keeps more bits" if q.fmt == "q15" else ""
    return (f"the {q.fmt} rounding bound on i_ref ({bound:.3g} A over {result.bound_horizon_s:g} s) reaches the "
            f"current limit ({limit:g} A): the signal LSBs (position {q.lsb['theta']:.3g} per count of a "
            f"{q.lsb['theta'] * 2**q.signal_bits:.3g} full scale, motor speed {q.lsb['omega']:.3g} rad/s, current "
            f"{q.lsb['current']:.3g} A) are too coarse for this loop's gains{hint}",)


#: largest magnitude of one product term in the C's int64 sums (8 terms at most, 2^63 the range)
PRODUCT_LIMIT = 2.0**60


def overflow_failures(quantized) -> tuple:
    """Each stored coefficient whose product with a full-scale signal (the input at its full
    scale, the state at ``SERVO_STATE_MAX``), scaled to the state's fraction bits, leaves the
    64-bit range of the C's sums: named with its value and format (the code would overflow,
    not saturate). The back-calculation's products of d1, d2 with the clamp's excess (below
    four times ``SERVO_STATE_MAX``) stay within the margin of :data:`PRODUCT_LIMIT` to 2^63."""
    from .quantize import q_name
    from .sensitivity import COEFFICIENTS
    s, g, word = quantized.signal_bits, quantized.guard, quantized.word
    out = []
    for sec in quantized.sections():
        stored = [(v, f, s + max(0, g - f)) for v, f in zip(sec.b_int, sec.fb)]
        stored += [(v, f, s + g + max(0, -f)) for v, f in zip(sec.a_int, sec.fa)]
        for name, (v, f, bits) in zip(COEFFICIENTS, stored):
            if abs(v) * 2.0**bits >= PRODUCT_LIMIT:
                out.append(f"{sec.name} {name} = {v * 2.0**-f:.6g} counts per count ({q_name(word, f)}) overflows "
                           f"{quantized.fmt}: its product with a full-scale signal, {abs(v) * 2.0**bits:.3g}, "
                           f"exceeds the 2^60 the fixed-point code's 64-bit sums allow")
    return tuple(out)


def _lost_filters(rows) -> tuple:
    """A filter whose complex pair became real is gone: say so."""
    return tuple(f"quantization turns the {r['what']}s of {r['section']} ({r['design_hz']:.4g} Hz) real: "
                 "the filter is gone" for r in rows if math.isnan(r["quantized_hz"]))


def export(design_result, scene, directory=None, *, fixed_point: str | None = None,
           current_sample_time: float | None = None, inputs=(), bound_horizon_s: float = 0.1) -> ExportResult:
    """Export a designed cascade as ``controller.json`` and C99 sources.

    Parameters
    ----------
    design_result : DesignResult
        From :func:`servo_toolkit.design` on ``scene`` (another scene's is refused:
        :meth:`~servo_toolkit.loop.result.DesignResult.require_scene`).
    scene : Scene
        The scene it was designed for (limits, sensors, speed estimator).
    directory : str or Path, optional
        Output folder (checked before work, written atomically); None: nothing is written.
    fixed_point : {None, "q15", "q31"}
        Quantize the motion controller; the margins are recomputed with the quantized
        coefficients and checked against the design's requirements: ``result.failures``
        names every requirement the quantized loop misses (and whether the design without
        quantization already misses it). In either format, a design whose own closed loop is
        unstable is a failure (``result.failures`` says so first), and so is each requirement
        the design itself misses (:func:`requirement_failures`); the files are still written.
        A fixed-point position count whose half reaches the error at rest or the limit cycle
        that ``check`` requires is a failure too (:mod:`.position_count`).
    current_sample_time : float, optional
        Sample time (s) of the current PI; default: see :func:`.blocks.current_loop`.
    inputs : sequence of path
        Files the export must not overwrite (e.g. the scene file).
    bound_horizon_s : float
        Horizon (s) of the stated fixed-point rounding bound on i_ref.

    Returns
    -------
    ExportResult
    """
    design_result.require_scene(scene, "design_result")
    if directory is not None:
        directory = check_directory(directory, inputs)
    if not (math.isfinite(bound_horizon_s) and bound_horizon_s > 0):
        raise SceneError("bound_horizon_s", f"must be > 0, got {bound_horizon_s!r}")
    blocks = blocks_of(design_result, scene, current_sample_time)
    ctrl = design_result.controller
    motion = ct.sample_system(ctrl.motion, ctrl.sample_time, method="tustin")
    result = ExportResult(scene.name, design_result, motion, blocks, bound_horizon_s=bound_horizon_s,
                          failures=design_failures(design_result))
    if fixed_point is None:
        result = replace(result, failures=result.failures + requirement_failures(design_result, quantized=False))
    else:
        q = quantize(blocks, scene.motor, fixed_point)
        qdesign, reason = evaluate_quantized(scene, design_result, quantized_controller(design_result, q))
        shifts = filter_shifts(blocks, q)
        result = replace(result, quantized=q, quantized_design=qdesign, filters=shifts,
                         sensitivity=coefficient_sensitivity(q, blocks.sample_time),
                         failures=result.failures + _failures(design_result, qdesign, reason)
                         + _lost_filters(shifts))
        count = position_count(q, scene, design_result)
        result = replace(result, position_count=count,
                         failures=overflow_failures(q) + result.failures + resolution_failures(result)
                         + count.failures())
    command = command_export(design_result, scene, fixed_point)
    result = replace(result, command=None if command.empty else command)
    files = {"controller.json": to_json(result.controller_json()) + "\n",
             HEADER_NAME: header(blocks, result.quantized, scene.name, __version__, result.command),
             SOURCE_NAME: source(blocks, result.quantized, result.command)}
    result = replace(result, files=files)
    if directory is not None:
        result = replace(result, directory=write_files(directory, files))
    return result

