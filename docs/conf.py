"""Sphinx configuration of the servo_toolkit documentation.

Build with ``python -m sphinx -W -b html docs OUT`` (warnings are errors). The scene-file
and command-line references are generated from the loader and the argument parser at build
time (``_ext/``), the notebooks are copied in as a gallery (not executed here: CI runs them).
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))

project = "servo_toolkit"
author = "servo_toolkit developers"
copyright = "2026, servo_toolkit developers"

extensions = [
    "myst_nb",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "scene_reference",
    "cli_reference",
    "notebook_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3
nb_execution_mode = "off"

numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"
autodoc_default_options = {"members": True, "undoc-members": False}
suppress_warnings = ["myst.header"]

html_theme = "alabaster"
html_title = "servo_toolkit"

# notebooks are stripped of outputs and kernel metadata; their code is Python
suppress_warnings += ["myst-nb.lexer"]


def _escape_bars(app, what, name, obj, options, lines):
    """Docstrings write absolute values as plain text (``|L|``, ``|1 / (1 + L)|``);
    reStructuredText would read them as substitutions. Escape every bar outside inline
    literals and roles."""
    import re
    literal = re.compile(r"(``.*?``|`[^`]*`)")
    for i, line in enumerate(lines):
        parts = literal.split(line)
        lines[i] = "".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


def setup(app):
    """Hooks of this documentation."""
    app.connect("autodoc-process-docstring", _escape_bars)
