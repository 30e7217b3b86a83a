"""Extreme but finite values: every numeric key of every shipped scene, set to 1e-300 ...
1e300 of either sign, is refused when the scene loads with one line naming the key and the
range its model is conditioned for, or runs cleanly through ``check``, ``simulate`` and
``sweep`` (exit 0 or 1, or one line and exit 2). Unit strings are quantities, never
arithmetic."""

from __future__ import annotations

import copy
import re
import tomllib

import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.scene.loader import load_scene, scene_from_dict

from .conftest import SCENE_FILES, SCENES, memoized_designs
from .test_bad_input import dumps, run

EMA = tomllib.loads((SCENES / "ema_reference.toml").read_text())
SHIPPED = {p.name: tomllib.loads(p.read_text()) for p in SCENE_FILES}
EXTREMES = (1e-300, -1e-300, 1e300, -1e300, 1e-30, 1e30)
_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def _numeric_leaves(data, path=()):
    """Key paths of every number and every quantity string (lists included)."""
    if isinstance(data, dict):
        for k, v in data.items():
            if path or k not in ("name", "description"):
                yield from _numeric_leaves(v, path + (k,))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            yield from _numeric_leaves(v, path + (i,))
    elif (isinstance(data, (int, float)) and not isinstance(data, bool)) or \
            (isinstance(data, str) and _NUMBER.match(data)):
        yield path


def _set(data, path, x):
    """``data`` with the number at ``path`` replaced by ``x`` (a quantity keeps its unit)."""
    data = copy.deepcopy(data)
    target = data
    for p in path[:-1]:
        target = target[p]
    old = target[path[-1]]
    target[path[-1]] = _NUMBER.sub(repr(x), old, count=1) if isinstance(old, str) else x
    return data


