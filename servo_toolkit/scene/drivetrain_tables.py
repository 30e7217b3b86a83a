"""How a scene's ``[[drivetrain]]`` array is read and checked: each stage table's stage and
its output friction, the rules between the stages (each stage's input is what the one
before delivers; only the stage that drives the output gives the stroke), whether the
chain's output is a travel, and a ``[load]`` given as a mass on an output angle. Used by
:mod:`.loader`.
"""

from __future__ import annotations

from ..components.stage_friction import StageFriction
from ..components.stages import STAGE_IO, STAGE_KINDS
from ..core.fields import Fields, require
from ..core.units import parse_quantity
from ..errors import SceneError


def _built(path: str, build):
    """``build()``; a Python error from a value the table's checks let through becomes a
    SceneError naming the table (any such error is a missing rule)."""
    try:
        return build()
    except SceneError:
        raise
    except (TypeError, ValueError, ArithmeticError, IndexError, KeyError, AttributeError) as exc:
        raise SceneError(path, f"invalid value ({type(exc).__name__}: {exc})") from None


def _stage(table, i: int, travel: bool):
    """The stage of ``drivetrain[i]`` and its output friction (None: none given; a cam's
    follower friction is the cam's own ``guide_friction_coefficient``); ``travel``: the
    stage's output is a travel."""
    f = Fields(table, f"drivetrain[{i}]")
    kind = f.text("kind")
    cls = STAGE_KINDS.get(kind)
    require(cls is not None, f.key("kind"), f"unknown stage kind {kind!r}; known: {sorted(STAGE_KINDS)}")
    friction = None if kind == "cam" else _built(f.path, lambda: StageFriction.from_fields(f, travel))
    return _built(f.path, lambda: cls.from_table(f)), friction


def _stage_outputs_travel(raw_stages) -> list:
    """Per stage: True when its output is a travel (what :data:`STAGE_IO` says it delivers)."""
    have, out = "rotary", []
    for table in raw_stages:
        kind = table.get("kind") if isinstance(table, dict) else None
        # a kind that is not a string is reported by the stage's own check, not here
        give = STAGE_IO.get(kind, (None, None))[1] if isinstance(kind, str) else None
        have = give or have
        out.append(have == "travel")
    return out


def _output_is_travel(raw_stages) -> bool:
    """True when the chain's output coordinate is a travel (it ends in a screw); a chain
    ending in a cam keeps the cam angle as its coordinate."""
    if raw_stages and raw_stages[-1].get("kind") == "cam":
        return False
    have = "rotary"
    for table in raw_stages:
        give = STAGE_IO.get(table.get("kind"), (None, None))[1]
        have = give or have
    return have == "travel"


def _check_load_not_mass(table, raw_stages) -> None:
    """A ``[load]`` whose ``inertia`` is written as a mass (kg) is a load on an output travel:
    refuse it, naming that rule, when the drivetrain does not end in a travel (or is missing),
    rather than reporting a dimension mismatch against kg*m^2."""
    value = table.get("inertia") if isinstance(table, dict) else None
    if not isinstance(value, str):  # a bare number is in kg*m^2 (SI) for an output angle
        return
    try:
        parse_quantity(value, "kg", "load.inertia")
    except SceneError:
        return  # not a mass: Load.from_table reports it
    if not raw_stages:
        where = "[[drivetrain]] is missing"
    else:
        last = raw_stages[-1].get("kind") if isinstance(raw_stages[-1], dict) else None
        where = (f"the drivetrain's output is an angle (drivetrain[{len(raw_stages) - 1}] is a {last}): "
                 "give the load's inertia in kg*m^2")
    raise SceneError("load.inertia", f"a load given as a mass ({value!r}) needs a drivetrain ending in a "
                                     f"travel output (a ball screw); {where}")


def check_stage_order(raw_stages) -> None:
    """Each stage's input must be what the previous stage delivers (the motor: a rotary
    shaft): a screw turns a shaft into travel, a linkage travel into an angle."""
    have, prev = "rotary", "the motor"
    for i, table in enumerate(raw_stages):
        kind = table.get("kind")
        need, give = STAGE_IO.get(kind, (None, None))
        require(need is None or need == have, f"drivetrain[{i}].kind",
                f"a {kind} stage takes a {need} input, but {prev} delivers {have} "
                f"({'a screw or cam turns a shaft into travel, a linkage travel into an angle'})")
        if give is not None:
            have, prev = give, f"drivetrain[{i}] ({kind})"


def check_stroke_stage(raw_stages) -> None:
    """A ``stroke`` is the range of the output: only the stage that drives it (the last
    one, compliances aside) may give one."""
    kinds = [t.get("kind") for t in raw_stages]
    last = max((i for i, k in enumerate(kinds) if k != "compliance"), default=0)
    for i, table in enumerate(raw_stages):
        require(i >= last or "stroke" not in table, f"drivetrain[{i}].stroke",
                f"the stroke is the range of the output: give it on the stage that drives the output, "
                f"drivetrain[{last}] ({kinds[last]})")
