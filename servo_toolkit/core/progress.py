"""Progress bars (tqdm) that show where someone watches: a terminal or Jupyter.

A bar is drawn in a Jupyter kernel (as a widget) and on a stderr that is a terminal; a CI
log or a redirected stderr gets none of tqdm's carriage returns and cursor escapes.
"""

from __future__ import annotations

import sys


def in_notebook() -> bool:
    """True inside a Jupyter (IPython) kernel, where tqdm.auto draws a widget."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return False
    try:
        shell = ipython.get_ipython()
    except Exception:  # noqa: BLE001 - no shell: not a notebook
        return False
    return shell is not None and "IPKernelApp" in getattr(shell, "config", {})


def watched(stream=None) -> bool:
    """True when a progress bar would be seen: in Jupyter, or on a terminal ``stream``
    (default: stderr)."""
    if in_notebook():
        return True
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream is not None and stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def progress_bar(iterable=None, *, show: bool = True, **kwargs):
    """A ``tqdm.auto`` bar over ``iterable`` (or with ``total=``), drawn only when ``show``
    and someone watches (:func:`watched`); otherwise a silent bar with the same interface."""
    from tqdm.auto import tqdm
    disable = not (show and watched(kwargs.get("file")))
    return tqdm(iterable, disable=disable, **kwargs)


__all__ = ["in_notebook", "progress_bar", "watched"]
