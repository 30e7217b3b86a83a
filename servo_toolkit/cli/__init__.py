"""The ``servo-toolkit`` command line; one module per command in this package.

Exit codes: 0 success (and every requirement met for ``check``; for ``design``, every row it
judges: the loop's, a note naming the scene's requirements it leaves to ``check``), 1
requirements not met,
2 bad input (the message names the scene key) or a simulation that left its validity domain
(:class:`~servo_toolkit.errors.SimulationError`, e.g. a step too large for an explicit
scheme); either way one line on stderr, no traceback. 130 interrupted by Ctrl-C (SIGINT,
"servo-toolkit: interrupted"), 143 terminated by SIGTERM (128 + 15, the shell's convention,
"servo-toolkit: terminated"): SIGTERM is turned into :class:`Terminated`, a
``KeyboardInterrupt`` raised in the main thread, so every atomic writer removes its
temporary file or folder exactly as on Ctrl-C. A closed stdout (``>&-``) or stderr writes to
nothing; it never changes the exit code.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import os
import signal
import sys
import threading
import warnings

from ..errors import SceneError, SceneWarning, SimulationError

#: Commands in help order, each with its one-line help; module ``cmd_NAME`` defines
#: ``register(subparsers)`` (with the same help) and ``run(args) -> int``.
COMMANDS = {
    "new": "write a commented scene to start from (an output angle or travel)",
    "stiffness": "series stiffness chain and compliance shares",
    "report": "HTML and PDF report of a scene (default: built-in EMA)",
    "kv": "dynamic-load factor Kv (inverse dynamics along prescribed motions)",
    "size": "size motor and screw along the scene's duty cycle: envelope, RMS, thermal, life, ratio sweep",
    "design": "loop design and margins",
    "check": "check loop requirements (exit 0 met, 1 not met, 2 bad input)",
    "simulate": "time simulation (compiled RK4, paper scheme or stiff reference)",
    "accuracy": "error against run time: RK4 step ladder vs the stiff reference",
    "sweep": "nonlinear closed-loop frequency response (sine dwell or multisine) against the linear loop",
    "reduce": ("what the scene's model leaves out for a study, why, and the measured cost "
               "(of all together and of each effect on its own)"),
    "export": "controller.json and C99 sources of the designed controller",
    "montecarlo": "nonlinear closed-loop variants (load inertia, stiffness), batched",
    "tolerances": "yield over the scene's [tolerances] and which tolerance drives it",
    "fit": "fit scene parameters to a measured frequency response or time traces",
    "excite": "an excitation for the rig's drive within the scene's limits, with the model's response to it (a file "
              "frf reads)",
    "frf": "frequency response and coherence from a time log (H1, Welch)",
    "study": "run one [studies.NAME] of any kind (built in or from an installed package)",
}


class _OneLineParser(argparse.ArgumentParser):
    """Command-line errors as one stderr line naming the option and the rule, exit 2."""

    def error(self, message):
        self.exit(2, f"servo-toolkit: error: {message}\n")


def build_parser(only=None) -> argparse.ArgumentParser:
    """The argument parser.

    Parameters
    ----------
    only : str, optional
        Register this command in full and the others by name and help alone, so that a
        command (or ``--help``) does not import the modules of every other command.
        Default: every command in full.
    """
    parser = _OneLineParser(prog="servo-toolkit",
                            description="Servo control design for electromechanical actuators.")
    from ..core.version import __version__
    parser.add_argument("--version", action="version", version=f"servo-toolkit {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_OneLineParser)
    for name, help_text in COMMANDS.items():
        if only is None or name == only:
            importlib.import_module(f".cmd_{name}", __name__).register(sub)
        else:
            sub.add_parser(name, help=help_text)
    return parser


def _command(argv) -> str:
    """The command named on the command line ("" when none is: ``--help`` or an error)."""
    args = sys.argv[1:] if argv is None else list(argv)
    first = next((a for a in args if not a.startswith("-")), "")
    return first if first in COMMANDS else ""


#: exit code of a run ended by SIGTERM (128 + 15); Ctrl-C (SIGINT) exits 130
EXIT_TERMINATED = 128 + signal.SIGTERM
EXIT_INTERRUPTED = 130


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C's KeyboardInterrupt (so the cleanup
    that runs on Ctrl-C runs on SIGTERM too)."""


def _raise_terminated(signum, frame):
    raise Terminated()


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM raises :class:`Terminated` while the command runs (main thread only; the
    previous handler is restored afterwards)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class _NullStream:
    """Where the output of a closed stream goes (``>&-``: Python's ``sys.stdout`` is None)."""

    closed = False
    encoding = "utf-8"

    def write(self, text):
        return len(text)

    def flush(self):
        pass

    def isatty(self):
        return False

    def fileno(self):
        raise OSError("the stream is closed")


