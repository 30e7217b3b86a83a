"""A series compliance (housing, mounting, shaft) and the load."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..fields import Fields, require
from .base import Jet, Spring, Stage


@dataclass(frozen=True)
class Compliance(Stage):
    """A rigid-ratio (1:1) stage that only adds a spring at its place in the chain.

    Parameters
    ----------
    name : str
    stiffness : float
        N*m/rad for rotary coordinates, N/m for linear ones.
    at : str
        ``"output"`` (the coordinate after the previous stage, the usual case).
    """

    name: str
    stiffness: float
    at: str = "output"

    def map(self, z) -> Jet:
        return Jet.linear(z, 1.0)

    def springs(self, z) -> list[Spring]:
        return [Spring(self.name, self.stiffness, Jet.linear(z, 1.0))]

    @classmethod
    def from_table(cls, f: Fields) -> "Compliance":
        """Build from a ``[[drivetrain]]`` table of kind ``compliance``."""
        stage = cls(name=f.text("name", "compliance"),
                    stiffness=f.quantity("stiffness", "N*m/rad", rule="positive"),
                    at=f.text("at", "output", choices={"output"}))
        f.check_unknown()
        return stage


@dataclass(frozen=True)
class Load:
    """What the output drives, at the output coordinate.

    Parameters
    ----------
    inertia : float
        kg*m^2 (kg for a linear output).
    hinge_moment : float
        Constant moment opposing positive motion (N*m).
    hinge_stiffness : float
        Spring moment per output angle (N*m/rad).
    damping : float
        N*m*s/rad.
    """

    inertia: float = 0.0
    hinge_moment: float = 0.0
    hinge_stiffness: float = 0.0
    damping: float = 0.0

    @classmethod
    def from_table(cls, f: Fields) -> "Load":
        """Build from a ``[load]`` table."""
        load = cls(inertia=f.quantity("inertia", "kg*m^2", 0.0, rule="nonnegative"),
                   hinge_moment=f.quantity("hinge_moment", "N*m", 0.0, rule="finite"),
                   hinge_stiffness=f.quantity("hinge_stiffness", "N*m/rad", 0.0, rule="finite"),
                   damping=f.quantity("damping", "N*m*s/rad", 0.0, rule="nonnegative"))
        require(math.isfinite(load.inertia), f.key("inertia"), "must be finite")
        f.check_unknown()
        return load
