"""Text a user reads: docstring markup (Sphinx roles, literal backticks) turned into plain
words, a referenced constant into its value."""

from __future__ import annotations

import importlib
import re

#: ``:role:`target``` (a Sphinx cross-reference), with an optional ``~`` or ``.`` prefix
_ROLE = re.compile(r":(?:py:)?(\w+):`([^`]+)`")
_LITERAL = re.compile(r"``([^`]*)``")
_SINGLE = re.compile(r"`([^`]*)`")


def _value(target: str, package: str):
    """The value of the constant ``target`` (``~.module.NAME`` relative to ``package``), or None."""
    path = target.lstrip("~")
    if path.startswith("."):
        path = package + path
    module, _, name = path.rpartition(".")
    try:
        value = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError):
        return None
    return value if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _role(match, package: str) -> str:
    role, target = match.group(1), match.group(2).strip()
    label = re.match(r"(.*?)\s*<(.+)>$", target)
    if label:  # :func:`words <target>`
        return label.group(1)
    if role == "data":
        value = _value(target, package)
        if value is not None:
            return f"{value:g}"
    name = target.lstrip("~.")
    return name.rsplit(".", 1)[-1] if target.startswith(("~", ".")) else name


def plain(text: str, package: str = "servo_toolkit") -> str:
    """``text`` without docstring markup.

    ``:data:`NAME``` becomes the constant's value (looked up relative to ``package``), any
    other role its target's name, ````literal```` and ```x``` their content.

    Examples
    --------
    >>> plain("eta_b = :data:`~.chain_split.MIN_BACKDRIVE`", "servo_toolkit.sim")
    'eta_b = 0.1'
    >>> plain("the design plant (:mod:`servo_toolkit.plant.linear`), ``Tc tanh(w)``")
    'the design plant (servo_toolkit.plant.linear), Tc tanh(w)'
    """
    text = _ROLE.sub(lambda m: _role(m, package), str(text))
    text = _LITERAL.sub(r"\1", text)
    return _SINGLE.sub(r"\1", text)