class _VerdictSafeStdout:
    """stdout for a command: a reader that goes away (a closed pipe, ``| head``) never stops
    the command nor changes its exit code, a character the stream's encoding cannot take (a
    scene name with an accent under a Latin-1 or ASCII locale) is written as an escape, and any
    other failure to write (a full disk) is remembered, so that the command ends with exit 2 and
    one line instead of a traceback."""

    def __init__(self, stream):
        self._stream = _NullStream() if stream is None else stream
        self.closed_by_reader = False
        self.error = None

    def write(self, text):
        if self.closed_by_reader or self.error is not None:
            return len(text)
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self.closed_by_reader = True
        except OSError as exc:
            self.error = exc
        except UnicodeEncodeError:  # a character the stream's encoding lacks (a non-UTF-8 locale): escaped
            encoding = getattr(self._stream, "encoding", None) or "ascii"
            return self.write(text.encode(encoding, "backslashreplace").decode(encoding))
        return len(text)

    def flush(self):
        if self.closed_by_reader or self.error is not None:
            return
        try:
            self._stream.flush()
        except BrokenPipeError:
            self.closed_by_reader = True
        except OSError as exc:
            self.error = exc

    def __getattr__(self, name):
        return getattr(self._stream, name)


@contextlib.contextmanager
def _notes_on_stderr():
    """A :class:`SceneWarning` raised while the command runs is one ``servo-toolkit: note:``
    line on stderr (each once); other warnings show as Python shows them."""
    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, SceneWarning):
            print(f"servo-toolkit: note: {message}", file=sys.stderr)
        else:
            shown(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.simplefilter("default", SceneWarning)
        warnings.showwarning = show
        yield


def main(argv=None) -> int:
    """Entry point; returns the exit code (0 done, 1 a requirement not met, 2 bad input,
    130 interrupted, 143 terminated by SIGTERM). No state of stdout changes it: a closed
    pipe or a closed stdout is ignored."""
    saved_err = sys.stderr
    if sys.stderr is None:  # 2>&-: diagnostics go nowhere, the exit code stays
        sys.stderr = _NullStream()
    try:
        with _sigterm_as_interrupt():
            return _main(argv)
    except Terminated:  # SIGTERM while parsing or after the command
        print("servo-toolkit: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("servo-toolkit: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        sys.stderr = saved_err


def _interruption(exc: BaseException):
    """The Ctrl-C or SIGTERM (:class:`Terminated`) behind ``exc``, or None. Python wraps what
    a class body's ``__set_name__`` raises in a RuntimeError, so a signal that lands while a
    library defines its classes (a late import) arrives as that error's cause."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _main(argv) -> int:
    parser = build_parser(only=_command(argv))
    args = parser.parse_args(argv)
    out = _VerdictSafeStdout(sys.stdout)
    saved, sys.stdout = sys.stdout, out
    try:
        with _notes_on_stderr():
            code = int(args.run(args) or 0)
        out.flush()
    except SceneError as exc:
        hint = None
        if exc.key == "drivetrain" and "no motor-driven" in exc.rule:
            from .hints import no_drivetrain_hint
            hint = no_drivetrain_hint(args.command, getattr(args, "scene", None))
        print(f"servo-toolkit: error: {exc}" + (f"; {hint}" if hint else ""), file=sys.stderr)
        code = 2
    except SimulationError as exc:
        print(f"servo-toolkit: simulation error: {exc}", file=sys.stderr)
        code = 2
    except MemoryError:  # an estimate let through (--force) what the machine cannot hold
        print("servo-toolkit: error: out of memory: the run is larger than this machine can hold; reduce "
              "it (the work budget refuses such runs without --force)", file=sys.stderr)
        code = 2
    except Terminated:
        print("servo-toolkit: terminated", file=sys.stderr)
        code = EXIT_TERMINATED
    except KeyboardInterrupt:
        print("servo-toolkit: interrupted", file=sys.stderr)
        code = EXIT_INTERRUPTED
    except Exception as exc:
        stop = _interruption(exc)
        if stop is None:
            raise
        terminated = isinstance(stop, Terminated)
        print(f"servo-toolkit: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        code = EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
    finally:
        sys.stdout = saved
    if out.error is not None:
        print(f"servo-toolkit: error: cannot write the output to stdout: {out.error.strerror or out.error}",
              file=sys.stderr)
        return 2
    return code


def _occupy_closed_fds() -> None:
    """Open the null device on a closed fd 0, 1 or 2 (``>&-``), so that no file the command
    opens later takes that number and receives what is written to stdout or stderr."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            with contextlib.suppress(OSError):
                os.open(os.devnull, os.O_RDWR)  # the lowest free number: this fd


#: the cyclic garbage collector's first threshold in a command's process (Python's default
#: 700): a command allocates a million objects, most of them the numerical libraries'
#: modules, which live until it ends
GC_THRESHOLD = 100_000


def entry() -> None:
    """Console-script wrapper.

    A command runs once in its own process: the cyclic garbage collector runs seldom while
    the libraries load (:data:`GC_THRESHOLD`) and, once the command is done, leaves out of
    the collection at exit the objects that live until then anyway (``gc.freeze``).
    """
    _occupy_closed_fds()
    gc.set_threshold(GC_THRESHOLD, *gc.get_threshold()[1:])
    code = main()
    gc.freeze()
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except OSError:  # the reader went away: nothing left to say, and the verdict stands
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    sys.exit(code)
