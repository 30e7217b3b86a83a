"""The documentation stays honest: it builds without warnings, its scene reference names
every key the loader reads, and its Python examples run."""

from __future__ import annotations

import argparse
import re
import textwrap
import types
import subprocess
import sys

import pytest

from .conftest import ROOT

DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))

#: a key read by a scene table: ``f.quantity("lead", ...)``, ``opt("bandwidth", ...)``, ...
_READ = re.compile(r"\b(?:f|fields)\.(?:raw|quantity|quantity_list|integer|text|number|has)\(\s*\"([a-z_0-9]+)\"")
_HELPER = re.compile(r"\b(?:opt|span)\(\s*\"([a-z_0-9]+)\"")


def _source_keys():
    keys = set()
    for path in (ROOT / "servo_toolkit").rglob("*.py"):
        text = path.read_text()
        if "Fields" not in text and "from_table" not in text:
            continue
        keys.update(_READ.findall(text))
        keys.update(_HELPER.findall(text))
    return keys


def test_scene_reference_names_every_key_the_loader_reads():
    import scene_reference
    text = scene_reference.scene_markdown()
    documented = set(re.findall(r"^\| `([a-z_0-9]+)` \|", text, flags=re.M))
    keys = _source_keys()
    assert len(keys) > 60  # the scan itself works
    missing = sorted(keys - documented)
    assert not missing, f"keys read by the loader but not in the scene reference: {missing}"


def test_the_scene_reference_kept_in_the_repository_is_the_loaders():
    import scene_reference
    kept = (DOCS / scene_reference.PAGE).read_text()
    assert kept == scene_reference.scene_markdown(), (
        "docs/reference/scene_keys.md is stale: run python docs/_ext/scene_reference.py")


def test_every_scene_key_has_a_sentence_of_its_own():
    """What the key is, in words (the unit, default and range are in the other columns):
    no empty meaning, no bare unit, no text shared by two keys of one table."""
    import scene_reference
    text = scene_reference.scene_markdown()
    short, shared = [], []
    for section in text.split("\n## ")[1:]:
        title, seen = section.splitlines()[0], {}
        for key, meaning in re.findall(r"^\| `([a-z_0-9]+)` \|.* \| ([^|]*) \|$", section, flags=re.M):
            if len(meaning.split()) < 4:
                short.append((title, key, meaning))
            if meaning in seen.values():
                shared.append((title, key, meaning))
            seen[key] = meaning
    assert not short and not shared, (short, shared)
    for key, words in (("ambient_temperature", "Temperature of the air"), ("viscous_friction", "Viscous friction"),
                       ("coulomb_friction", "Coulomb (sliding) friction torque"), ("bandwidth", "bandwidth")):
        assert re.search(rf"^\| `{key}` \|.*{re.escape(words)}", text, flags=re.M), key


def test_scene_reference_rows_carry_units_defaults_and_rules():
    import scene_reference
    text = scene_reference.scene_markdown()
    row = re.search(r"^\| `resistance` \| (.*)$", text, flags=re.M).group(1)
    assert "`ohm`" in row and "required" in row and "positive" in row
    row = re.search(r"^\| `inductance` \| (.*)$", text, flags=re.M).group(1)
    assert "`H`" in row and "| 0 |" in row and "nonnegative" in row


def test_scene_reference_documents_the_tolerance_forms():
    import scene_reference
    text = scene_reference.scene_markdown()
    section = text[text.index("## `[tolerances]`"):]
    section = section[:section.index("\n## ", 1)]
    for form in ('`"lo:hi"`', '`"+-5 %"`', "`{sigma = ", "drivetrain.stiffness_scale", "exit 2"):
        assert form in section, form
    row = re.search(r"^\| `min_yield` \| (.*)$", section, flags=re.M).group(1)
    assert "1e-06 .. 1 |" in row and "0.99" in row


def test_cli_reference_names_every_command_and_option():
    import cli_reference

    from servo_toolkit.cli import build_parser
    text = cli_reference.cli_markdown()
    parser = build_parser()
    for name, _, sub in cli_reference._subparsers(parser):
        assert f"## `{name}`" in text
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            for opt in action.option_strings:
                assert f"`{opt}`" in text, (name, opt)


def _python_examples():
    for path in sorted(DOCS.rglob("*.md")):
        if any(part in ("reference", "notebooks", "_build") for part in path.relative_to(DOCS).parts[:-1]):
            continue
        for k, block in enumerate(re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)):
            yield pytest.param(block, id=f"{path.relative_to(DOCS)}#{k}")


@pytest.mark.parametrize("code", list(_python_examples()))
def test_python_examples_run(code, tmp_path, monkeypatch):
    (tmp_path / "scenes").symlink_to(ROOT / "scenes")  # examples name the shipped scenes
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    # a block inside a list item is indented with the item; it runs as a module does (a
    # dataclass looks its module up)
    module = types.ModuleType("__docs__")
    monkeypatch.setitem(sys.modules, "__docs__", module)
    exec(compile(textwrap.dedent(code), "<docs example>", "exec"), module.__dict__)


def test_docs_build_without_warnings(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("numpydoc")
    pytest.importorskip("myst_nb")
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(DOCS), str(tmp_path / "html")],
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    html = (tmp_path / "html" / "reference" / "scene_keys.html").read_text()
    assert "torque_constant" in html
