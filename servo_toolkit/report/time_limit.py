"""A wall-time limit per report section, so that one slow or stuck study cannot hold the
report back (the section then says that it was stopped, and why)."""

from __future__ import annotations

import contextlib
import signal
import threading

from .section import NotAvailable


class SectionTimeout(NotAvailable):
    """A section ran past the report's time limit per section."""


def _can_alarm() -> bool:
    return (hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
            and signal.getitimer(signal.ITIMER_REAL)[0] == 0.0)


@contextlib.contextmanager
def time_limit(seconds: float | None, what: str = "this section"):
    """Raise :class:`SectionTimeout` in the block once ``seconds`` of wall time have passed.

    The limit interrupts Python code (including the right-hand sides that compiled solvers
    call back); it is a no-op when ``seconds`` is None, outside the main thread, where the
    platform has no interval timer, or when another interval timer is already running.

    Parameters
    ----------
    seconds : float or None
    what : str
        Named in the error message.
    """
    if not seconds or not _can_alarm():
        yield
        return

    def _stop(signum, frame):
        raise SectionTimeout(f"{what} was stopped after {seconds:g} s, the report's time limit per section "
                             "(servo-toolkit report --section-time-limit S raises it)")

    previous = signal.signal(signal.SIGALRM, _stop)
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
