"""Requirement rows of the nonlinear Monte Carlo for ``servo-toolkit check``.

A scene's ``[robustness]`` may bound the worst tracking error (``max_tracking_error``, an
angle, or a length for an output travel) and the worst peak motor current
(``max_peak_current``) over the nonlinear closed-loop time runs of its variants
(:func:`~.run.montecarlo`, the checked design's controller). They become the rows
``robust_tracking_error`` and ``robust_peak_current``. A variant whose run failed (a
non-finite state, the stroke end, or a step outside its stability region) has no figure to
judge: the check raises :class:`~servo_toolkit.errors.SimulationError` naming the variant
and the reason (exit 2), never a row failed on a non-finite figure.
"""

from __future__ import annotations

import numpy as np

from ...errors import SimulationError
from ...loop.requirements import Requirement, check, time_requirements


def montecarlo_requirements(scene, spec) -> list[Requirement]:
    """The Monte Carlo requirements ``spec`` (a :class:`~servo_toolkit.scene.tables.Robustness`)
    sets, in display units (deg or mm, A); empty when it sets none
    (:func:`servo_toolkit.loop.requirements.time_requirements` of ``[robustness]``).

    Raises
    ------
    SceneError
        ``robustness.max_tracking_error`` given as an angle for an output travel, or as a
        length for an output angle.
    """
    return [] if spec is None else time_requirements(scene, spec, "robustness")


def montecarlo_checks(scene, spec, controller, *, progress: bool = False, executor=None):
    """Run the variants of ``spec`` with ``controller`` and check its Monte Carlo
    requirements; ``executor`` runs the chunks of variants (the checks do not depend on it).

    Returns
    -------
    checks : list of Check
        Empty (and nothing run) when ``spec`` sets no Monte Carlo requirement.
    result : MonteCarloResult or None
    """
    requirements = montecarlo_requirements(scene, spec)
    if not requirements:
        return [], None
    result = spec_montecarlo(scene, spec, controller, progress=progress, executor=executor)
    return result_checks(requirements, result), result


def spec_montecarlo(scene, spec, controller, *, executor=None, progress: bool = False):
    """The nonlinear time runs (:func:`~.run.montecarlo`) of the variants ``spec`` (a
    :class:`~servo_toolkit.scene.tables.Robustness`) samples, with ``controller``."""
    from .run import montecarlo
    return montecarlo(scene, spec.ranges, samples=spec.samples, seed=spec.seed, grid=spec.method == "grid",
                      controller=controller, executor=executor, progress=progress)


def result_checks(requirements, result) -> list:
    """The checks of ``requirements`` (from :func:`montecarlo_requirements`) on the variants
    of ``result``: the worst figure over the variants.

    Raises
    ------
    SimulationError
        Some variant's run failed (its step outside the RK4 stability region, a non-finite
        state, the stroke end): there is no figure to judge, so no verdict.
    """
    failed = np.flatnonzero(result.failed)
    if failed.size:
        i = int(failed[0])
        at = ", ".join(f"{k}={v[i]:.4g}" for k, v in result.values.items())
        raise SimulationError(f"the robustness Monte Carlo could not run {failed.size} of {result.count} "
                              f"variants (first: variant {i}, {at}: {result.reasons[i]}); no verdict on "
                              f"robust_tracking_error / robust_peak_current")
    worst = {"tracking_error": result.error_display, "peak_current": result.peak_current}
    return check(requirements, {k: float(np.max(v)) for k, v in worst.items()})


def check_cases(checks, result) -> list[tuple]:
    """(test name, passed, message) per Monte Carlo check, for ``check``'s table and JUnit."""
    cases = []
    for c in checks:
        i = result.worst_index(c.name)
        at = "" if i is None else "; at " + ", ".join(f"{k}={v[i]:.4g}" for k, v in result.values.items())
        failed = int(np.sum(result.failed))
        why = f"{failed} of {result.count} variants failed ({result.reasons[int(np.argmax(result.failed))]})" \
            if failed else f"achieved {c.achieved:.4g} {c.unit}"
        cases.append((f"robust_{c.name}", c.passed,
                      f"worst case over {result.count} nonlinear time runs: required {c.sense} {c.required:g} "
                      f"{c.unit}, {why}" + ("" if c.passed else f", short by {c.shortfall:.3g} {c.unit}") + at))
    return cases
