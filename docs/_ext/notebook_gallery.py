"""Copy the repository's notebooks into the documentation as a gallery (not executed)."""

from __future__ import annotations

import shutil
from pathlib import Path


def _copy(app, config):
    src = Path(app.srcdir).parent / "notebooks"
    dst = Path(app.srcdir) / "notebooks"
    dst.mkdir(exist_ok=True)
    names = sorted(p.name for p in src.glob("*.ipynb"))
    for old in dst.glob("*.ipynb"):
        if old.name not in names:
            old.unlink()
    for name in names:
        if not (dst / name).exists() or (dst / name).read_bytes() != (src / name).read_bytes():
            shutil.copyfile(src / name, dst / name)
    lines = ["# Notebook gallery", "",
             "Each notebook tells one engineer's story with the toolkit; they run top to bottom in "
             "the test suite (`pytest --nbmake notebooks`). Run them yourself for the plots.", "",
             "```{toctree}", ":maxdepth: 1", "", *[f"notebooks/{n[:-6]}" for n in names], "```", ""]
    text = "\n".join(lines)
    gallery = Path(app.srcdir) / "gallery.md"
    if not gallery.exists() or gallery.read_text() != text:
        gallery.write_text(text)


def setup(app):
    """Sphinx extension entry point."""
    app.connect("config-inited", _copy)
    return {"parallel_read_safe": True, "version": "1"}
