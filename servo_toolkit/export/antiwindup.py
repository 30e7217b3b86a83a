"""The current clamp's back-calculation into the exported motion controller's integrator.

The simulation's sampled controller (:func:`servo_toolkit.sim.kernel.controller_update`)
computes ``y = C x + D u`` (plus a feedforward current), updates ``x <- A x + B u`` and, when
``|y|`` exceeds the current limit, adds ``g (clamp(y) - y)`` to the updated state, with ``g``
the controller's integrator direction (its eigenvector at z = 1) over its output gain
(:func:`servo_toolkit.sim.command_slots.with_back_calculation`). Along that direction the
state stays put (``A g = g``) and adds ``C g = 1`` A per A to every later output: the
integral gives up the clamp's excess, so the next output starts at the limit. That is a
property of the transfer function, not of the realization, so the exported biquads do the same
with the eigenvector of their own states (direct form II transposed):

* the section with the pole at z = 1 (the last one, should two have one), with zero input
  and output 1: ``s0 = 1``, ``s1 = -a2``;
* each later section in steady state on the constant it then receives, ``x``, with output
  ``y = H(1) x``: ``s0 = y - b0 x``, ``s1 = b2 x - a2 y``;

all divided by the product of the later sections' DC gains ``H(1)`` (the integrator's
contribution to i_ref). Earlier sections take nothing. A controller without a pole within
:data:`POLE_TOLERANCE` of z = 1 (the ``lead_lag`` structure), or whose integrator does not
reach i_ref, has no back-calculation, as in the simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a section pole within this of z = 1 is the integrator (the simulation's tolerance on the
#: controller's eigenvalue)
POLE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class BackCalculation:
    """Where the clamp's excess goes: ``state += gain * (clamp(i_ref) - i_ref)``.

    Attributes
    ----------
    integrator : str
        Name of the section with the pole at z = 1.
    gains : tuple
        ``(section index, state index, gain, unit)`` per state it moves (zero gains left
        out); the index counts :meth:`.blocks.Blocks.sections` in signal order, the state is
        0 or 1 of the section's direct form II transposed, the gain is in the section's
        output unit per A of excess.
    names : tuple of str
        The sections' names, in signal order.
    """

    integrator: str
    gains: tuple
    names: tuple = ()

    def vector(self, sections) -> np.ndarray:
        """The gains as one vector over every section's two states, in signal order."""
        out = np.zeros(2 * len(sections))
        for k, j, g, _ in self.gains:
            out[2 * k + j] = g
        return out

    def describe(self) -> str:
        """One line: what the clamp's excess moves, with units."""
        return (f"back-calculation into {self.integrator}: " +
                ", ".join(f"{self.names[k]} s{j} += {g:.6g} {unit} x excess" for k, j, g, unit in self.gains))

    def to_dict(self) -> dict:
        return {"integrator": self.integrator,
                "gains": [{"section": int(k), "name": self.names[k], "state": int(j), "gain": float(g), "unit": unit}
                          for k, j, g, unit in self.gains]}


def _pole_at_one(sec) -> bool:
    roots = np.roots([1.0, *sec.a]) if any(sec.a) else np.array([0.0])
    return bool(np.any(np.abs(roots - 1.0) <= POLE_TOLERANCE))


def back_calculation(sections) -> BackCalculation | None:
    """The back-calculation gains of the biquads ``sections`` (signal order, the last one's
    output i_ref in A); None without an integrator (see the module docstring)."""
    at_one = [k for k, s in enumerate(sections) if _pole_at_one(s)]
    if not at_one:
        return None
    first = at_one[-1]
    a2 = sections[first].a[1]
    states = [(first, 1.0, -a2)]
    x = 1.0
    for k in range(first + 1, len(sections)):
        b, a = sections[k].b, sections[k].a
        y = x * sum(b) / (1.0 + sum(a))
        states.append((k, y - b[0] * x, b[2] * x - a[1] * y))
        x = y
    if not (abs(x) > 1e-300 and np.isfinite(x)):
        return None
    gains = tuple((k, j, v / x, f"{sections[k].output_unit}/A")
                  for k, s0, s1 in states for j, v in ((0, s0), (1, s1)) if v != 0.0)
    return BackCalculation(sections[first].name, gains, tuple(s.name for s in sections))


__all__ = ["BackCalculation", "POLE_TOLERANCE", "back_calculation"]
