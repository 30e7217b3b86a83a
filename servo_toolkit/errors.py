"""Errors raised at the scene boundary."""

from __future__ import annotations


class SceneError(ValueError):
    """A scene violates a rule.

    Parameters
    ----------
    key : str
        Key path inside the scene, e.g. ``drivetrain[2].rod_length``.
    rule : str
        The rule that was broken, in plain words.
    source : str, optional
        File the scene came from.
    """

    def __init__(self, key: str, rule: str, source: str | None = None):
        self.key = key
        self.rule = rule
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}{key}: {rule}")

    def with_source(self, source: str) -> "SceneError":
        """Return the same error tagged with the file it came from."""
        return SceneError(self.key, self.rule, source)


class SceneWarning(UserWarning):
    """A scene value that loads but may not be what its author meant (a bare number far from
    its key's typical values, read in the key's SI unit); the command line prints it as one
    ``servo-toolkit: note:`` line on stderr."""


class SimulationError(RuntimeError):
    """A simulation left its validity domain (non-finite state, unstable step)."""


class StrokeEndReached(SimulationError):
    """A run carried its output past the end of the stroke (the end stops are not modelled
    unless asked for): a physical outcome of the run, not a numerical failure.

    Attributes
    ----------
    time_s : float
        When the output left the stroke.
    """

    def __init__(self, message: str, time_s: float):
        super().__init__(message)
        self.time_s = float(time_s)
