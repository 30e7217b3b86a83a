"""Helpers shared by the command modules.

The command modules import only this module, :mod:`.budget` and the standard library when
their parser is built (``servo-toolkit CMD --help``); what a command computes with (the
scene loader and its unit parser, python-control, scipy, the compiled kernels, matplotlib) is imported in
its ``run``, when it runs.
"""

from __future__ import annotations

import contextlib
import sys

from ..core.json_text import to_json
from ..errors import SceneError


def load_scene(path=None):
    """:func:`servo_toolkit.scene.loader.load_scene`, imported when a command reads its scene."""
    from ..scene.loader import load_scene as load
    return load(path)


def add_scene(parser, optional: bool = False) -> None:
    """Add the SCENE positional (the built-in reference EMA when optional and absent)."""
    if optional:
        parser.add_argument("scene", nargs="?", default=None, help="scene TOML (default: built-in EMA)")
    else:
        parser.add_argument("scene", help="scene TOML file")


def add_json(parser) -> None:
    """Add ``--json``."""
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def add_force(parser) -> None:
    """Add ``--force``: run beyond the work budget (:mod:`servo_toolkit.cli.budget`)."""
    from .budget import TIME_BUDGET_S
    parser.add_argument("--force", action="store_true",
                        help=f"run even when the work is estimated beyond the budget ({TIME_BUDGET_S / 60:.0f} min on "
                             "2 cores, or 4 GiB for one array); without it such a run is refused before it starts, "
                             "naming the option or scene key that sets its size")


def add_friction(parser) -> None:
    """Add ``--friction``: the friction model of the nonlinear runs (``ModelOptions.friction``)."""
    parser.add_argument("--friction", choices=("stick", "smooth", "off"), default=None,
                        help="friction model (default: chosen by need, friction that holds unless the reduction's "
                             "estimate of smoothing it at every node is within its budget; --full holds): 'stick' "
                             "holds exactly at rest below the breakaway (static) level and breaks away above it (the "
                             "scene's static_friction, Stribeck speed and Coulomb level on the motor, each stage and "
                             "the load); 'smooth' the motor's Coulomb friction as Tc tanh(w / 1 rad/s), never "
                             "sticking, the rest left out; 'off' viscous friction only")


def check_robustness_budget(scene, spec, robust_design: bool, samples_option, force: bool) -> None:
    """Refuse a ``[robustness]`` study (``spec``, a Robustness or None) estimated beyond the
    work budget unless ``force``; the knob named is ``--samples`` when the command line set
    the count, else the scene's ``robustness.samples``."""
    if spec is None:
        return
    from .budget import check_time, robustness_seconds
    seconds, what = robustness_seconds(scene, spec, robust_design)
    knob = "--samples" if samples_option is not None else "robustness.samples"
    check_time(seconds, knob, what, spec.samples, force)


def check_design_budget(scene, force: bool) -> None:
    """Refuse a loop design (or evaluation) on a chain of so many compliances that its margins
    on the n-mass plant are estimated beyond the work budget, unless ``force``; the knob
    named is the drivetrain, checked before any design runs."""
    from .budget import check_time, design_seconds
    seconds, what = design_seconds(scene)
    check_time(seconds, "drivetrain", what, f"{len(scene.stages)} stages", force)


def emit(args, result, text: str) -> None:
    """Print JSON (``--json``) or the text table on stdout."""
    if getattr(args, "json", False):
        sys.stdout.write(to_json(result.to_dict() if hasattr(result, "to_dict") else result) + "\n")
    else:
        sys.stdout.write(text.rstrip() + "\n")


def bounded(kind=float, low=None, high=None, *, low_open: bool = False, what: str = "a number"):
    """An argparse ``type``: a finite number of ``kind`` within [low, high] (``low_open``:
    above low), else an error naming the rule (argparse names the option; exit 2)."""
    import argparse
    import math

    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if isinstance(value, float) and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be finite (got {text})")
        if low is not None and (value <= low if low_open else value < low):
            raise argparse.ArgumentTypeError(f"must be {'above' if low_open else 'at least'} {low:g} (got {text})")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high:g} (got {text})")
        return value
    parse.__name__ = what
    return parse


