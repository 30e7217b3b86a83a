"""``servo-toolkit frf``: frequency response and coherence from a rig's time log.

LOG.csv has a ``time_s`` column (equally spaced) and one column per signal; the traces
``simulate -o`` writes (time column ``t_s``) read as they are, their last sample left out
when the run's final step is shorter than the others. ``--input`` and ``--output`` name the
columns of the excitation and of the response (default ``current_A`` and
``motor_angle_rad``); ``--output`` is a column of the log, not a file (``-o`` is the file
written). A period the log records in a comment line before its header (``# period_samples:
N``, with ``# settle_periods: K`` and ``# excited_bins: FIRST:LAST``, as ``excite`` writes) is
the periodic window's default, and the recorded bins are the frequencies estimated.
The H1 estimator (see :mod:`servo_toolkit.identify.frf`: whole periods of a periodic
excitation in rectangular windows, or Welch averaging of Hann windows) gives the response
at every excited frequency with its coherence and the number of spectra averaged;
``--derivative`` turns an angle's response into the speed's (what ``fit --response plant``
compares). ``-o`` writes the CSV that ``fit`` reads. The step each of the two columns is
rounded to (:mod:`servo_toolkit.identify.resolution`: as a ``# resolution_COLUMN: STEP`` line
records it, else as its values show it) sets the error its rounding leaves in the response,
written with it (``resolution_db,resolution_deg``) and named in a comment line. A ``# signal:
NAME`` line names the signal the response is to (the output column, or its speed with
``--derivative``, e.g. ``motor_speed_rad_s``): ``--plant-frf`` takes it from there.
"""

from __future__ import annotations

from .common import add_json, bounded, emit, parse_band
from ..core.files import check_stamped_file, write_text
from ..core.marks import stamp
from ..errors import SceneError


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("frf", help="frequency response and coherence from a time log (H1, Welch)")
    p.add_argument("log", metavar="LOG.csv",
                   help="time log: time_s,SIGNAL,... (equally spaced times), or a trace simulate -o wrote (t_s,...)")
    p.add_argument("--input", default="current_A", metavar="COLUMN",
                   help="the log's column holding the input (excitation) signal (default current_A)")
    p.add_argument("--output", default="motor_angle_rad", metavar="COLUMN",
                   help="the log's column holding the output (response) signal, not a file: -o names the file "
                        "written (default motor_angle_rad)")
    p.add_argument("--derivative", action="store_true",
                   help="the response of the output's time derivative (an angle log gives the speed response, "
                        "as fit --response plant compares)")
    p.add_argument("--window", choices=("auto", "periodic", "hann"), default="auto",
                   help="periodic: whole periods of a periodic excitation (multisine), rectangular windows, no "
                        "leakage; hann: Welch averaging (noise, chirp); auto (default): periodic when the input "
                        "repeats, else hann")
    p.add_argument("--segment", type=bounded(int, 16, 2 ** 24, what="a number of samples"), metavar="N",
                   help="hann: samples per Welch segment (default: the largest power of two giving 8 segments)")
    p.add_argument("--period", type=bounded(int, 16, 2 ** 30, what="a number of samples"), metavar="N",
                   help="periodic: samples per period (default: the one the log records in a '# period_samples: N' "
                        "line before its header, as excite writes, with the lines its '# excited_bins: FIRST:LAST' "
                        "line names; else the period the input repeats with)")
    p.add_argument("--settle", type=bounded(int, 0, 2 ** 20, what="a number of periods"), metavar="K",
                   help="periodic: periods left out at the start (default: the log's '# settle_periods: K' line, "
                        "else 1 when the log holds 3 or more periods, else 0)")
    p.add_argument("--band", metavar="LO:HI", help="keep frequencies from LO to HI Hz (default: every excited one)")
    p.add_argument("-o", "--out", dest="out", metavar="FRF.csv",
                   help="write frequency_hz,gain_db,phase_deg,coherence here (the CSV fit reads)")
    add_json(p)
    p.set_defaults(run=run)


def _estimator(data) -> str:
    if data.window == "periodic":
        return f"H1 estimator, rectangular window on each of {data.averages} periods"
    return f"H1 estimator, Hann windows, {data.averages} Welch segments"


