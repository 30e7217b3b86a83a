"""Generate the command-line reference from the argument parser itself.

Every command registered in :func:`servo_toolkit.cli.build_parser` gets a section with its
usage line, its help and every option, so the page cannot drift from the parser.
"""

from __future__ import annotations

import argparse

from generated import page_generator


def _subparsers(parser):
    for action in parser._actions:  # argparse keeps its sub-commands here
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help for a in action._choices_actions}
            for name, sub in action.choices.items():
                yield name, helps.get(name, ""), sub


def _option_rows(sub):
    rows = []
    for action in sub._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        names = ", ".join(f"`{s}`" for s in action.option_strings) or f"`{action.metavar or action.dest}`"
        if action.option_strings and action.nargs != 0:
            names += f" `{action.metavar or action.dest.upper()}`"
        text = (action.help or "").replace("|", "\\|").replace("\n", " ")
        if action.default not in (None, False, [], argparse.SUPPRESS) and "default" not in text:
            text += f" (default: `{action.default}`)"
        rows.append(f"| {names} | {text} |")
    return rows


def cli_markdown() -> str:
    """The command-line reference as Markdown."""
    from servo_toolkit.cli import build_parser
    parser = build_parser()
    out = ["# Command-line reference", "",
           "Generated from the argument parser of `servo-toolkit`; `servo-toolkit COMMAND --help` "
           "prints the same. Exit codes: 0 done (every requirement the command judges met: `check` every row, `design` "
           "its loop's, naming the rest), 1 a requirement not met, "
           "2 bad input or a run outside its validity domain (one line on stderr naming the key or "
           "option and the rule), 130 interrupted. `--json` prints one JSON object on stdout.", ""]
    for name, help_text, sub in _subparsers(parser):
        usage = " ".join(sub.format_usage().split())
        if usage.startswith("usage: "):
            usage = usage[len("usage: "):]
        out += [f"## `{name}`", "", help_text or "", "", "```text", usage, "```", ""]
        if sub.description:
            out += [sub.description, ""]
        rows = _option_rows(sub)
        if rows:
            out += ["| argument | meaning |", "| --- | --- |", *rows, ""]
    return "\n".join(out)


def setup(app):
    """Sphinx extension entry point."""
    app.connect("config-inited", page_generator("reference/cli.md", cli_markdown))
    return {"parallel_read_safe": True, "version": "1"}
