"""Fixed-point form of the motion controller: integer coefficients, signal scales, bounds.

Formats (``fixed_point``):

* ``"q15"``: coefficients int16 in Q(m).(n), m + n = 15; signals int16 values, full scale
  2^15 counts; biquad states int64 with 16 extra fraction bits.
* ``"q31"``: coefficients int32 in Q(m).(n), m + n = 31; signals int32 values with full scale
  2^29 counts (two guard bits keep every 64-bit product sum in range); states int64.

Each section is stored about z = 1 (the delta-operator coefficients): with ``z = 1 + w``,
``N(1 + w) = n0 w^2 + n1 w + n2`` and ``D(1 + w) = w^2 + d1 w + d2``, i.e.
``b0 = n0, b1 = n1 - 2 n0, b2 = n2 - n1 + n0`` and ``a1 = d1 - 2, a2 = d2 - d1 + 1``. A pole or
zero pair near z = 1 (a filter far below the sample rate) makes ``d1, d2`` (``n1, n2``) small,
and each coefficient has its own Q format (the full word on its own value), so these get the
fraction bits a direct-form ``a1 = -2 + ...`` would lose: the natural frequency of a pair is set
by ``d2 = D(1)`` to the word's relative precision, however close to z = 1 it sits. The
recursion adds the integer parts (``2 y``, ``y``) exactly. :mod:`.sensitivity` tells how far one
LSB of each stored coefficient moves the section's poles and zeros.

A signal is an integer count of its LSB, its full scale (the value of ``2^S`` counts) over
``2^S``; each full scale is a power of two (in the signal's unit), so converting between
counts and engineering units is a shift (:func:`full_scales`):

* position (theta_ref, theta, and their difference), rad or m: the smallest power of two at
  least :data:`FULL_SCALE_MARGIN` times the largest of the stroke's span ``hi - lo`` (what the
  error can reach) and its ends' magnitudes ``|lo|``, ``|hi|`` (what theta can reach);
* motor speed, rad/s: the smallest power of two at least :data:`FULL_SCALE_MARGIN` times the
  no-load speed ``Vlim / Ke`` (a load that drives the motor can push it past that; 2^12 rad/s
  for a motor without back EMF);
* current, A: the power of two above the current limit (i_ref is clamped there, and the limit
  stays below ``2^S`` counts).

In the integer domain a section's numerator carries ``LSB_in / LSB_out``.

Rounding (the C ``rshift_round``: half away from zero): every product shifted right loses at
most half a count of the state scale ``2^-G`` LSB, and the DF2T recursion sums ten of them
per output (the ``n0`` product four times, ``n1`` and ``d1`` twice, ``n2`` and ``d2`` once),
amplified by the recursive part ``1 / A(z)``; the output is rounded to half an LSB (the recursion keeps the unrounded value). With the inputs rounded to half an LSB, the
i_ref difference between the fixed-point code and the same quantized coefficients in exact
arithmetic is at most :meth:`Quantized.error_bound` (l1 norms of the impulse responses over
the horizon; the speed PI integrates, so the bound grows with the horizon). The coefficient
quantization itself is judged by the margins of the quantized controller.

At the current clamp the integer code back-calculates its integrator as the floating one
(:mod:`.antiwindup`), in the integrator section's own arithmetic: with the clamp's excess
``E`` (from the rounded i_ref, in the states' ``2^-G`` counts) ``s0 += E`` and
``s1 += d1 E - d2 E - E`` (``-a2 E``, the products shifted as the recursion shifts
``d1 y``, ``d2 y``), so that the step moves the states along the integer recursion's own
integrator direction. A gain rounded to the coefficient word instead (``-a2`` of a PID's
section to 2^-15) leaves a part of every clamped sample's move on the section's other pole,
where, near z = 1, it adds up over the clamp beyond the bound below. A clamped sample so
resets the integrator's share of the rounding error (the error's dynamics there,
``A - g C``, have the other poles of ``A`` and 0 in place of the integrator's): the error
does not accumulate while the clamp holds, and the bound, derived for the linear range, is
checked through the clamp by the tests. The feedforward current added before the clamp is
saturated at twice the current's full scale, so the excess stays below ``2^(S + 2)`` counts
and its products with d1, d2 below 2^62 wherever :func:`.build.overflow_failures` passes
their products with ``y`` (below ``2^(S + G)``, each under 2^60).

The current PI and a speed estimator stay in ``double`` (the estimate is rounded to motor
speed counts before the motion step, which the bound's input rounding covers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import signal

from ..errors import SceneError
from .antiwindup import back_calculation
from .blocks import Biquad, Blocks

#: format -> (coefficient fraction word W, signal bits S, extra state fraction bits G)
FORMATS = {"q15": (15, 15, 16), "q31": (31, 29, 0)}


#: full scale of the position and the motor speed over the most the signal reaches (a travel
#: past the stroke's ends into the end stops, a motor driven past its no-load speed)
FULL_SCALE_MARGIN = 1.25

#: most fraction bits of a coefficient (the C shifts 64-bit products by at most this)
MAX_FRACTION_BITS = 62


def q_format(values, word: int) -> int:
    """Fraction bits n so that every ``round(v * 2^n)`` fits in ``word`` bits plus sign (at
    most :data:`MAX_FRACTION_BITS`: smaller coefficients lose their low bits)."""
    m = float(np.max(np.abs(values))) if len(values) else 0.0
    if m == 0.0:
        return word
    n = min(word - (math.floor(math.log2(m)) + 1), MAX_FRACTION_BITS)
    while round(m * 2.0**n) > 2**word - 1:
        n -= 1
    return n


def q_name(word: int, frac: int) -> str:
    """``"Q2.13"`` style name (integer bits may be negative for small coefficients)."""
    return f"Q{word - frac}.{frac}"


def about_one(b, a) -> tuple:
    """``(n, d)``: ``N(1 + w)`` and ``D(1 + w)`` of ``b0 + b1 z^-1 + b2 z^-2`` over
    ``1 + a1 z^-1 + a2 z^-2`` (``n = (n0, n1, n2)``, ``d = (d1, d2)``)."""
    b0, b1, b2 = (float(v) for v in b)
    a1, a2 = (float(v) for v in a)
    return (b0, 2 * b0 + b1, b0 + b1 + b2), (2 + a1, 1 + a1 + a2)


def direct_form(n, d) -> tuple:
    """Inverse of :func:`about_one`: ``(b, a)`` with ``b = (b0, b1, b2)``, ``a = (a1, a2)``."""
    n0, n1, n2 = n
    d1, d2 = d
    return (n0, n1 - 2 * n0, n2 - n1 + n0), (d1 - 2, d2 - d1 + 1)


#: rounding terms per output of the C section: products of n0, n1, n2, d1, d2 (module docstring)
ROUNDING_WEIGHTS = (4, 2, 1, 2, 1)


@dataclass(frozen=True)
class QSection:
    """A biquad with integer coefficients about z = 1 (see the module docstring).

    ``n_k = b_int[k] 2^-fb[k]`` (counts out per count in) and ``d_k = a_int[k - 1] 2^-fa[k - 1]``,
    each coefficient in its own Q format.
    """

    name: str
    b_int: tuple
    a_int: tuple
    fb: tuple
    fa: tuple
    lsb_in: float
    lsb_out: float

    def about_one(self) -> tuple:
        """``(n, d)`` as floats in the integer domain."""
        return (tuple(v * 2.0**-f for v, f in zip(self.b_int, self.fb)),
                tuple(v * 2.0**-f for v, f in zip(self.a_int, self.fa)))

    def biquad(self, original: Biquad) -> Biquad:
        """The quantized coefficients back in physical units (direct form)."""
        b, a = direct_form(*self.about_one())
        scale = self.lsb_out / self.lsb_in
        return replace(original, b=tuple(v * scale for v in b), a=tuple(a))

    def counts(self):
        """``(b, [1, a1, a2])`` in the integer domain (floats)."""
        b, a = direct_form(*self.about_one())
        return np.array(b), np.array([1.0, *a])

    def to_dict(self, word: int) -> dict:
        b, a = self.counts()
        return {"name": self.name, "form": "about_z_1", "b": list(self.b_int), "a": list(self.a_int),
                "b_formats": [q_name(word, f) for f in self.fb], "a_formats": [q_name(word, f) for f in self.fa],
                "b_fraction_bits": list(self.fb), "a_fraction_bits": list(self.fa),
                "direct_form_counts": {"b": [float(v) for v in b], "a": [float(v) for v in a]},
                "input_lsb": self.lsb_in, "output_lsb": self.lsb_out}


@dataclass(frozen=True)
class Quantized:
    """The fixed-point motion controller.

    Attributes
    ----------
    fmt : str
        ``"q15"`` or ``"q31"``.
    lsb : dict
        ``theta`` (rad, or m for a linear output), ``omega`` (motor rad/s), ``current`` (A)
        per count; each a power of two (:func:`full_scales` over ``2^S``).
    position : tuple of QSection
    speed : QSection or None
    current_limit_counts : int
    blocks : Blocks
        The quantized coefficients in physical units (what the fixed-point code computes,
        up to rounding).
    integrator : int or None
        Index (in :meth:`sections`) of the section the clamp back-calculates (its pole at
        z = 1; the last section, i_ref's); None without an integrator.
    """

    fmt: str
    lsb: dict
    position: tuple
    speed: QSection | None
    current_limit_counts: int
    blocks: Blocks
    integrator: int | None = None

    @property
    def word(self) -> int:
        return FORMATS[self.fmt][0]

    @property
    def signal_bits(self) -> int:
        return FORMATS[self.fmt][1]

    @property
    def guard(self) -> int:
        return FORMATS[self.fmt][2]

    @property
    def full_scale(self) -> dict:
        """``theta``, ``omega``, ``current``: the value of ``2^S`` counts of each signal (its
        unit as in :attr:`lsb`)."""
        return {k: v * 2**self.signal_bits for k, v in self.lsb.items()}

    def sections(self) -> tuple:
        return self.position + ((self.speed,) if self.speed is not None else ())

    def error_bound(self, steps: int) -> float:
        """Largest |i_ref| difference (A) over ``steps`` samples between the fixed-point code
        and exact arithmetic on the quantized coefficients, inputs rounded to the nearest
        count, while no signal reaches its full scale (the current clamp: see the module docstring)."""
        err = 1.0  # theta_ref and theta rounded: half a count each
        for sec in self.position:  # later sections take the previous one's counts
            err = _section_error(sec, err, steps, self.guard)
        if self.speed is not None:
            err = _section_error(self.speed, err * self.position[-1].lsb_out / self.speed.lsb_in + 0.5,
                                 steps, self.guard)
        return err * self.sections()[-1].lsb_out

    def signal_scales(self) -> list:
        """Per signal: name, unit, full scale, its base-2 exponent and the LSB (what drive
        firmware needs to convert counts: ``value = counts * full_scale / 2^S``)."""
        unit = self.blocks.output_unit
        rows = (("theta_ref, theta", unit, "theta"), ("omega_m", "rad/s", "omega"), ("i_ref", "A", "current"))
        return [{"signals": name, "unit": u, "full_scale": self.full_scale[k],
                 "full_scale_log2": int(round(math.log2(self.full_scale[k]))), "lsb": self.lsb[k]}
                for name, u, k in rows]

    def to_dict(self) -> dict:
        unit = self.blocks.output_unit
        return {"format": self.fmt, "coefficient_word_bits": self.word + 1,
                "signal_full_scale_counts": 2**self.signal_bits, "state_extra_fraction_bits": self.guard,
                "lsb": {f"theta_{unit}": self.lsb["theta"], "omega_m_rad_s": self.lsb["omega"],
                        "current_A": self.lsb["current"]},
                "full_scale": {f"theta_{unit}": self.full_scale["theta"],
                               "omega_m_rad_s": self.full_scale["omega"], "current_A": self.full_scale["current"]},
                "signal_scales": self.signal_scales(),
                "sections": [s.to_dict(self.word) for s in self.sections()],
                "current_limit_counts": self.current_limit_counts,
                "back_calculation": None if self.integrator is None else {
                    "section": self.integrator, "name": self.sections()[self.integrator].name,
                    "s0": "+= E", "s1": "+= d1 E - d2 E - E (-a2 E with the section's stored d1, d2)",
                    "E": "the clamp's excess in the states' 2^-G counts of i_ref"}}


def _l1(b, a, steps: int) -> float:
    """l1 norm of the first ``steps`` samples of the impulse response of b / a."""
    x = np.zeros(steps)
    x[0] = 1.0
    return float(np.sum(np.abs(signal.lfilter(b, a, x))))


def _section_error(sec: QSection, err_in: float, steps: int, guard: int) -> float:
    """Bound on the output error (counts) of a section from its input error (counts)."""
    b, a = sec.counts()
    shifts = [f - guard for f in sec.fb] + list(sec.fa)
    ints = tuple(sec.b_int) + tuple(sec.a_int)
    injected = 0.5 * sum(w for w, k, v in zip(ROUNDING_WEIGHTS, shifts, ints) if v and k > 0) * 2.0**-guard
    return 0.5 + injected * _l1([1.0], a, steps) + err_in * _l1(b, a, steps)


def _pow2_above(x: float) -> float:
    return 2.0 ** (math.floor(math.log2(max(x, 1e-300))) + 1)


def _pow2_at_least(x: float) -> float:
    """The smallest power of two >= x (x itself when it is one, to a relative 1e-12)."""
    return 2.0 ** math.ceil(math.log2(max(x, 1e-300)) - 1e-12)


def full_scales(blocks: Blocks, motor) -> dict:
    """Full scale of each signal (the value of ``2^S`` counts): ``theta`` in the output's unit
    from ``blocks.stroke``, ``omega`` (motor rad/s) from the no-load speed, ``current`` (A)
    from the current limit; each a power of two (see the module docstring)."""
    lo, hi = (float(v) for v in blocks.stroke)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise SceneError("drivetrain.stroke", f"must be two finite positions, lower < upper, got {blocks.stroke!r}")
    reach = max(hi - lo, abs(lo), abs(hi))
    omega = (_pow2_at_least(FULL_SCALE_MARGIN * motor.voltage_limit / motor.back_emf_constant)
             if motor.back_emf_constant > 0 else 2.0**12)
    return {"theta": _pow2_at_least(FULL_SCALE_MARGIN * reach), "omega": omega,
            "current": _pow2_above(blocks.current_limit)}


def quantize(blocks: Blocks, motor, fmt: str) -> Quantized:
    """Quantize ``blocks`` to ``fmt`` (``"q15"`` or ``"q31"``)."""
    if fmt not in FORMATS:
        raise SceneError("fixed_point", f"must be one of {tuple(FORMATS)}, got {fmt!r}")
    word, sbits, _ = FORMATS[fmt]
    lsb = {k: v / 2**sbits for k, v in full_scales(blocks, motor).items()}
    out_lsb = lsb["omega"] if blocks.speed is not None else lsb["current"]

    def q(sec: Biquad, lsb_in, lsb_out):
        n, d = about_one(np.array(sec.b) * lsb_in / lsb_out, sec.a)
        fb, fa = tuple(q_format([v], word) for v in n), tuple(q_format([v], word) for v in d)
        return QSection(sec.name, tuple(int(round(v * 2.0**f)) for v, f in zip(n, fb)),
                        tuple(int(round(v * 2.0**f)) for v, f in zip(d, fa)), fb, fa, lsb_in, lsb_out)

    position = tuple(q(s, lsb["theta"] if j == 0 else out_lsb, out_lsb) for j, s in enumerate(blocks.position))
    speed = None if blocks.speed is None else q(blocks.speed, lsb["omega"], lsb["current"])
    ilim = int(math.floor(blocks.current_limit / lsb["current"]))
    qb = replace(blocks, position=tuple(s.biquad(o) for s, o in zip(position, blocks.position)),
                 speed=None if speed is None else speed.biquad(blocks.speed),
                 current_limit=ilim * lsb["current"])
    return Quantized(fmt, lsb, position, speed, ilim, qb, _integrator(qb))


def _integrator(qb: Blocks) -> int | None:
    """Index of the quantized controller's integrator section (:mod:`.antiwindup`), which
    the integer code back-calculates in its own arithmetic: the last section, whose output
    is i_ref (the speed PI of the cascade; scipy's ``zpk2sos`` puts the pole at z = 1, on the
    unit circle, in the last section of a position path)."""
    bc = back_calculation(qb.sections())
    if bc is None:
        return None
    names = [s.name for s in qb.sections()]
    if bc.integrator != names[-1]:
        raise ValueError(f"the fixed-point back-calculation needs the integrator in the last section, "
                         f"found it in {bc.integrator} of {names}")
    return len(names) - 1


def natural_frequencies(sec: Biquad, sample_time: float) -> dict:
    """Continuous natural frequencies (Hz) of a section's complex zero and pole pairs (the
    Tustin map inverted: s = (2 / Ts) (z - 1) / (z + 1))."""
    out = {}
    for key, poly in (("zero_hz", sec.b), ("pole_hz", (1.0, *sec.a))):
        roots = np.roots(np.trim_zeros(np.asarray(poly, float), "b")) if np.any(poly) else np.array([])
        roots = roots[np.abs(roots.imag) > 0]
        if roots.size:
            s = 2.0 / sample_time * (roots[0] - 1) / (roots[0] + 1)
            out[key] = float(abs(s) / (2 * math.pi))
    return out


def filter_shifts(blocks: Blocks, quantized: Quantized) -> list:
    """Per position section with a complex zero or pole pair: design and quantized natural
    frequencies (Hz) and their shift (the notch moves when its coefficients are rounded)."""
    rows = []
    for orig, qs in zip(blocks.position, quantized.blocks.position):
        f0, f1 = natural_frequencies(orig, blocks.sample_time), natural_frequencies(qs, blocks.sample_time)
        for key in f0:
            got = f1.get(key, math.nan)
            rows.append({"section": orig.name, "what": key.split("_")[0], "design_hz": f0[key],
                         "quantized_hz": got, "shift_hz": got - f0[key],
                         "shift_relative": (got - f0[key]) / f0[key]})
    return rows