def _key(path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


MUTATIONS = [(name, path, x) for name, data in sorted(SHIPPED.items()) for path in _numeric_leaves(data)
             for x in EXTREMES]


def _load(name, path, x):
    return scene_from_dict(_set(SHIPPED[name], path, x), name)


@pytest.fixture(scope="module")
def mutation_loads():
    """``(scene, key path, value, SceneError or None)`` of every mutation, each loaded once
    (any other exception fails the tests that use it)."""
    out = []
    for name, path, x in MUTATIONS:
        try:
            _load(name, path, x)
        except SceneError as exc:
            out.append((name, path, x, exc))
            continue
        out.append((name, path, x, None))
    return out


@pytest.fixture(scope="module")
def accepted(mutation_loads):
    return [(name, path, x) for name, path, x, exc in mutation_loads if exc is None]


def test_every_extreme_value_loads_or_names_its_key_and_range(mutation_loads):
    assert len(MUTATIONS) > 1000
    for name, path, x, exc in mutation_loads:
        if exc is not None:
            text = str(exc)
            assert "\n" not in text, (name, path, x, text)
            if abs(x) in (1e300, 1e30) and "integer" not in exc.rule:
                # a huge value names the key it was given at, or the chain it breaks
                top = _key(path[:2]) if path[0] in ("drivetrain", "stages") else _key(path[:1])
                assert exc.key.startswith(top), (name, path, x, text)


def test_what_loads_is_a_value_that_means_zero_or_nothing_extreme(accepted):
    # only magnitudes that are zero for the model (1e-300, 1e-30 of a signed or optional key) load
    assert all(abs(x) < 1 for _, _, x in accepted), [a for a in accepted if abs(a[2]) >= 1]


#: at most this many accepted mutations go through the commands (spread over the list)
RUNS = 6


def test_accepted_extremes_run_cleanly_through_the_commands(accepted, tmp_path):
    pick = accepted[:: max(1, len(accepted) // RUNS)][:RUNS]
    for i, (name, path, x) in enumerate(pick):
        scene = tmp_path / f"m{i}.toml"
        scene.write_text(dumps(_set(SHIPPED[name], path, x)))
        one_point = ["--frequency", "8"] if "motor" in SHIPPED[name] else []
        for argv in (["check", str(scene), "--linear-only", "--nominal", "--samples", "8"],
                     ["simulate", str(scene)], ["sweep", str(scene), *one_point]):
            code, lines = run(argv)
            assert code in (0, 1, 2) and not any("Traceback" in ln for ln in lines), (argv, code, lines)
            if code == 2:
                assert len([ln for ln in lines if "error" in ln.split(":")[1]]) == 1, (argv, lines)


@pytest.mark.parametrize("path, value, key, words", [
    (("drivetrain", 0, "efficiency"), 1e-300, "drivetrain[0].efficiency", "[0.01, 1]"),
    (("drivetrain", 1, "nut_mass"), "1e30 kg", "drivetrain[1].nut_mass", "[1e-09, 1e+06] kg"),
    (("motor", "resistance"), "1e15 ohm", "motor.resistance", "[0.001, 10000] ohm"),
    (("motor", "resistance"), "1e-6 ohm", "motor.resistance", "[0.001, 10000] ohm"),
    (("load", "inertia"), "1e30 kg*m^2", "load.inertia", "[1e-12, 1e+06] kg*m^2"),
    (("drivetrain", 0, "torsional_stiffness"), "1e-30 N*m/rad", "drivetrain[0].torsional_stiffness",
     "[0.01, 1e+12] N*m/rad"),
    (("sensors", "sample_time"), "0.1 ms / 0", "sensors.sample_time", "not an expression"),
    # 1 nH on 0.5 ohm: L/R = 2 ns, where the reference solver stalls (3e6 evaluations)
    (("motor", "inductance"), "1e-9 H", "motor.inductance", "L/R = 2e-09 s is below 1e-07 s"),
])
def test_the_reported_extremes_are_refused_at_load_time(path, value, key, words):
    data = copy.deepcopy(EMA)
    target = data
    for p in path[:-1]:
        target = target[p]
    target[path[-1]] = value
    with pytest.raises(SceneError) as err:
        scene_from_dict(data, "ema.toml")
    assert err.value.key == key and words in err.value.rule


@pytest.mark.parametrize("command", ["check", "simulate", "sweep"])
def test_a_unit_expression_is_one_line_in_every_command(tmp_path, command):
    data = copy.deepcopy(EMA)
    data["sensors"]["sample_time"] = "0.1 ms / 0"
    scene = tmp_path / "expr.toml"
    scene.write_text(dumps(data))
    code, lines = run([command, str(scene)])
    assert code == 2 and len(lines) == 1 and "sensors.sample_time" in lines[0] and "expression" in lines[0]


@pytest.mark.parametrize("text", ["1 mm / 2 s", "3 ms * 2", "1e-3 s + 1 s"])
def test_a_quantity_is_a_number_and_a_unit(text):
    from servo_toolkit.core.units import parse_quantity
    with pytest.raises(SceneError, match="not an expression"):
        parse_quantity(text, "m/s" if "mm" in text else "s", "k")


@pytest.mark.parametrize("text, unit, si", [("1 kg*m^2", "kg*m^2", 1.0), ("2 rad/s^3", "rad/s^3", 2.0),
                                            ("1e3 1/s", "1/s", 1e3), ("1 m**2", "m^2", 1.0),
                                            ("1696.8 N*m/deg", "N*m/rad", 1696.8 * 180 / 3.141592653589793)])
def test_exponents_and_reciprocals_are_still_units(text, unit, si):
    from servo_toolkit.core.units import parse_quantity
    assert parse_quantity(text, unit, "k") == pytest.approx(si, rel=1e-12)


# --- in-range values at the ends of each key's conditioned range, through every command ------


def _table_path(table: str, key: str) -> tuple:
    """``("drivetrain", 1, "nut_mass")`` of the loader's ``drivetrain[1]`` and ``nut_mass``."""
    parts = []
    for piece in table.split("."):
        head = re.match(r"^[^\[]*", piece).group(0)
        if head:
            parts.append(head)
        parts += [int(i) for i in re.findall(r"\[(\d+)\]", piece)]
    return tuple(parts) + (key,)


def _edges():
    """``(scene, key path, value)``: every numeric key the loader reads from a shipped scene
    with a range, at both ends of it in SI (the smallest nonzero magnitude and the largest;
    +-the largest for a signed key), as :mod:`servo_toolkit.core.ranges` and the components
    state them. A list key has its first entry set."""
    from servo_toolkit.core.fields import recording_reads
    out = []
    for name, data in sorted(SHIPPED.items()):
        with recording_reads() as reads:
            scene_from_dict(copy.deepcopy(data), name)
        seen = set()
        for r in reads:
            if r.written is None or r.bounds is None or r.reader not in ("quantity", "number", "quantity list"):
                continue
            path = _table_path(r.table, r.key) + ((0,) if isinstance(r.written, list) else ())
            try:
                _get(data, path)
            except (KeyError, IndexError, TypeError):
                continue  # a key of a nested record the loader names differently (a pair of moments)
            if path in seen:
                continue
            seen.add(path)
            low, high = r.bounds
            out += [(name, path, x) for x in ((high, -high) if r.rule == "finite" else (low, high))]
    return out


def _get(data, path):
    for p in path:
        data = data[p]
    return data


def _put(data, path, x):
    data = copy.deepcopy(data)
    target = data
    for p in path[:-1]:
        target = target[p]
    target[path[-1]] = x
    return data


EDGES = _edges()


@pytest.fixture(scope="module")
def edge_loads():
    """``(scene, key path, value, SceneError or None)`` of every range end of :data:`EDGES`."""
    out = []
    for name, path, x in EDGES:
        try:
            scene_from_dict(_put(SHIPPED[name], path, x), name)
        except SceneError as exc:
            out.append((name, path, x, exc))
            continue
        out.append((name, path, x, None))
    return out


@pytest.fixture(scope="module")
def accepted_edges(edge_loads):
    """Every range end of :data:`EDGES` that loads (a scene accepted with it)."""
    return [(name, path, x) for name, path, x, exc in edge_loads if exc is None]


def test_every_range_end_loads_or_names_its_key(edge_loads, accepted_edges):
    """A value at an end of its key's range is inside the range: it loads, or a rule that
    joins it to another key (a stroke the linkage cannot reach, a time constant, a duty cycle
    past the stroke) refuses it in one line naming a key of the same scene."""
    assert len(EDGES) > 400
    for name, path, x, exc in edge_loads:
        if exc is not None:
            assert "\n" not in str(exc) and exc.key, (name, path, x, str(exc))
            assert "conditioned for (got" not in exc.rule or _key(path) not in exc.key, (name, path, x, str(exc))
    assert len(accepted_edges) > 300


def _errors(lines) -> list:
    """The error lines of a run's stderr (``servo-toolkit: error:``, ``servo-toolkit:
    simulation error:``)."""
    return [ln for ln in lines if re.match(r"servo-toolkit: (\w+ )?error:", ln)]


#: command -> arguments that keep a run short ({tmp}: a fresh folder)
EDGE_COMMANDS = {
    "stiffness": [], "design": ["--linear-only"], "check": ["--nominal", "--samples", "8"],
    "simulate": [], "sweep": ["--frequency", "8"], "kv": [], "reduce": ["--estimate-only"], "accuracy": [],
    "export": ["-o", "{tmp}/export"], "montecarlo": ["--samples", "4", "--duration", "0.02"], "size": ["--no-sweep"],
    "report": ["-o", "{tmp}/report"],
}
#: the mutations every command runs (a deterministic spread over the accepted range ends of the
#: scenes with a loop, and one of a scene without, whose report is quick); report runs on the
#: latter only (the others' reports are the same computations as the commands' own)
EDGE_PICKS = ("ema_sizing.toml", "deflection_platform.toml")


def _edge_runs():
    runs = []
    for k, scene in enumerate(EDGE_PICKS):
        mine = []
        for name, path, x in EDGES:
            if name != scene:
                continue
            try:
                scene_from_dict(_put(SHIPPED[name], path, x), name)
            except SceneError:
                continue
            mine.append((name, path, x))
        runs.append(mine[(7 * k + 3) % len(mine)])
    return runs


@pytest.fixture(scope="module")
def memoized_design():
    """The loop design once per mutation (it is deterministic): the commands share it."""
    with memoized_designs():
        yield


@pytest.mark.parametrize("mutation", _edge_runs(), ids=lambda m: f"{m[0]}:{_key(m[1])}={m[2]:g}")
def test_range_ends_run_cleanly_through_every_command(mutation, memoized_design, tmp_path):
    name, path, x = mutation
    scene = tmp_path / name
    scene.write_text(dumps(_put(SHIPPED[name], path, x)))
    for command, extra in EDGE_COMMANDS.items():
        if command == "report" and name != EDGE_PICKS[-1]:
            continue
        argv = [command, str(scene), *(a.replace("{tmp}", str(tmp_path)) for a in extra)]
        code, lines = run(argv)
        assert code in (0, 1, 2) and not any("Traceback" in ln for ln in lines), (argv, code, lines)
        if code == 2:
            assert len(_errors(lines)) == 1, (argv, lines)


#: the commands that need no loop design, run at every accepted range end of every shipped
#: scene, ``size`` at every other one and ``kv`` at every eighth (its step responses are the
#: costliest)
STATIC_COMMANDS = {"stiffness": 1, "size": 2, "kv": 8}


def test_every_accepted_range_end_runs_cleanly_through_the_static_commands(accepted_edges, tmp_path):
    """Breadth: every key's range ends of every shipped scene through ``stiffness`` (and
    ``size`` and ``kv`` at a deterministic spread): a clean run, or one line and exit 2 (a
    scene without a motor-driven drivetrain or a duty cycle, a joint its friction locks);
    never a traceback."""
    assert len(accepted_edges) > 300
    ran = {command: 0 for command in STATIC_COMMANDS}
    for i, (name, path, x) in enumerate(accepted_edges):
        scene = tmp_path / name
        scene.write_text(dumps(_put(SHIPPED[name], path, x)))
        for command, every in STATIC_COMMANDS.items():
            if i % every:
                continue
            ran[command] += 1
            code, lines = run([command, str(scene), *EDGE_COMMANDS[command]])
            assert code in (0, 1, 2) and not any("Traceback" in ln for ln in lines), (
                name, _key(path), x, command, code, lines)
            if code == 2:
                assert len(_errors(lines)) == 1, (name, _key(path), x, command, lines)
    assert min(ran.values()) > 40, ran


def test_a_nut_too_heavy_for_the_two_mass_model_is_named_and_the_full_chain_runs_it(tmp_path, memoized_design):
    """A nut of 1e6 kg behind the rocker: its inertia's variation along the stroke exceeds the
    motor side's. The two-mass model (load side held at q0) cannot take it and names the stage;
    the full chain tabulates each node's inertia along the stroke, so ``simulate`` runs it."""
    from servo_toolkit.sim import ModelOptions, build_model, controller_for
    scene = tmp_path / "edge.toml"
    scene.write_text(dumps(_put(EMA, ("drivetrain", 1, "nut_mass"), "1e6 kg")))
    loaded = load_scene(scene)
    controller, _ = controller_for(loaded)
    with pytest.raises(SceneError) as exc:
        build_model(loaded, controller, ModelOptions(chain="two_mass"))
    assert exc.value.key == "drivetrain[1]" and "the ball screw: nut's inertia" in str(exc.value)
    code, lines = run(["simulate", str(scene)])
    assert code == 0 and not _errors(lines), lines


def test_a_sweep_of_an_unstable_loop_says_it_is_the_designs_verdict():
    """A load of 1e6 kg*m^2 (the end of its range): no cascade of the reference EMA holds it
    (``design`` finds no stable one); a sweep of such a loop stops with the closed loop's
    rightmost pole, a verdict on the design rather than a failed run."""
    from servo_toolkit.drivetrain.operating_point import operating_point
    from servo_toolkit.errors import SimulationError
    from servo_toolkit.loop import linear_closed_loop
    from servo_toolkit.sim import default_controller
    from servo_toolkit.studies.sweep.compute import linear_response
    data = copy.deepcopy(EMA)
    data["load"]["inertia"] = "1e6 kg*m^2"
    scene = scene_from_dict(data, "ema.toml")
    controller = default_controller(scene)
    with pytest.raises(SimulationError, match="a physical verdict on the design") as err:
        linear_response(scene, controller, [8.0])
    # the pole it names is the closed loop's rightmost (python-control's poles of the loop)
    q0 = operating_point(scene)[0]
    worst = max(linear_closed_loop(scene, controller, q0=q0).poles(), key=lambda p: p.real)
    assert worst.real > 0 and f"{worst.real:.4g} {worst.imag:+.4g}j 1/s" in str(err.value)
