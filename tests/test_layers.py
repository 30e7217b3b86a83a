"""The package follows the data: every import points down the pipeline, no cycles.

The layer order is written once, here (and shown in docs/guide/architecture.md): a module may
import from its own layer's package or from a layer before it, never from one after it.
``servo_toolkit/__init__.py`` (the lazy top-level names), the CLI's command registry and the
registry of study kinds (``scene/study_kind.py``: the scene defines a study kind's interface,
the studies' ``kind.py`` modules and installed packages provide it, and the scene imports
their runners by name only when a study runs) are the only places that may name a module by
string.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "servo_toolkit"

#: the pipeline, first to last; a package may import only from itself and from those before it
LAYERS = ("errors", "core", "lti", "_physics", "display", "components", "drivetrain", "scene", "plant", "loop", "sim",
          "studies", "identify", "export", "report", "tuner", "cli", "__main__")


def _modules():
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = (path, parts[-1] == "__init__")
    return out


MODULES = _modules()


def _imports(name):
    """(line, imported module) of every toolkit import in a module, lazy ones included."""
    path, is_pkg = MODULES[name]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    here = name.split(".") if is_pkg else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            if node.level:
                base = ".".join(here[: len(here) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            if base.split(".")[0] != "servo_toolkit":
                continue
            for alias in node.names:
                full = f"{base}.{alias.name}"
                yield node.lineno, full if full in MODULES else base
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "servo_toolkit":
                    yield node.lineno, alias.name


def _layer(module: str) -> int:
    parts = module.split(".")
    if len(parts) == 1:
        return -1  # the package itself: its lazy names
    return LAYERS.index(parts[1])


def test_every_module_belongs_to_a_layer():
    unknown = sorted({n.split(".")[1] for n in MODULES if "." in n} - set(LAYERS))
    assert not unknown, f"modules outside the layer order (add them to LAYERS or move them): {unknown}"


@pytest.mark.parametrize("name", [n for n in MODULES if n != "servo_toolkit"])
def test_imports_point_down_the_pipeline(name):
    mine = _layer(name)
    upward = [f"line {line}: {target}" for line, target in _imports(name)
              if _layer(target) > mine or (_layer(target) == -1 and name.split(".")[1] != "cli")]
    assert not upward, f"{name} imports from a later layer: {upward}"


def test_no_import_cycles():
    graph = {n: {t for _, t in _imports(n) if t in MODULES and t != n} for n in MODULES}
    # a package's __init__ re-exporting its own modules is not a cycle of the pipeline
    for n, (path, is_pkg) in MODULES.items():
        if is_pkg:
            graph[n] = {t for t in graph[n] if not t.startswith(n + ".")}
    state, stack, cycles = {}, [], []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles[:5])


def test_no_import_by_name_string():
    allowed = {"servo_toolkit", "servo_toolkit.cli", "servo_toolkit.scene.study_kind"}
    found = []
    for name, (path, _) in MODULES.items():
        if name in allowed:
            continue
        text = path.read_text(encoding="utf-8")
        for needle in ("import_module(", "__import__("):
            if needle in text:
                found.append(f"{name}: {needle}")
    assert not found, f"modules imported by a name string: {found}"


def test_version_is_the_package_metadata_version():
    import tomllib

    from servo_toolkit import __version__
    project = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert __version__ == project["version"]
