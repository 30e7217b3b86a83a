"""Every numeric option of every command, at its extremes: one stderr line and exit 2, or a
clean run (exit 0 or 1); never a traceback, never a hang.

The numeric options are found by introspecting the parser (``type`` a ``bounded(...)`` parser,
``float`` or ``int``), plus the numeric pieces of option strings (``--require NAME=X unit``,
``--vary NAME=LO:HI``, ``--amplitude "X deg"``, ``--sample-time "X s"``). Each run goes
through :func:`servo_toolkit.cli.main` in this process, next to options that keep an accepted
run short (a short duration, few variants, one sweep point, the estimate-only reduction);
the loop design of a scene is computed once per set of design inputs (memoized here: the
same inputs give the same design).
"""

from __future__ import annotations

import argparse
import signal

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from servo_toolkit.cli import build_parser, main

from .conftest import SCENES, memoized_designs

EMA = str(SCENES / "ema_reference.toml")
PLATFORM = str(SCENES / "deflection_platform.toml")
TOLERANCES = str(SCENES / "examples" / "ema_tolerances.toml")

#: extreme finite values, infinities and NaN, as a user types them
EXTREMES = ("1e-300", "-1e-300", "1e300", "-1e300", "inf", "-inf", "nan",
            "123456789012345678901234567890", "-123456789012345678901234567890")
#: no single run may take longer (s): a hang fails the test instead of stalling it
RUN_LIMIT_S = 300

#: command -> arguments that keep an accepted run cheap ({tmp}: a fresh folder)
BASE = {
    "stiffness": [EMA],
    "report": [PLATFORM, "-o", "{tmp}/report"],
    "kv": [EMA, "--study", "kv_8hz"],
    "design": [EMA, "--linear-only", "--nominal"],
    "check": [EMA, "--linear-only", "--nominal", "--samples", "8"],
    "simulate": [EMA],
    "accuracy": [EMA],
    "sweep": [EMA, "--frequency", "20"],
    "reduce": [EMA, "--estimate-only"],
    "export": [EMA, "-o", "{tmp}/export", "--nominal"],
    "montecarlo": [EMA, "--samples", "8", "--duration", "0.02"],
    "tolerances": [TOLERANCES, "--linear-only", "--samples", "64"],
    "fit": None,  # no numeric option
    "frf": None,  # needs a log file; its --segment bounds are tested in test_identify_frf.py
    "excite": [EMA, "-o", "{tmp}/stimulus.csv", "--resolution", "4", "--periods", "1", "--settle", "0"],
    "new": None,  # no numeric option (writes a starting scene)
    "size": None,  # no numeric option (the duty cycle's numbers are scene keys, tested in test_sizing*.py)
    "study": None,  # no numeric option (a study's numbers are scene keys)
}
#: options whose base argument the case replaces
REPLACES = {("kv", "--frequency"): ["--study", "kv_8hz"], ("kv", "--amplitude"): ["--study", "kv_8hz"],
            ("sweep", "--frequency"): ["--frequency", "20"], ("check", "--samples"): ["--samples", "8"],
            ("montecarlo", "--samples"): ["--samples", "8"], ("montecarlo", "--duration"): ["--duration", "0.02"],
            ("tolerances", "--samples"): ["--samples", "64"], ("excite", "--periods"): ["--periods", "1"],
            ("excite", "--settle"): ["--settle", "0"]}
#: numeric pieces of string options: option -> templates of the value ({x} the number)
PIECES = {
    "--require": ["bandwidth={x} Hz", "phase_margin={x} deg", "gain_margin={x} dB", "sensitivity_peak={x} dB",
                  "phase_lag_at_bandwidth={x} deg"],
    "--vary": ["load_inertia=0:{x}", "load_inertia={x}:1", "stiffness={x}:1.2", "stiffness=0.8:{x}"],
    "--amplitude": ["{x} deg", "{x}"],
    "--sample-time": ["{x} s"],
    "--current-sample-time": ["{x} s"],
}
#: a second option a case needs to mean anything (``--dt`` applies to the fixed-step methods)
WITH = {("simulate", "--dt"): ["--method", "rk4"]}


def _is_numeric(action) -> bool:
    kind = action.type
    return kind in (int, float) or "bounded" in getattr(kind, "__qualname__", "")


def numeric_cases():
    """``(command, option, templates)`` for every numeric option of every command."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    cases = []
    for command, p in sub.choices.items():
        if BASE[command] is None:
            continue
        for action in p._actions:
            if not action.option_strings or action.choices is not None:
                continue
            option = action.option_strings[-1]
            if _is_numeric(action):
                cases.append((command, option, ("{x}",)))
            elif option in PIECES:
                cases.append((command, option, tuple(PIECES[option])))
    return cases


CASES = numeric_cases()


def test_every_command_with_a_numeric_option_is_covered():
    commands = {c for c, _, _ in CASES}
    assert commands == {c for c, base in BASE.items() if base is not None}
    assert ("montecarlo", "--duration", ("{x}",)) in CASES and ("simulate", "--dt", ("{x}",)) in CASES


@pytest.fixture(scope="module", autouse=True)
def memoized_design():
    """The loop design once per set of inputs (it is deterministic): keeps each run short."""
    with memoized_designs():
        yield


def _alarm(signum, frame):
    raise TimeoutError(f"a run took longer than {RUN_LIMIT_S} s")


def run_cli(argv, capsys):
    """(exit code, stderr) of one in-process run; argparse's exit counts as its code."""
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(RUN_LIMIT_S)
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    captured = capsys.readouterr()
    return code, captured.err


def assert_clean(argv, code, err):
    assert "Traceback" not in err, (argv, err)
    assert code in (0, 1, 2), (argv, code, err)
    if code == 2:
        lines = [ln for ln in err.splitlines() if ln.startswith("servo-toolkit:")
                 and not ln.startswith(("servo-toolkit: compiling", "servo-toolkit: note:"))]
        assert len(lines) == 1, (argv, err)


def _argv(command, option, template, value, tmp):
    base = [a.replace("{tmp}", str(tmp)) for a in BASE[command]]
    drop = REPLACES.get((command, option))
    if drop:
        i = next(k for k in range(len(base) - 1) if base[k:k + 2] == drop)
        base = base[:i] + base[i + 2:]
    return [command, *base, *WITH.get((command, option), []), option, template.format(x=value)]


@pytest.mark.parametrize("command, option, templates", CASES, ids=[f"{c} {o}" for c, o, _ in CASES])
def test_extreme_values_are_one_line_or_a_clean_run(command, option, templates, tmp_path_factory, capsys):
    @settings(max_examples=2 if command in ("report", "export", "accuracy", "montecarlo") else 4, deadline=None,
              suppress_health_check=list(HealthCheck), derandomize=True)
    @given(template=st.sampled_from(templates), value=st.sampled_from(EXTREMES))
    def check(template, value):
        argv = _argv(command, option, template, value, tmp_path_factory.mktemp("run"))
        assert_clean(argv, *run_cli(argv, capsys))
    check()
