"""Scene key paths as fit parameters: resolve ``load.inertia``, ``drivetrain[3].stiffness``,
``motor.resistance`` ... to their SI unit and value, and build the scene with new values.

A new value is put into the scene's own table (in SI, as a bare number) and the scene is
built again by the loader, so that everything the loader derives from the key (reflected
inertias, stiffness chain, checks) follows the new value exactly as it would for a file
that wrote it.
"""

from __future__ import annotations

import copy
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..errors import SceneError
from ..core.fields import recording_reads
from ..scene.loader import read_scene_text, scene_from_dict


@dataclass(frozen=True)
class Parameter:
    """One scene key to fit.

    Attributes
    ----------
    key : str
        Key path as error messages print it, e.g. ``drivetrain[3].stiffness``.
    table : str
        Path of its table, e.g. ``drivetrain[3]``.
    name : str
        Key inside the table.
    unit : str
        SI unit the loader converts it to.
    initial : float
        Value in the scene (SI).
    written : object
        The value as the file writes it (None when the loader's default applies).
    signed : bool
        The scene accepts any sign (a constant force or moment): fitted as a value, not as a
        logarithm.
    bounds : tuple or None
        ``(low, high)``: the magnitudes the loader accepts for the key, the range its model
        is conditioned for (:mod:`servo_toolkit.core.ranges`, or the component's own).
    """

    key: str
    table: str
    name: str
    unit: str
    initial: float
    written: object = None
    signed: bool = False
    bounds: tuple | None = None


def _split(key: str) -> tuple[str, str]:
    table, _, name = key.rpartition(".")
    return table, name


def _table(data: dict, table: str, create: bool = False):
    """The dict of ``table`` (``motor``, ``drivetrain[3]``, ``studies.step``) inside ``data``."""
    node = data
    for part in table.split("."):
        name, _, index = part.partition("[")
        if name not in node:
            if not create:
                return None
            node[name] = {}
        node = node[name]
        if index:
            node = node[int(index.rstrip("]"))]
    return node


class SceneTemplate:
    """A scene's tables with some keys free: :meth:`scene` builds it with given values.

    Parameters
    ----------
    scene : Scene
        A scene loaded from a file (its ``source``).
    keys : sequence of str
        Key paths to free; each must be a positive scalar quantity the loader reads, or a
        nonzero one that it accepts with either sign (``load.hinge_moment``).

    Raises
    ------
    SceneError
        A key the scene does not read (naming the keys it does), or one that is not a
        positive scalar quantity.
    """

    def __init__(self, scene, keys):
        if not scene.source:
            raise SceneError("scene", "fitting needs a scene read from a file (load_scene)")
        self.source = scene.source
        self.text = read_scene_text(Path(scene.source))
        self.data = tomllib.loads(self.text)
        with recording_reads() as reads:
            base = scene_from_dict(copy.deepcopy(self.data), self.source)
        self.base = base
        quantities = {f"{r.table}.{r.key}": r for r in reads if r.reader == "quantity"}
        lists = {f"{r.table}.{r.key}" for r in reads if r.reader == "quantity list"}
        params = []
        if not keys:
            raise SceneError("--param", "give at least one scene key to fit, e.g. load.inertia")
        if len(set(keys)) != len(keys):
            dup = next(k for k in keys if list(keys).count(k) > 1)
            raise SceneError(dup, "given twice as a fit parameter")
        for key in keys:
            read = quantities.get(key)
            if read is None:
                if key in lists or any(key.startswith(f"{k}[") for k in lists):
                    raise SceneError(key, "a list, not a scalar quantity; fit parameters are positive scalars")
                known = ", ".join(sorted(k for k in quantities if not k.startswith(("studies", "requirements", "sensors",
                                                                                     "robustness"))))
                raise SceneError(key, f"not a quantity of this scene; fit one of: {known}")
            if read.table.startswith(("studies", "requirements", "robustness", "sensors")):
                raise SceneError(key, "not a physical parameter of the plant; fit motor, drivetrain or load keys")
            table = _table(self.data, read.table)
            written = table.get(read.key) if table is not None else None
            value = self._value(key, read)
            signed = read.rule == "finite"
            if signed and not (value != 0 and abs(value) < float("inf")):
                raise SceneError(key, f"must be a nonzero finite scalar to be fitted: its magnitude sets the "
                                 f"search's scale (is {value:g} {read.unit})")
            if not signed and not (value > 0 and value < float("inf")):
                raise SceneError(key, f"must be a positive finite scalar to be fitted (is {value:g} {read.unit})")
            params.append(Parameter(key, read.table, read.key, read.unit, value, written, signed,
                                    None if read.bounds is None else tuple(float(b) for b in read.bounds)))
        self.parameters = tuple(params)

    def _value(self, key, read) -> float:
        from ..core.units import parse_quantity
        table = _table(self.data, read.table)
        if table is not None and read.key in table:
            return parse_quantity(table[read.key], read.unit, key)
        default = read.default
        return float(default) if isinstance(default, (int, float)) else parse_quantity(default, read.unit, key)

    @property
    def initial(self) -> list:
        """Initial values (SI), in parameter order."""
        return [p.initial for p in self.parameters]

    def scene(self, values):
        """The scene with the parameters set to ``values`` (SI, in parameter order)."""
        data = copy.deepcopy(self.data)
        for p, v in zip(self.parameters, values):
            _table(data, p.table, create=True)[p.name] = float(v)
        return scene_from_dict(data, self.source)
