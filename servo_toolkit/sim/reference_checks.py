"""What a time run can resolve of a sine command: the one rule ``simulate`` (Python and
command line), the sweeps, the reductions and the scene's sine studies apply before any work;
and whether a command given in units is one of the scene's output."""

from __future__ import annotations

from ..core.output_units import output_unit
from ..errors import SceneError

#: a sine command is tracked meaningfully up to this fraction of the controller's sample
#: rate (4 samples per period; the Nyquist limit itself, 0.5 / Ts, samples a sine at its zeros)
NYQUIST_FRACTION = 0.25
#: fewest whole periods of a sine command a time run must hold
MIN_PERIODS = 1.0


def check_sine_frequency(frequency: float, sample_time: float, duration: float | None, key: str,
                         min_periods: float = MIN_PERIODS, duration_key: str | None = None) -> None:
    """SceneError naming ``key`` unless a sine command at ``frequency`` (Hz) is one the run
    can resolve.

    Parameters
    ----------
    frequency : float
    sample_time : float
        The controller's sample time (s); 0 for a continuous controller (no upper limit).
    duration : float or None
        The run's length (s); None: no lower limit checked here.
    key : str
        The option, scene key or argument named in the error (``--frequency``,
        ``studies.NAME.frequency``, ``reference``).
    min_periods : float
    duration_key : str, optional
        Named instead of ``key`` when the run is too short for the frequency (the Python
        ``simulate``'s ``duration``).

    Raises
    ------
    SceneError
        ``frequency`` above :data:`NYQUIST_FRACTION` of the sample rate (at or above its
        Nyquist limit the sampled controller sees an alias, e.g. the sine at its zeros), or
        fewer than ``min_periods`` periods in ``duration``.
    """
    if sample_time > 0:
        top = NYQUIST_FRACTION / sample_time
        if not frequency <= top:
            raise SceneError(key, f"must be at most {top:g} Hz, a quarter of the controller's {1 / sample_time:g} Hz "
                                  f"sample rate (its Nyquist limit is {0.5 / sample_time:g} Hz; a sine there is sampled "
                                  f"at fixed phases, not tracked) (got {frequency:g} Hz)")
    if duration is not None and not frequency * duration >= min_periods * (1 - 1e-9):
        if duration_key is not None:
            raise SceneError(duration_key, f"must be at least {min_periods / frequency:g} s: the run must hold "
                                           f"{min_periods:g} whole period(s) of the {frequency:g} Hz sine command "
                                           f"(got {duration:g} s)")
        raise SceneError(key, f"must be at least {min_periods / duration:g} Hz: the run of {duration:g} s must hold "
                              f"{min_periods:g} whole period(s) of the command (got {frequency:g} Hz)")


def check_reference_output(position_unit: str | None, scene, key: str = "reference") -> None:
    """SceneError naming ``key`` when a command's positions were given as Quantities of the
    other output's unit than the scene's (``position_unit`` ``"m"`` for a shaft's angle,
    ``"rad"`` for a carriage's travel): a bare number is in the output's SI unit either way,
    but 1 mm read as 0.001 rad of a shaft angle is no command the user meant."""
    wanted = output_unit(scene).si
    if position_unit is None or position_unit == wanted:
        return
    words = {"m": "a travel (m)", "rad": "an angle (rad)"}
    raise SceneError(key, f"its positions are {words[position_unit]} and this scene's output is "
                          f"{words[wanted]}: give them in the output's unit")


__all__ = ["MIN_PERIODS", "NYQUIST_FRACTION", "check_reference_output", "check_sine_frequency"]
