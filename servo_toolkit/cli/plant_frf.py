"""``--plant-frf FRF.csv``: the designed loop closed on a measured plant response (what
``frf -o`` writes), its rows beside the model's (:mod:`servo_toolkit.loop.measured`,
:mod:`servo_toolkit.studies.gate.measured`)."""

from __future__ import annotations

from ..errors import SceneError

#: an output speed's response (what frf --derivative writes for the output) is its position's
#: times j w: the position's is taken
INTEGRALS = {"output_speed_rad_s": "output_angle_rad", "output_speed_m_s": "output_travel_m"}
#: the signal a measured response is to when neither the option nor the file names one
DEFAULT_SIGNAL = "motor_angle_rad"
#: the columns of the measured response; what frf -o writes
EXPECTED = "frequency_hz,gain_db,phase_deg,coherence[,averages[,resolution_db,resolution_deg]] (what frf -o writes)"


def add_plant_frf_options(p) -> None:
    """The options of a loop closed on a measured plant response."""
    p.add_argument("--plant-frf", metavar="FRF.csv",
                   help="also close the designed loop on a measured plant: the response from the motor current to "
                        "--plant-frf-signal as frf -o writes it (frequency_hz,gain_db,phase_deg,coherence,averages); its "
                        "margins beside the model's with their 95 %% intervals from the coherence and the averages "
                        "(check: rows measured_<requirement>), points of coherence below 0.8 never decide; with --filter auto a measured drivetrain mode off the model's moves the "
                        "notch onto it")
    p.add_argument("--plant-frf-signal", default=None, metavar="COLUMN",
                   help="the signal the measured response is to (frf's --output): motor_angle_rad, "
                        "motor_speed_rad_s, output_angle_rad or output_travel_m; its input is the motor current "
                        "(default: the one the file's '# signal:' line names, as frf -o writes it, else "
                        f"{DEFAULT_SIGNAL})")




def _time_log(time_column: str) -> str:
    """The rule a time log (a rig's log, simulate's traces) given for the response breaks."""
    from ..identify.headers import time_log_rule
    return f"{time_log_rule(time_column)}; expected {EXPECTED}"


def _time_column(path) -> str | None:
    """The time column a CSV file's header starts with (a time log), else None."""
    from ..identify.headers import TIME_COLUMNS
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.strip() and not line.lstrip().startswith("#"):
                    first = line.split(",", 1)[0].strip()
                    return first if first in TIME_COLUMNS else None
    except OSError:
        return None
    return None


def read_plant_frf(path):
    """The measured response in ``path`` (FrequencyData), or one SceneError naming
    ``--plant-frf`` and the rule."""
    from ..identify.data import FrequencyData, read_data
    try:
        data = read_data(path)
    except SceneError as exc:
        rule = exc.rule if exc.key in ("(file)", "header") else f"{exc.key}: {exc.rule}"
        time_column = _time_column(path) if exc.key == "header" else None
        if time_column:
            rule = _time_log(time_column)
        raise SceneError("--plant-frf", rule, str(path)) from None
    if not isinstance(data, FrequencyData):
        raise SceneError("--plant-frf", _time_log(_time_column(path) or "time_s"), str(path))
    if data.points < 2:
        raise SceneError("--plant-frf", f"{data.points} point(s); a loop on measured data needs at least two",
                         str(path))
    return data


def plant_response(path):
    """The measured response in ``path`` (:func:`read_plant_frf`) as the loop takes it: an
    output speed's response (``frf --derivative`` of the output, its ``# signal:`` line says
    so) as its position's, divided by ``j w``; a response to a signal the loop does not take
    is one SceneError naming ``--plant-frf``."""
    from dataclasses import replace

    import numpy as np

    from ..loop.measured import SIGNALS
    data = read_plant_frf(path)
    if data.signal in INTEGRALS:
        return replace(data, gain_db=data.gain_db - 20 * np.log10(2 * np.pi * data.frequency_hz),
                       phase_deg=data.phase_deg - 90.0, signal=INTEGRALS[data.signal])
    if data.signal is not None and data.signal not in SIGNALS:
        raise SceneError("--plant-frf", f"records the response to {data.signal} (its '# signal:' line); a loop on a "
                         f"measured plant takes the motor current's response to {', '.join(SIGNALS)}", str(path))
    return data