def add_sine_options(parser, *, repeat: bool = False, what: str = "the sine command") -> None:
    """Add ``--amplitude`` (with units, in the output's unit) and ``--frequency`` (Hz)."""
    kw = dict(action="append") if repeat else {}
    parser.add_argument("--amplitude", metavar="AMP", **kw,
                        help=f"amplitude of {what} with units, e.g. '2 deg' or '1 mm' for an output travel "
                             "(a bare number is in deg, or mm for a travel; default 2 deg / 1 mm)"
                             + (", repeatable: one curve each" if repeat else ""))
    parser.add_argument("--frequency", metavar="HZ", **kw,
                        type=bounded(float, 0.0, 1e5, low_open=True, what="a frequency in Hz"),
                        help=f"frequency of {what} in Hz (default 8 Hz)" + (", repeatable" if repeat else ""))


def amplitudes_si(scene, texts, option: str = "--amplitude"):
    """``--amplitude`` values (one text or a list) in SI after the scene's output unit;
    None when not given. Raises SceneError naming the option and the rule: not an
    amplitude, or a sine about the operating point that leaves the stroke."""
    from ..core.output_units import output_unit
    from ..scene.study_stroke import check_amplitude
    from ..studies.run import has_motor_drivetrain
    if texts is None:
        return None
    unit = output_unit(scene)
    values = [unit.parse(t, option) for t in ([texts] if isinstance(texts, str) else texts)]
    if has_motor_drivetrain(scene):
        for a in values:
            check_amplitude(scene, a, option)
    return values[0] if isinstance(texts, str) else values


def parse_band(text, option: str = "--band", low_open: bool = False):
    """``LO:HI`` in Hz as a tuple (None for None); SceneError naming ``option`` unless
    0 <= LO < HI < inf (0 < LO with ``low_open``)."""
    if text is None:
        return None
    lo, sep, hi = text.partition(":")
    try:
        band = (float(lo), float(hi))
    except ValueError:
        band = None
    if (not sep or band is None or not 0 <= band[0] < band[1] or band[1] == float("inf")
            or (low_open and band[0] == 0)):
        raise SceneError(option, f"must be LO:HI in Hz with {'0 <' if low_open else '0 <='} LO < HI (got {text})")
    return band


def add_scheduler(parser, *, workers: bool = True, what: str = "chunks of the work") -> None:
    """Add ``--scheduler ADDRESS``: run ``what`` on an existing dask.distributed cluster."""
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None,
                        help=f"send {what} to the dask scheduler at ADDRESS (e.g. tcp://10.0.0.5:8786; needs the "
                             "cluster extra, pip install 'servo-toolkit[cluster]', and servo-toolkit of this version "
                             "on the workers); the results equal a run in one process. Without it, dask's "
                             "DASK_SCHEDULER_ADDRESS is used when set"
                             + (" and --workers is not given; --scheduler and --workers exclude each other"
                                if workers else ""))


def scheduler_of(args):
    """The dask scheduler a command sends its chunks to (a
    :class:`~servo_toolkit.core.cluster.SchedulerAddress`), or None: ``--scheduler``, else
    ``DASK_SCHEDULER_ADDRESS`` unless ``--workers`` asks for local processes. Checked before
    the scene is read; ``--scheduler`` with ``--workers`` is a SceneError."""
    from ..core.cluster import scheduler_address
    workers = getattr(args, "workers", None)
    if args.scheduler is not None and workers:
        raise SceneError("--scheduler", f"excludes --workers: the chunks run on the cluster or in local processes, "
                                        f"not both (got --workers {workers})")
    if workers:
        return None
    return scheduler_address(args.scheduler)


@contextlib.contextmanager
def study_executor(scheduler, workers=None):
    """``(executor, slots)`` for a study's ``executor=``: the dask cluster's (``scheduler``,
    a SchedulerAddress; a stderr note names it), a process pool of ``workers`` > 1, or
    ``(None, None)`` to run here. ``slots`` is how many chunks run at once. The cluster's
    client or the pool is closed on leaving."""
    if scheduler is not None:
        from ..core.cluster import open_cluster
        with open_cluster(scheduler) as cluster:
            given = "" if scheduler.key == "--scheduler" else f" (from {scheduler.key})"
            print(f"servo-toolkit: note: running chunks on the dask cluster at {cluster.address}{given}, "
                  f"{cluster.threads} worker thread{'s' if cluster.threads != 1 else ''}", file=sys.stderr)
            yield cluster.executor, cluster.threads
    elif workers and workers > 1:
        from ..core.parallel import process_pool
        with process_pool(workers) as pool:
            yield pool, workers
    else:
        yield None, None
