"""Results shared between report sections, computed once and cached (errors included, apart
from a section's time limit: the next caller computes the result again)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .section import NotApplicable
from .time_limit import SectionTimeout


@dataclass
class Context:
    """What the section builders share: the scene, the settings and cached results.

    Parameters
    ----------
    scene : Scene
    light : bool
        Use light settings for expensive studies (fewer points and shorter runs), so that a
        report of the reference EMA takes well under a minute.
    executor : concurrent.futures.Executor or None
        Passed to studies that accept one.
    plant_frf : FrequencyData or None
        A measured plant response (``report --plant-frf``): the design places its notch on
        its drivetrain mode (:mod:`servo_toolkit.loop.measured_mode`), the requirements
        table adds the measured rows and the report a section on it.
    plant_frf_signal : str
        The signal the measured response is to, from the motor current.
    """

    scene: object
    light: bool = True
    executor: object = None
    plant_frf: object = None
    plant_frf_signal: str = "motor_angle_rad"
    _cache: dict = field(default_factory=dict, repr=False)

    def result(self, key: str, compute):
        """``compute()`` once per key; a failure is cached and re-raised to every caller.

        A :class:`~.time_limit.SectionTimeout` is not a property of the result but of the
        section that happened to compute it first: it is re-raised to that section and not
        cached, so a later caller (the requirements table, which has no time limit) computes
        the result in full."""
        if key not in self._cache:
            try:
                self._cache[key] = (True, compute())
            except SectionTimeout:
                raise
            except Exception as exc:  # noqa: BLE001 - re-raised below to each section
                self._cache[key] = (False, exc)
        ok, value = self._cache[key]
        if not ok:
            raise value
        return value

    def has_drivetrain(self) -> bool:
        """True when the scene has a motor-driven drivetrain."""
        return bool(self.scene.stages) and self.scene.motor is not None

    def require_drivetrain(self, what: str = "this section") -> None:
        """Raise :class:`NotApplicable` with a polite reason when there is no drivetrain."""
        if not self.has_drivetrain():
            kind = describe_kind(self.scene)
            raise NotApplicable(f"{what} needs a motor-driven drivetrain; this scene describes {kind}, "
                                "which the toolkit analyses with its own studies instead")

    def use_design(self, result) -> None:
        """Report ``result`` (a DesignResult, e.g. a tuned one) instead of designing."""
        self._cache["design"] = (True, result)

    def design(self):
        """The designed loop (``servo_toolkit.loop.design``, or the one given)."""
        self.require_drivetrain("loop design")
        from ..loop import design
        return self.result("design", lambda: design(self.scene, measured_mode=self.measured_mode()))

    def measured_mode(self):
        """The drivetrain mode of the measured response (None without one, or without a mode)."""
        if self.plant_frf is None:
            return None
        from ..loop.measured import POOR_COHERENCE
        from ..loop.measured_mode import find_mode
        d = self.plant_frf
        return find_mode(d.frequency_hz, d.complex, d.coherence, self.plant_frf_signal, POOR_COHERENCE)


    def actuator(self):
        """The designed loop's nonlinear step and requirement sine
        (:func:`servo_toolkit.studies.actuator.actuator_check`), or None when the linear closed
        loop is unstable: one set of runs for the requirements table and the time section."""
        def compute():
            d = self.design()
            if not d.margins.closed_loop_stable:
                return None
            from ..studies.actuator import actuator_check
            return actuator_check(self.scene, d)
        return self.result("actuator", compute)


def describe_kind(scene) -> str:
    """A few words on what a scene describes."""
    if scene.mechanism is not None:
        return f"a multi-axis mechanism ({type(scene.mechanism).__name__})"
    if scene.roller_screw:
        return f"a {len(scene.roller_screw)}-stage planetary roller screw"
    if scene.stages:
        return "a drivetrain without a motor"
    return "no drivetrain"
