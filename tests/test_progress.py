"""Progress bars show where someone watches (a terminal, Jupyter) and nowhere else: a CI log
gets no carriage returns or cursor escapes. ``--version`` names the toolkit's version."""

from __future__ import annotations

import io
import subprocess
import sys

from servo_toolkit.core import progress
from servo_toolkit.core.version import __version__

from .conftest import ROOT


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_bar_is_drawn_on_a_terminal_and_not_on_a_redirected_stream():
    log, tty = io.StringIO(), _Terminal()
    for stream in (log, tty):
        for _ in progress.progress_bar(range(3), file=stream, desc="work", mininterval=0):
            pass
    assert log.getvalue() == ""
    assert "work" in tty.getvalue() and "\r" in tty.getvalue()


def test_show_false_hides_the_bar_even_on_a_terminal():
    tty = _Terminal()
    for _ in progress.progress_bar(range(3), show=False, file=tty):
        pass
    assert tty.getvalue() == ""


def test_a_jupyter_kernel_is_watched_whatever_its_streams(monkeypatch):
    assert not progress.watched(io.StringIO())
    monkeypatch.setattr(progress, "in_notebook", lambda: True)
    assert progress.watched(io.StringIO())


def test_a_command_writes_no_bar_into_a_log(tmp_path):
    """``report`` draws its section and writing bars on a terminal only: its stderr into a
    pipe (a CI log) stays free of carriage returns and cursor escapes."""
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", "report", "scenes/deflection_platform.toml",
                           "-o", str(tmp_path / "r")], cwd=ROOT, capture_output=True, text=False, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert b"servo-toolkit:" in proc.stderr  # the notes on sections that do not apply
    assert b"\r" not in proc.stderr and b"\x1b[" not in proc.stderr


def test_version_option():
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", "--version"], cwd=ROOT, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == f"servo-toolkit {__version__}"
