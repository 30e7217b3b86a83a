"""The C header of the parameter and state layout, generated from :mod:`.layout`.

The compiled kernels (``servo_toolkit/_physics``) index the flat arrays with the constants of
:mod:`servo_toolkit.sim.layout`; their header ``layout.h`` is this module's
:func:`header_text`, written by ``python -m servo_toolkit.sim.layout_header`` and checked
against it by the tests, so the Python table stays the one place a slot is defined.
"""

from __future__ import annotations

import sys
from pathlib import Path

from . import layout

#: where the header lives in the source tree
HEADER = Path(__file__).resolve().parents[1] / "_physics" / "layout.h"


def constants() -> dict[str, int | float]:
    """The layout's upper-case numeric constants, in definition order."""
    return {name: value for name, value in vars(layout).items()
            if name.isupper() and isinstance(value, (int, float)) and not isinstance(value, bool)}


def header_text() -> str:
    """``layout.h``: one ``#define`` per constant of :mod:`.layout`."""
    lines = ["/* Generated from servo_toolkit/sim/layout.py by `python -m servo_toolkit.sim.layout_header`:",
             "   edit the Python table, then regenerate (the tests check the two agree). */",
             "#ifndef SERVO_LAYOUT_H", "#define SERVO_LAYOUT_H", ""]
    for name, value in constants().items():
        text = str(value) if isinstance(value, int) else repr(float(value))
        lines.append(f"#define {name} {text}")
    lines += ["", "#endif", ""]
    return "\n".join(lines)


def main() -> int:
    HEADER.write_text(header_text())
    sys.stdout.write(f"wrote {HEADER}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
