"""Scene key paths: the numeric keys a scene's loader reads (``motor.resistance``,
``drivetrain[3].stiffness``, ``load.hinge_moment`` ...), resolved to their SI unit, rule,
conditioned range and value, and the scene built again with new values.

A new value is put into the scene's own table (in SI, as a bare number) and the scene is
built again by the loader, so that everything the loader derives from the key (reflected
inertias, stiffness chain, checks) follows the new value exactly as it would for a file
that wrote it. Fitting (:mod:`servo_toolkit.identify.params`) and tolerances
(:mod:`servo_toolkit.scene.tolerances`) both name scene keys this way.
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass

from ..errors import SceneError
from ..core.fields import KeyRead, recording_reads

#: tables whose keys describe the built actuator (the others set studies, requirements,
#: display or the variations themselves)
PHYSICAL_TABLES = ("motor", "drivetrain", "load", "sensors")
#: tables that never hold a physical parameter
NOT_PHYSICAL = ("studies", "requirements", "robustness", "tolerances", "display", "duty_cycle", "name",
                "description")
#: usual other names of a key (the load's mass of an output travel is its ``inertia``; the
#: motor's catalogue symbols), suggested for a key the scene does not have
SYNONYMS = {"mass": "inertia", "moment_of_inertia": "inertia", "j": "inertia", "kt": "torque_constant",
            "ke": "back_emf_constant", "r": "resistance", "l": "inductance", "friction": "coulomb_friction",
            "stiction": "static_friction", "k": "stiffness"}
_INDEX = re.compile(r"\[(\d+)\]")


@dataclass(frozen=True)
class KeyPath:
    """One numeric scene key (also a fit parameter,
    :data:`servo_toolkit.identify.params.Parameter`).

    Attributes
    ----------
    key : str
        Key path as error messages print it, e.g. ``drivetrain[3].stiffness``.
    table : str
        Path of its table, e.g. ``drivetrain[3]``.
    name : str
        Key inside the table.
    unit : str
        SI unit the loader converts it to (``"dimensionless"`` for a number, ``"1"`` for an
        integer).
    value : float
        Value in the scene (SI; the loader's default when the file does not write it).
    written : object
        The value as the file writes it (None when the loader's default applies).
    rule : str or None
        The loader's sign rule (``"positive"``, ``"nonnegative"``, ``"finite"``, ``"at
        least N"`` for an integer).
    bounds : tuple or None
        ``(low, high)``: the range the model is conditioned for
        (:mod:`servo_toolkit.core.ranges`).
    integer : bool
        An integer key (an encoder's bits): varied values are rounded.
    """

    key: str
    table: str
    name: str
    unit: str
    value: float
    written: object = None
    rule: str | None = None
    bounds: tuple | None = None
    integer: bool = False

    @property
    def signed(self) -> bool:
        """The loader accepts either sign (a constant force or moment, rule ``"finite"``):
        a fit varies the value itself, not its logarithm."""
        return self.rule == "finite"


def split_key(key: str) -> tuple[str, str]:
    """``"drivetrain[3].stiffness"`` -> ``("drivetrain[3]", "stiffness")``."""
    table, _, name = key.rpartition(".")
    return table, name


def table_of(data: dict, table: str, create: bool = False):
    """The dict of ``table`` (``motor``, ``drivetrain[3]``, ``studies.step``) inside ``data``
    (None when absent and not ``create``)."""
    node = data
    for part in table.split("."):
        name, _, index = part.partition("[")
        if not isinstance(node, dict):
            return None
        if name not in node:
            if not create:
                return None
            node[name] = {}
        node = node[name]
        if index:
            i = int(index.rstrip("]"))
            if not isinstance(node, list) or i >= len(node):
                return None
            node = node[i]
    return node if isinstance(node, dict) else None


def _physical(table: str) -> bool:
    return table.split(".")[0].split("[")[0] in PHYSICAL_TABLES


class SceneKeys:
    """The numeric keys one scene's loader reads, and the scene built with new values.

    Parameters
    ----------
    data : dict
        The scene's parsed TOML (copied; ``[tolerances]`` and ``[robustness]`` are dropped:
        a variant is the actuator, not the variations).
    source : str, optional
        File the scene came from (for error messages).
    build : callable
        ``build(data, source)`` -> Scene: the loader's
        :func:`~servo_toolkit.scene.loader.scene_from_dict`.
    """

    def __init__(self, data: dict, source: str | None = None, build=None):
        if build is None:
            raise TypeError("SceneKeys needs the loader's scene_from_dict as build")
        self.build = build
        scene_from_dict = build
        self.data = {k: copy.deepcopy(v) for k, v in data.items() if k not in ("tolerances", "robustness")}
        self.source = source
        with recording_reads() as reads:
            self.base = scene_from_dict(copy.deepcopy(self.data), source)
        self.reads = tuple(reads)
        self._si = _in_si(self.data, self.reads)
        self._quantities = {f"{r.table}.{r.key}": r for r in reads if r.reader == "quantity"}
        self._integers = {f"{r.table}.{r.key}": r for r in reads if r.reader == "integer"}
        self._lists = {f"{r.table}.{r.key}" for r in reads if r.reader == "quantity list"}
        self._other = {f"{r.table}.{r.key}" for r in reads if r.reader in ("text", "value")}

    def known(self, integers: bool = True) -> list[str]:
        """The physical numeric keys of this scene, sorted."""
        keys = [k for k, r in self._quantities.items() if _physical(r.table)]
        if integers:
            keys += [k for k, r in self._integers.items() if _physical(r.table)]
        return sorted(set(keys))

    @staticmethod
    def _unknown_rule(key: str, what: str, known: list) -> str:
        """The rule for a key that is not known: the nearest known key (by spelling, or by a
        usual other name of the same table's key: a travel's ``load.mass`` is
        ``load.inertia``), then the known keys of the same table, or the tables that have
        some when the table has none."""
        import difflib
        table, _, name = key.rpartition(".")
        same = [k for k in known if k.rpartition(".")[0] == table]
        alias = f"{table}.{SYNONYMS[name]}" if name in SYNONYMS and table else None
        close = [alias] if alias in known else difflib.get_close_matches(key, known, n=1, cutoff=0.8)
        hint = f"did you mean {close[0]}? " if close else ""
        if same:
            return f"{hint}not {what}; {table} has {', '.join(same)}"
        tables = sorted({k.rpartition(".")[0] for k in known})
        return (f"{hint}not {what}; the tables with numeric keys are {', '.join(tables)} "
                "(docs/reference/scene_keys.md lists every key)")

    def resolve(self, key: str, *, where: str | None = None, integers: bool = True,
                what: str = "a numeric key of this scene", excluded=()) -> KeyPath:
        """The key path ``key``.

        Parameters
        ----------
        key : str
        where : str, optional
            Key path the error names (default ``key``).
        integers : bool
            Accept integer keys.
        what : str
            What the key must be, for the error message (the known keys of its table, or the
            tables, follow it).
        excluded : collection of str
            Keys left out of the known keys the error lists (keys the caller refuses).

        Raises
        ------
        SceneError
            Not a scalar numeric key of a physical table (motor, drivetrain, load,
            sensors), naming the keys that are.
        """
        where = where or key
        read = self._quantities.get(key) or (self._integers.get(key) if integers else None)
        if read is None:
            if key in self._lists or any(key.startswith(f"{k}[") for k in self._lists):
                raise SceneError(where, "a list, not a scalar quantity; name a scalar key")
            base = re.sub(r"\[\d+\]$", "", key)  # an element of a list names the list
            if base in self._other:
                table, _, name = base.rpartition(".")
                value = (table_of(self.data, table) or {}).get(name)
                kind = ("a list of whole numbers (counts such as a gear's teeth are exact)"
                        if isinstance(value, list) and all(isinstance(v, int) for v in value) else
                        "a list" if isinstance(value, list) else "a table" if isinstance(value, dict) else "a text")
                raise SceneError(where, f"not a numeric key that can vary: {kind}")
            if key.split(".")[0].split("[")[0] in NOT_PHYSICAL:
                raise SceneError(where, "not a physical parameter of the actuator; name motor, drivetrain, load "
                                        "or sensors keys")
            raise SceneError(where, self._unknown_rule(key, what, [k for k in self.known(integers) if k not in excluded]))
        if not _physical(read.table):
            raise SceneError(where, "not a physical parameter of the actuator; name motor, drivetrain, load or "
                                    "sensors keys")
        table = table_of(self.data, read.table)
        written = table.get(read.key) if table is not None else None
        integer = read.reader == "integer"
        return KeyPath(key, read.table, read.key, "1" if integer else read.unit, self._value(key, read),
                       written, read.rule, None if integer else read.bounds, integer)

    def _value(self, key: str, read: KeyRead) -> float:
        from ..core.units import parse_quantity
        table = table_of(self.data, read.table)
        if table is not None and read.key in table:
            raw = table[read.key]
        else:
            raw = read.default
        if read.reader == "integer":
            return float(raw)
        return float(raw) if isinstance(raw, (int, float)) else parse_quantity(raw, read.unit, key)

    def data_with(self, values: dict) -> dict:
        """A copy of the scene's tables with ``values`` (key path -> SI value) written in
        (its quantities already converted to SI numbers: the loader reads them as such)."""
        data = copy.deepcopy(self._si)
        for key, v in values.items():
            table, name = split_key(key)
            read = self._integers.get(key)
            target = table_of(data, table, create=True)
            if target is None:
                raise SceneError(key, "its table is not in the scene")
            target[name] = int(round(float(v))) if read is not None else float(v)
        return data

    def scene(self, values: dict):
        """The scene with ``values`` (key path -> SI value) written into its tables."""
        return self.build(self.data_with(values), self.source)


def _in_si(data: dict, reads) -> dict:
    """A copy of ``data`` with every quantity of the actuator's tables that is written as text
    replaced by its SI number (a bare number is SI to the loader), so that building the scene
    again does not parse units: the same scene, several times faster to build."""
    from ..core.units import parse_quantity
    out = copy.deepcopy(data)
    for r in reads:
        if r.reader not in ("quantity", "quantity list") or not _physical(r.table) or r.unit in (None, "dB"):
            continue
        table = table_of(out, r.table)
        if table is None or r.key not in table:
            continue
        value = table[r.key]
        key = f"{r.table}.{r.key}"
        if r.reader == "quantity" and isinstance(value, str):
            table[r.key] = parse_quantity(value, r.unit, key)
        elif r.reader == "quantity list" and isinstance(value, list):
            table[r.key] = [parse_quantity(v, r.unit, f"{key}[{i}]") if isinstance(v, str) else v
                            for i, v in enumerate(value)]
    return out


__all__ = ["KeyPath", "NOT_PHYSICAL", "PHYSICAL_TABLES", "SceneKeys", "split_key", "table_of"]