def settle_plant_frf(args):
    """The measured response ``--plant-frf`` names (:func:`plant_response`; None without one),
    kept in ``args.plant_frf_response``, with ``args.plant_frf_signal`` settled: the option's signal, else the one the file
    records (``# signal: NAME``), else :data:`DEFAULT_SIGNAL`. An option that names another
    signal than the file records is one SceneError naming ``--plant-frf-signal``."""
    if not getattr(args, "plant_frf", None):
        return None
    data = plant_response(args.plant_frf)
    named, recorded = args.plant_frf_signal, data.signal
    if named is not None and recorded is not None and named != recorded:
        raise SceneError("--plant-frf-signal", f"{named}, but {args.plant_frf} records the response to {recorded} "
                         "(its '# signal:' line, as frf -o writes it): leave the option out, or estimate the "
                         "response to the signal named")
    args.plant_frf_signal = named or recorded or DEFAULT_SIGNAL
    args.plant_frf_response = data  # read once: the mode, the check and the report take it from here
    return data


def _settled(args):
    """The response :func:`settle_plant_frf` read (read and settled now when it has not run)."""
    data = getattr(args, "plant_frf_response", None)
    return data if data is not None else settle_plant_frf(args)


def measured_mode_of(args):
    """The drivetrain mode of the response ``--plant-frf`` names (None: no file, or no mode
    in it; :mod:`servo_toolkit.loop.measured_mode`)."""
    if not getattr(args, "plant_frf", None):
        return None
    from ..loop.measured import POOR_COHERENCE, SIGNALS
    from ..loop.measured_mode import find_mode
    data = _settled(args)
    if args.plant_frf_signal not in SIGNALS:
        return None  # named by measured_loop's own error, after the design
    return find_mode(data.frequency_hz, data.complex, data.coherence, args.plant_frf_signal, POOR_COHERENCE)


def plant_frf_check(args, scene, result, rows: bool = True):
    """``(rows, JSON dict, text)`` of ``result`` (the scene's design) closed on the response
    ``--plant-frf`` names; ``rows=False`` (``design``): the figures beside the model's, no
    verdict on them."""
    import numpy as np

    from ..loop.measured import measured_loop
    from ..studies.gate import measured_rows
    data = _settled(args)
    f_req = next((c.required for c in result.requirements if c.name == "bandwidth"), None)
    m = measured_loop(result, scene.motor, data.frequency_hz, data.complex, data.coherence,
                      signal=args.plant_frf_signal, source=str(args.plant_frf), required_bandwidth_hz=f_req,
                      averages=data.averages, resolution_sd=data.resolution_sd)
    table = measured_rows(m, result.requirements) if rows else []
    d = m.to_dict()
    d["points_detail"] = [{"frequency_hz": float(f), "loop_gain_db": float(20 * np.log10(abs(lm))),
                           "loop_phase_deg": float(np.degrees(np.angle(lm))), "coherence": float(c),
                           "poor_coherence": bool(c < m.poor_coherence)}
                          for f, lm, c in zip(m.frequency_hz, m.loop, m.coherence)]
    verdict = ([] if rows else ["  verdict: the model's (the exit code); check --plant-frf judges the measured plant's "
                                "rows"])
    text = "\n".join([m.margins_table(), m.table(),
                      *(f"  {r.id:<34}{'ok' if r.passed else r.status.upper()}  {r.message()}" for r in table),
                      *verdict, *(f"  note: {n}" for n in m.notes())])
    return table, d, text
