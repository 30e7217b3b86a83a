"""Many closed-loop variants, compiled: every variant the single run's RK4 loop.

Every variant is a row of a parameter matrix ``P`` (n_variants, nP) built by the model code
(:mod:`.variants`), with its own initial state and, where its tables differ (a rigid chain
whose load inertia varies), its own stroke tables (``T[tix[v]]``). :func:`run_variants`
runs them on worker threads without the interpreter lock, each through the same
right-hand side, controller sample and RK4 loop as a single :func:`servo_toolkit.sim.run`
(``servo_toolkit/_physics/batch.h``): one physics, and a variant's numbers do not depend on
the thread that ran it. Instead of traces a variant keeps its figures (largest |tracking
error|, peak |current|, whether a limit was reached) and the states where its step is
checked (peak current, largest drivetrain deflection, the end); a non-finite state or the
stroke end stops that variant only.

:func:`jacobians` gives d(rhs)/dx by central differences at states of the variants
(:func:`servo_toolkit.sim.stability.jacobian` is its face for one state).
"""

from __future__ import annotations

from .._physics._kernels import jacobians, run_variants, variant_run  # noqa: F401
from .layout import (F_CUR, F_ERR, F_SAT, F_STATUS, F_STEP, F_TAU, NFIG, NSNAP, S_DEFLECTION,  # noqa: F401 - re-exported
                     S_END, S_PEAK)

__all__ = ["jacobians", "run_variants", "variant_run"]
