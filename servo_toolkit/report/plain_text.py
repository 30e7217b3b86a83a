"""Text a user reads: docstring markup (Sphinx roles, literal backticks) turned into plain
words, a referenced constant into its value."""

from __future__ import annotations

import re

#: ``:role:`target``` (a Sphinx cross-reference), with an optional ``~`` or ``.`` prefix
_ROLE = re.compile(r":(?:py:)?(\w+):`([^`]+)`")
_LITERAL = re.compile(r"``([^`]*)``")
_SINGLE = re.compile(r"`([^`]*)`")


def _value(target: str, constants):
    """The number ``constants`` holds under the last name of ``target``, or None."""
    value = (constants or {}).get(target.rsplit(".", 1)[-1])
    return value if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _role(match, constants) -> str:
    role, target = match.group(1), match.group(2).strip()
    label = re.match(r"(.*?)\s*<(.+)>$", target)
    if label:  # :func:`words <target>`
        return label.group(1)
    if role == "data":
        value = _value(target, constants)
        if value is not None:
            return f"{value:g}"
    name = target.lstrip("~.")
    return name.rsplit(".", 1)[-1] if target.startswith(("~", ".")) else name


def plain(text: str, constants=None) -> str:
    """``text`` without docstring markup.

    ``:data:`NAME``` becomes the number ``constants`` (a mapping, e.g. a module's
    ``vars()``) holds under ``NAME``, any other role its target's name, ````literal```` and
    ```x``` their content.

    Examples
    --------
    >>> plain("eta_b = :data:`~.chain_split.MIN_BACKDRIVE`", {"MIN_BACKDRIVE": 0.1})
    'eta_b = 0.1'
    >>> plain("the design plant (:mod:`servo_toolkit.plant.linear`), ``Tc tanh(w)``")
    'the design plant (servo_toolkit.plant.linear), Tc tanh(w)'
    """
    text = _ROLE.sub(lambda m: _role(m, constants), str(text))
    text = _LITERAL.sub(r"\1", text)
    return _SINGLE.sub(r"\1", text)
