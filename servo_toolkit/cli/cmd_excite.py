"""``servo-toolkit excite``: an excitation for a rig's drive (:mod:`servo_toolkit.studies.excite`).

A multisine with a low crest factor, a PRBS or a periodic chirp over a band from the scene's
loop, added to the drive's current reference or as its speed reference, as large as the
current, voltage and stroke limits allow; ``-o`` writes it with the model's run of it (the
log to expect), a file ``frf`` reads as it is (its period recorded in a comment line).
Frequencies take units (``--band "2 Hz:0.1 kHz"``, ``--resolution "0.5 Hz"``; a bare number
is in Hz), the amplitude too (``"5 A"``, ``"300 rpm"``; a bare number is in A or rad/s).
"""

from __future__ import annotations

from ..errors import SceneError
from .common import add_json, add_scene, bounded, emit, load_scene

SIGNALS = ("multisine", "prbs", "chirp")
INPUTS = ("current", "speed")
#: the amplitude's unit for each input
UNITS = {"current": "A", "speed": "rad/s"}


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("excite", help="an excitation for the rig's drive within the scene's limits, with the "
                                      "model's response to it (a file frf reads)")
    add_scene(p)
    p.add_argument("-o", "--out", dest="out", metavar="STIMULUS.csv",
                   help="write the excitation and the model's predicted log here: time_s, the excitation "
                        "(current_excitation_A or speed_reference_rad_s), current_A, voltage_V, motor_angle_rad, "
                        "motor_speed_rad_s and the output's position, the period in a comment line (frf reads it)")
    p.add_argument("--signal", choices=SIGNALS, default="multisine",
                   help="multisine: equal lines, Schroeder's phases lowered further by clipping (default); prbs: a "
                        "maximum-length binary sequence; chirp: a periodic linear chirp")
    p.add_argument("--input", choices=INPUTS, default="current",
                   help="what the drive takes: current, added to the current reference of the scene's position loop, "
                        "which holds the operating point (default); speed, the motor-speed reference of the drive's "
                        "speed loop (the design's speed PI), no position loop")
    p.add_argument("--band", metavar="LO:HI",
                   help="frequencies of interest, each in Hz or with units (default: a decade around the loop's gain "
                        "crossover, up to twice the first drivetrain mode)")
    p.add_argument("--resolution", metavar="HZ",
                   help="frequency resolution, the period's inverse, in Hz or with units (default: five lines across "
                        "the first mode's half-power bandwidth, at most the band's low end)")
    p.add_argument("--periods", type=bounded(int, 1, 1000, what="a number of periods"), default=4, metavar="N",
                   help="periods averaged (default 4)")
    p.add_argument("--settle", type=bounded(int, 0, 1000, what="a number of periods"), metavar="K",
                   help="periods run first and left out (default: five time constants of the drive's loop, at "
                        "least one)")
    p.add_argument("--amplitude", metavar="AMP",
                   help="the excitation's peak in A (current) or rad/s (speed), or with units ('5 A', '300 rpm'); "
                        "refused beyond a limit (default: the largest within 80 %% of the current, voltage and "
                        "stroke limits)")
    p.add_argument("--seed", type=bounded(int, 0, 2 ** 32 - 1, what="a whole number"), default=0, metavar="N",
                   help="seed of the PRBS register's start and of the multisine's random-phase starts (default 0)")
    p.add_argument("--plot", metavar="FILE", help="save the excitation and the plant's response (PNG/SVG/PDF)")
    add_json(p)
    p.set_defaults(run=run)


def _quantity(text: str, unit: str, option: str) -> float:
    """``text`` in ``unit``: a bare number is in it, a quantity with units converted to it."""
    try:
        return float(text)
    except ValueError:
        from ..core.units import parse_quantity
        return parse_quantity(text.strip(), unit, option)


def frequency(text: str, option: str) -> float:
    """A positive, finite frequency (Hz) from ``"2"``, ``"2 Hz"`` or ``"12 rad/s"``."""
    import math
    value = _quantity(text, "Hz", option)
    if not (math.isfinite(value) and value > 0):
        raise SceneError(option, f"must be a positive, finite frequency (got {text!r})")
    return value


def band_of(text: str | None):
    """``--band LO:HI`` in Hz, or None."""
    if text is None:
        return None
    lo, sep, hi = text.partition(":")
    if not sep:
        raise SceneError("--band", f"must be LO:HI, each in Hz or with units (got {text!r})")
    band = (frequency(lo, "--band"), frequency(hi, "--band"))
    if not band[0] < band[1]:
        raise SceneError("--band", f"must be LO:HI with LO < HI (got {text!r})")
    return band


def amplitude_of(text: str | None, kind: str):
    """``--amplitude`` in A or rad/s (a bare number in that unit), or None."""
    if text is None:
        return None
    import math
    value = _quantity(text, UNITS[kind], "--amplitude")
    if not (math.isfinite(value) and value > 0):
        raise SceneError("--amplitude", f"must be a positive, finite peak in {UNITS[kind]} (got {text!r})")
    return value


def run(args) -> int:
    """Run the command."""
    from ..core.files import check_figure_file, check_stamped_file, save_figure, write_text
    from ..core.marks import stamp
    band = band_of(args.band)
    resolution = None if args.resolution is None else frequency(args.resolution, "--resolution")
    amplitude = amplitude_of(args.amplitude, args.input)
    scene = load_scene(args.scene)
    inputs = [args.scene, *scene.input_files]
    if args.out is not None:
        check_stamped_file(args.out, "-o", "excite", (".csv",), inputs=inputs)
    if args.plot is not None:
        check_figure_file(args.plot, "--plot", inputs=inputs)
    from ..studies.excite import excite
    res = excite(scene, signal=args.signal, input=args.input, band=band, resolution=resolution, periods=args.periods,
                 settle=args.settle, amplitude=amplitude, seed=args.seed)
    if args.out:
        write_text(args.out, stamp(res.csv(), "excite"), "-o")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        axes = res.plot()
        save_figure(axes[0].figure, args.plot)
    out = res.to_dict()
    text = res.table()
    if args.out:
        out["output_file"] = str(args.out)
        text += f"\nwritten to {args.out} (frf {args.out} estimates it; its period is recorded there)"
    emit(args, out, text)
    return 0
