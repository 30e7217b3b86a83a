"""The headers of measured data (:mod:`.data`): the columns each kind of CSV takes, and the
rule a header breaks, in words that name the first wrong or missing column, or tell a drive's
time log to go through ``frf`` first."""

from __future__ import annotations

FREQUENCY_HEADER = ("frequency_hz", "gain_db", "phase_deg")
#: the optional columns of a frequency response, in their order, in groups that come together
#: and each with those before it
FREQUENCY_OPTIONAL = (("coherence",), ("averages",), ("resolution_db", "resolution_deg"))
#: the headers of a frequency response
FREQUENCY_HEADERS = tuple(FREQUENCY_HEADER + sum(FREQUENCY_OPTIONAL[:k], ())
                          for k in range(len(FREQUENCY_OPTIONAL) + 1))
TIME_HEADER = ("time_s", "voltage_V", "current_A", "motor_angle_rad", "output_angle_rad")
#: closed-loop traces, by the output's unit
LOOP_HEADERS = {unit: ("time_s", f"command_{unit}", f"output_{unit}", "current_A") for unit in ("m", "rad")}


def _stem(name: str) -> str:
    """A column's quantity without its unit (``phase_rad`` -> ``phase``)."""
    return name.rsplit("_", 1)[0].lower() if "_" in name else name.lower()


#: the columns a time log's time may have
TIME_COLUMNS = ("time_s", "t_s")


def time_log_rule(time_column: str) -> str:
    """What a drive's time log (a rig's log, ``excite``'s or ``simulate``'s) given where a
    response is read needs."""
    return (f"is a drive's time log (first column {time_column}, its current logged): estimate its response "
            "with frf LOG -o FRF.csv and give that file")


def header_rule(header: tuple, expected: str) -> str:
    """The rule a header breaks, naming its first wrong or missing column when the kind of
    data it means is recognisable (the quantity of its columns), else the headers read. A
    drive's time log (its current logged, no voltage to drive a model with nor a command and
    output of closed-loop traces, or ``excite``'s excitation column) is told to go through
    ``frf``."""
    names = {c.lower() for c in header}
    loop = any(_stem(c) in ("command", "output") for c in header)
    if header and header[0] in TIME_COLUMNS and "current_A" in header and not loop and (
            "voltage_V" not in header or "current_excitation_A" in header):
        return f"{time_log_rule(header[0])}; expected {expected}"
    if header and _stem(header[0]).startswith("freq") or names & {"gain_db", "phase_deg", "coherence"}:
        kind, template, optional = "a frequency response", FREQUENCY_HEADER, FREQUENCY_OPTIONAL
    elif any(_stem(c) == "voltage" for c in header):
        kind, template, optional = "voltage-driven time traces", TIME_HEADER, ()
    elif any(_stem(c) in ("command", "output") for c in header):
        unit = next((c.rsplit("_", 1)[1] for c in header if _stem(c) == "command" and "_" in c), "m")
        template = LOOP_HEADERS.get(unit, LOOP_HEADERS["m"])
        kind, optional = "closed-loop time traces", ()
    else:
        return f"expected {expected}, got {','.join(header)!r}"
    full = template + sum(optional, ())
    starts = {len(template) + len(sum(optional[:k], ())) for k in range(len(optional) + 1)}
    wanted = ",".join(template) + "".join(f"[,{','.join(o)}" for o in optional) + "]" * len(optional)
    for n, name in enumerate(full):
        if n >= len(header):
            if n < len(template) or n not in starts:
                return f"column {n + 1} ({name}) is missing; expected {wanted} ({kind})"
            break
        if header[n] != name:
            why = (f"column names are case-sensitive: write {name}" if header[n].lower() == name.lower() else
                   f"the unit of {_stem(name)} must be {name.split('_', 1)[1]}" if _stem(header[n]) == _stem(name)
                   else f"column {n + 1} of {kind} is {name}")
            return f"column {n + 1} is {header[n]!r}: {why}; expected {wanted}"
    return f"column {len(full) + 1} ({header[len(full)]!r}) is not a column of {kind}; expected {wanted}"


__all__ = ["FREQUENCY_HEADER", "FREQUENCY_HEADERS", "FREQUENCY_OPTIONAL", "LOOP_HEADERS", "TIME_COLUMNS",
           "TIME_HEADER", "header_rule", "time_log_rule"]
