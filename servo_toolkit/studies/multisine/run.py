"""Frequency response of the nonlinear loop by a periodic multisine, estimated as a rig's log is
(``sweep --method multisine``).

The command is a multisine about the operating point: equal-amplitude cosines on chosen
lines of one period (whole multiples of its fundamental, log-spaced over the band, nearest
duplicates merged) with Schroeder's phases ``-pi k (k - 1) / K`` (a low crest factor:
the peak stays near sqrt(2 K) times a line's amplitude instead of K times), scaled to the
given peak amplitude. It is one period of a periodic sampled command
(:meth:`servo_toolkit.sim.Reference.table`), sampled at the controller's sample instants,
so the controller reads it exactly. The compiled closed loop runs ``settle + periods``
periods; the records of the last ``periods`` are estimated period by period, rectangular
windows on whole periods (:func:`servo_toolkit.core.spectra.periodic_h1`: the estimator
``frf`` uses for a periodic log), at the excited lines only.

Two responses, as ``fit --response`` reads them: ``closed_loop``, position command ->
output position; ``plant``, motor current -> motor speed, both measured in the running
loop (the rig's way: the drive in current control inside its position loop). Each is
compared with its linear model at the operating point: the design's linear closed loop, and
the linear plant's mechanics times the torque constant.

The output's power at the lines the command does not excite (below the highest line) is
the loop's nonlinear distortion: zero for a linear loop; the coherence cannot show it (a
periodic steady state repeats exactly, its coherence is 1).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ...core.parallel import run_cases
from ...core.spectra import periodic_h1
from ...errors import SceneError, SimulationError
from ..sweep.points import study_points
from .result import MultisineResult

RESPONSES = ("closed_loop", "plant")
#: estimation periods by default
DEFAULT_PERIODS = 4
#: lines per decade of a band given without a number of lines (log-spaced; lines the period's
#: harmonics cannot tell apart are merged)
LINES_PER_DECADE = 10
#: the records are taken at least this many times per period of the highest line's fourth
#: harmonic's Nyquist rate (2 x 4 x f_hi): harmonics up to the 4th do not alias onto the lines
RECORDS_PER_HIGHEST = 8
#: a continuous controller's command table: samples per period of the highest line
TABLE_PER_HIGHEST = 40
#: most command samples in one period (they are copied into the model's parameters)
MAX_PERIOD_SAMPLES = 2_000_000


@dataclass(frozen=True)
class MultisinePlan:
    """The multisine: band, lines and periods.

    Parameters
    ----------
    band : (float, float)
        Lowest and highest line (Hz).
    lines : int
        Lines asked for, log-spaced over the band (whole multiples of the period's
        fundamental, the lowest line; duplicates merged, so there may be fewer).
    periods : int
        Periods estimated from.
    settle : int or None
        Periods run first and left out (transients); None: enough for five time constants
        of the linear closed loop's slowest pole, at least one.
    """

    band: tuple
    lines: int = 30
    periods: int = DEFAULT_PERIODS
    settle: int | None = None

    def __post_init__(self):
        lo, hi = self.band
        if not (0 < lo < hi < math.inf):
            raise SceneError("--band", f"must be LO:HI in Hz with 0 < LO < HI (got {lo:g}:{hi:g})")
        if not 2 <= self.lines <= 10_000:
            raise SceneError("--lines", f"must lie in [2, 10000] (got {self.lines})")
        if not 1 <= self.periods <= 1000:
            raise SceneError("--periods", f"must lie in [1, 1000] (got {self.periods})")
        if self.settle is not None and not 0 <= self.settle <= 1000:
            raise SceneError("--settle", f"must lie in [0, 1000] (got {self.settle})")

    def line_multiples(self) -> np.ndarray:
        """The excited lines as whole multiples of the fundamental (the lowest line)."""
        lo, hi = self.band
        return np.unique(np.round(np.geomspace(1.0, hi / lo, self.lines)).astype(int))

    def settle_periods(self, decay_rate: float | None) -> int:
        """Settling periods: the plan's, or five time constants of ``decay_rate`` (1/s)."""
        if self.settle is not None:
            return self.settle
        if decay_rate is None or not decay_rate > 0:
            return 1
        return max(1, math.ceil(5.0 / decay_rate * self.band[0]))


