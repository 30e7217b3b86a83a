"""Every option of every command says what it does in ``--help``."""

import argparse

import pytest

from servo_toolkit.cli import COMMANDS, build_parser


def _subparsers():
    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_option_has_help_text(command):
    silent = [a.option_strings or [a.dest] for a in _subparsers()[command]._actions
              if a.dest != "help" and not (a.help or "").strip()]
    assert silent == []


def test_simulate_help_names_every_method():
    method = next(a for a in _subparsers()["simulate"]._actions if a.dest == "method")
    assert all(f"'{m}'" in method.help for m in method.choices)
