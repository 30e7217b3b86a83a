"""Write a generated page only when its text changed (Sphinx then rebuilds only it)."""

from __future__ import annotations

from pathlib import Path


def write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` unless it already holds it."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def page_generator(relative: str, make):
    """A Sphinx ``config-inited`` handler that writes ``make()`` to ``relative`` in the
    documentation's source folder."""
    def generate(app, config):
        write_if_changed(Path(app.srcdir) / relative, make())
    return generate