def schroeder(multiples, samples: int) -> np.ndarray:
    """One period (``samples`` equally spaced) of equal cosines on the whole ``multiples`` of
    the fundamental, Schroeder's phases, peak 1."""
    k = np.asarray(multiples, int)
    n = k.size
    phase = -math.pi * np.arange(n) * (np.arange(n) - 1) / n
    x = np.zeros(samples)
    t = np.arange(samples) / samples
    for kk, ph in zip(k, phase):
        x += np.cos(2 * math.pi * kk * t + ph)
    return x / np.max(np.abs(x))


def grid(plan: MultisinePlan, sample_time: float) -> tuple[int, int]:
    """Command samples per period and records per period (a divisor of it)."""
    lo, hi = plan.band
    period = 1.0 / lo
    if sample_time > 0:
        n = period / sample_time
        if abs(n - round(n)) > 1e-6:
            raise SceneError("--band", f"the lowest line {lo:g} Hz must make a period of whole controller samples "
                             f"({sample_time:g} s): e.g. {1.0 / (sample_time * math.ceil(n)):.6g} Hz")
        n = int(round(n))
    else:
        n = int(math.ceil(TABLE_PER_HIGHEST * hi * period))
    if n > MAX_PERIOD_SAMPLES:
        raise SceneError("--band", f"one period of the lowest line {lo:g} Hz holds {n} command samples, more than "
                         f"{MAX_PERIOD_SAMPLES}: a higher lowest line")
    if hi * 4 > 0.5 / (period / n) and sample_time > 0:
        raise SceneError("--band", f"the highest line {hi:g} Hz must be at most {n / period / 8:.4g} Hz, an "
                         f"eighth of the command's sample rate {n / period:.6g} Hz")
    want = RECORDS_PER_HIGHEST * hi * period  # records per period at least
    d = max(1, int(n // math.ceil(want)))  # the largest decimation that divides the period
    while n % d:
        d -= 1
    return n, n // d


def _case(case):
    """One amplitude (module level, so that executors can pickle it)."""
    from ...sim import Reference, run
    model, amplitude, plan, multiples, settle, n, n_rec, response, method, limits = case
    period = 1.0 / plan.band[0]
    step = period / n
    shape = schroeder(multiples, n)
    ref = Reference.table(np.arange(n) * step, amplitude * shape, periodic=True)
    total = settle + plan.periods
    start = time.perf_counter()
    out = {"response": np.full(multiples.size, complex(np.nan, np.nan)), "coherence": np.full(multiples.size, np.nan),
           "distortion_db": math.nan, "saturated": False, "peak_current_A": math.nan, "peak_voltage_V": math.nan,
           "error": None, "log": None}
    try:
        res = run(model, ref, total * period, method, output_dt=period / n_rec)
    except SimulationError as exc:
        out.update(error=str(exc), wall_s=time.perf_counter() - start)
        return out
    m = total * n_rec
    if response == "closed_loop":
        u, y = res.reference_angle[:m] - model.q0, res.output_angle[:m] - model.q0
    else:
        u, y = res.motor_current[:m], res.motor_speed[:m]
    fs = n_rec / period
    spec = periodic_h1(fs, u, y, n_rec, settle=settle, lines=multiples)
    window = slice(settle * n_rec, m)
    i_peak = float(np.max(np.abs(res.current_reference[window])))
    v_peak = float(np.max(np.abs(res.motor_voltage[window])))
    yy = np.fft.rfft(y[window].reshape(plan.periods, n_rec).mean(axis=0))
    band = np.arange(1, int(multiples[-1]) + 1)
    others = np.setdiff1d(band, multiples)
    excited = float(np.sum(np.abs(yy[multiples]) ** 2))
    other = float(np.sum(np.abs(yy[others]) ** 2))
    out.update(response=spec.response, coherence=spec.coherence,
               distortion_db=10 * math.log10(other / excited) if other > 0 and excited > 0 else -math.inf,
               saturated=bool(i_peak >= limits[0] * (1 - 1e-9) or v_peak >= limits[1] * (1 - 1e-9)),
               peak_current_A=i_peak, peak_voltage_V=v_peak, log=(res.times[:m], u, y),
               wall_s=time.perf_counter() - start)
    return out


def linear_plant_response(scene, q0: float, frequency_hz, structural_damping: float) -> np.ndarray:
    """omega_m / i (rad/s per A) of the linear plant's mechanics at q0, complex: the
    continuous response (the sweep's records are not the drive's control instants; a drive's
    log of them is :func:`servo_toolkit.plant.sampled.drive_plant_response`)."""
    from ...plant.sampled import drive_plant_response
    return drive_plant_response(scene, frequency_hz, q0, structural_damping, sample_time=0.0)


@dataclass(frozen=True)
class MultisineSpec:
    """What a multisine sweep runs, resolved and checked before any work (:func:`multisine_spec`).

    Parameters
    ----------
    study : str
        The study's name.
    plan : MultisinePlan
    amplitudes : tuple of float
        Peak command amplitudes (rad, or m for an output travel); one run each.
    response : {"closed_loop", "plant"}
    """

    study: str
    plan: MultisinePlan
    amplitudes: tuple
    response: str = "closed_loop"


def multisine_spec(scene, study=None, *, band=None, lines: int | None = None, amplitudes=None,
                   periods: int = DEFAULT_PERIODS, settle: int | None = None, response: str = "closed_loop",
                   options=None) -> MultisineSpec:
    """The multisine a sweep of ``study`` runs, checked against the band's rules (no design,
    no run); the parameters are :func:`multisine_sweep`'s.

    Returns
    -------
    MultisineSpec

    Raises
    ------
    SceneError
        As :func:`multisine_sweep`.
    """
    if response not in RESPONSES:
        raise SceneError("--response", f"must be one of {', '.join(RESPONSES)} (got {response!r})")
    name, freqs, amps = study_points(scene, study)
    default = max(len(set(freqs)), 2)
    if band is None:
        if len(set(freqs)) < 2:
            raise SceneError("--band", "a multisine needs a band: give --band LO:HI (Hz) or a frequency_sweep study "
                             "with at least two frequencies")
        band = (min(freqs), max(freqs))
    elif 0 < band[0] < band[1] < math.inf:  # a band of its own: its lines by the decade
        default = max(default, math.ceil(LINES_PER_DECADE * math.log10(band[1] / band[0])) + 1)
    plan = MultisinePlan(tuple(float(b) for b in band), int(lines or default), periods, settle)
    if amplitudes is not None:
        amps = tuple(float(a) for a in np.atleast_1d(amplitudes))
    if not amps or min(amps) <= 0:
        raise ValueError("amplitudes must be non-empty and positive")
    continuous = options is not None and options.controller_mode == "continuous"
    grid(plan, 0.0 if continuous else float(scene.sensors.sample_time or 0.0))  # the band's rules
    return MultisineSpec(name, plan, tuple(amps), response)


def multisine_sweep(scene, study=None, *, band=None, lines: int | None = None, amplitudes=None,
                    periods: int = DEFAULT_PERIODS, settle: int | None = None, response: str = "closed_loop",
                    controller=None, options=None, full: bool = False, method: str = "rk4", executor=None,
                    progress: bool = True, controller_source: str | None = None,
                    spec: MultisineSpec | None = None) -> MultisineResult:
    """Frequency response of the scene's loop from a periodic multisine command.

    Parameters
    ----------
    scene : Scene
    study : str or Study, optional
        A ``frequency_sweep`` study: its frequencies give the band (lowest to highest) and
        the number of lines, its amplitudes the command's peaks; default the scene's first.
    band : (float, float), optional
        Lowest and highest line (Hz), replacing the study's. The lowest is the period's
        fundamental: one period must hold whole controller samples.
    lines : int, optional
        Lines asked for (default: the study's number of frequencies, and with ``band`` given at
        least :data:`LINES_PER_DECADE` per decade of it).
    amplitudes : sequence of float, optional
        Peak command amplitudes (rad, or m for an output travel); one run each.
    periods, settle : int
        Periods estimated from, and run first (None: five time constants of the linear loop's
        slowest pole, at least one).
    response : {"closed_loop", "plant"}
        Command -> output position, or motor current -> motor speed.
    controller, options, full, method, executor, progress, controller_source
        As :func:`servo_toolkit.studies.sweep.compute.sweep`.
    spec : MultisineSpec, optional
        The multisine, resolved once by the caller (:func:`multisine_spec`); ``study``,
        ``band``, ``lines``, ``amplitudes``, ``periods``, ``settle`` and ``response`` are
        then not read.

    Returns
    -------
    MultisineResult

    Raises
    ------
    SceneError
        Naming the option: a band without two distinct frequencies, a lowest line whose period
        is not whole samples, a highest line above an eighth of the sample rate, a response
        that is not one of :data:`RESPONSES`.
    """
    from ...sim import controller_for
    from ..model_setup import model_setup
    from ..sweep.compute import linear_response

    start = time.perf_counter()
    if spec is None:  # the band's rules, before any work
        spec = multisine_spec(scene, study, band=band, lines=lines, amplitudes=amplitudes, periods=periods,
                              settle=settle, response=response, options=options)
    name, plan, amps, response = spec.study, spec.plan, spec.amplitudes, spec.response
    multiples = plan.line_multiples()
    source = controller_source
    if controller is None:
        controller, source = controller_for(scene)
    freq = plan.band[0] * multiples
    setup = model_setup(scene, controller, freq, amps, options=options, full=full, source=source)
    options, model, reduced, left_out = setup.options, setup.model, setup.reduced, setup.left_out
    notes = list(setup.notes)
    n, n_rec = grid(plan, model.sample_time)
    closed, decay = linear_response(scene, controller, freq, options.damping_ratio)
    linear = closed if response == "closed_loop" else linear_plant_response(scene, model.q0, freq,
                                                                             options.damping_ratio)
    settle_n = plan.settle_periods(decay)
    limits = (scene.motor.current_limit, scene.motor.voltage_limit)
    cases = [(model, a, plan, multiples, settle_n, n, n_rec, response, method, limits) for a in amps]
    out = run_cases(_case, cases, executor=executor, progress=progress, description="multisine")
    return MultisineResult(
        scene=scene.name, study=name, response_kind=response, frequency_hz=freq, amplitudes=np.asarray(amps, float),
        response=np.array([o["response"] for o in out]), coherence=np.array([o["coherence"] for o in out]),
        linear_response=linear, distortion_db=np.array([o["distortion_db"] for o in out]),
        saturated=np.array([o["saturated"] for o in out]), peak_current_A=np.array([o["peak_current_A"] for o in out]),
        peak_voltage_V=np.array([o["peak_voltage_V"] for o in out]), errors=tuple(o["error"] for o in out),
        logs=tuple(o["log"] for o in out), periods=plan.periods, settle=settle_n, period_s=1.0 / plan.band[0],
        lines_asked=plan.lines, reduced=reduced, left_out=left_out, options=dict(options.__dict__),
        controller=model.controller, method=method, wall_s=time.perf_counter() - start, notes=tuple(notes),
        output_unit=scene.drivetrain.output_unit)


__all__ = ["MultisinePlan", "MultisineSpec", "RESPONSES", "grid", "linear_plant_response", "multisine_spec",
           "multisine_sweep", "schroeder"]