def _table(data) -> str:
    lines = [f"Frequency response from {data.source} ({data.points} frequencies, {_estimator(data)})",
             "  frequency_hz     gain_db   phase_deg  coherence"]
    step = max(1, data.points // 40)
    for k in range(0, data.points, step):
        lines.append(f"  {data.frequency_hz[k]:12.4g}  {data.gain_db[k]:10.4g}  {data.phase_deg[k]:10.4g}  "
                     f"{data.coherence[k]:9.3f}")
    if step > 1:
        lines.append(f"  (one frequency in {step}; -o writes them all)")
    low = data.coherence < 0.8
    if low.any():
        lines.append(f"  coherence below 0.8 at {int(low.sum())} of {data.points} frequencies")
    return "\n".join(lines)


#: a trace of simulate -o: the columns of the closed loop's command and response (an output
#: angle, an output travel)
_SIMULATE_HINTS = ("--input reference_angle_rad --output output_angle_rad",
                   "--input reference_travel_m --output output_travel_m")


def _check_columns(args, log) -> None:
    """The input and output signals' columns are in the log, else one line naming the
    option, what it names and the columns there are."""
    for option, name, what in (("--input", args.input, "input (excitation)"),
                               ("--output", args.output, "output (response)")):
        if name not in log.columns:
            fits = [h for h in _SIMULATE_HINTS if h.split()[1] in log.columns] if log.time_column == "t_s" else []
            hint = f" (a trace of simulate -o: e.g. {fits[0]} for the closed loop)" if fits else ""
            raise SceneError(f"{option} {name}", f"{args.log} has no such column; {option} names the {what} "
                             f"signal's column, one of: {', '.join(log.columns)}{hint}")


def run(args) -> int:
    """Run the command."""
    import sys

    from ..identify.frf import estimate_frf, frf_csv, read_time_log, response_signal
    from ..identify.resolution import log_resolution
    band = parse_band(args.band)
    if args.out is not None:
        check_stamped_file(args.out, "-o", "frf", (".csv",), inputs=(args.log,))
    log = read_time_log(args.log)
    _check_columns(args, log)
    notes = list(log.notes)  # printed once the estimate is made: a failing run prints its error alone
    t, columns = log.time_s, log.columns
    period, settle, lines = args.period, args.settle, None
    if log.period_samples is not None and period is None and args.window != "hann" and args.segment is None:
        period = log.period_samples
        settle = log.settle_periods if settle is None else settle
        if log.excited_bins is not None:
            lines = list(range(log.excited_bins[0], log.excited_bins[1] + 1))
        notes.append(f"the period as the log records it, {period} samples"
                     + (f", {settle} settling" if settle is not None else "")
                     + (f", lines {lines[0]} to {lines[-1]} of the period" if lines else ""))
    steps = [log_resolution(log, c) for c in (args.input, args.output)]
    data = estimate_frf(t, columns[args.input], columns[args.output], window=args.window, segment=args.segment,
                        period=period, settle=settle, band=band, derivative=args.derivative,
                        source=str(args.log), lines=lines, resolution=tuple(r.step for r in steps))
    notes += [r.text() for r in steps]
    signal = response_signal(args.output, args.derivative)
    if args.out is not None:
        head = f"# signal: {signal}\n" + "".join(f"# {r.text()}\n" for r in steps)
        write_text(args.out, stamp(head + frf_csv(data), "frf"), "-o")
    for note in notes:
        print(f"servo-toolkit: note: {args.log}: {note}", file=sys.stderr)
    out = {"source": str(args.log), "input": args.input, "output": args.output, "derivative": args.derivative,
           "signal": signal,
           "time_column": log.time_column, "log_notes": list(log.notes),
           "window": data.window, "averages": data.averages,
           "points": data.points, "frequency_hz": data.frequency_hz.tolist(), "gain_db": data.gain_db.tolist(),
           "phase_deg": data.phase_deg.tolist(), "coherence": data.coherence.tolist(),
           "resolution": [r.to_dict() for r in steps],
           "resolution_db": None if data.resolution_db is None else data.resolution_db.tolist(),
           "resolution_deg": None if data.resolution_deg is None else data.resolution_deg.tolist()}
    if args.out is not None:
        out["output_file"] = str(args.out)
    emit(args, out, _table(data) + (f"\nwritten to {args.out}" if args.out else ""))
    return 0
