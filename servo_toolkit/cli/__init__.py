"""The ``servo-toolkit`` command line; one module per command in this package.

Exit codes: 0 success (and every requirement met for ``check``), 1 requirements not met,
2 bad input (the message names the scene key) or a simulation that left its validity domain
(:class:`~servo_toolkit.errors.SimulationError`, e.g. a step too large for an explicit
scheme); either way one line on stderr, no traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ..errors import SceneError, SimulationError

#: Command modules; each defines ``NAME``, ``register(subparsers)`` and ``run(args) -> int``.
COMMANDS = ("stiffness", "report", "kv", "design", "check", "simulate", "accuracy", "sweep", "reduce",
            "export", "montecarlo")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every command registered."""
    parser = argparse.ArgumentParser(prog="servo-toolkit",
                                     description="Servo control design for electromechanical actuators.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f".cmd_{name}", __name__).register(sub)
    return parser


def main(argv=None) -> int:
    """Entry point; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except SceneError as exc:
        print(f"servo-toolkit: error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"servo-toolkit: simulation error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # pragma: no cover
        return 0


def entry() -> None:
    """Console-script wrapper."""
    sys.exit(main())
