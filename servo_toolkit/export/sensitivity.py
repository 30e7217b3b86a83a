"""How far one LSB of each stored fixed-point coefficient moves its section's poles and zeros.

A section's roots are mapped back to the continuous plane with the inverse Tustin map
``s = (2 / Ts) (z - 1) / (z + 1)``; a coefficient's sensitivity is the largest move of a root
(Hz, and relative to that root's own frequency) when the coefficient changes by one LSB of
its Q format, every other coefficient kept. Roots at z = -1 (s infinite) are left out, and so
are a lower-order section's padding roots: a pure gain or a first-order section stored as a
biquad has its denominator's trailing coefficients exactly 0, poles at z = 0 (s = -2 / Ts) that
cancel as many zeros near z = 0 and are no dynamics of the controller. A coefficient whose
polynomial has no other root (a pure gain's) moves none: its figures are None.
"""

from __future__ import annotations

import math

import numpy as np

from .quantize import direct_form, q_name

#: names of the stored coefficients of a section (:mod:`.quantize`: about z = 1)
COEFFICIENTS = ("n0", "n1", "n2", "d1", "d2")


def padding(den) -> int:
    """How many of a section's orders are padding: the trailing exact zeros of its
    denominator ``(1, a1, a2)`` (2 for a pure gain, 1 for a first-order section)."""
    den = np.asarray(den, float)
    return int(den.size - np.trim_zeros(den, "b").size)


def _roots_s(poly, sample_time: float, pad: int = 0) -> np.ndarray:
    """Continuous roots (rad/s) of a polynomial in z (descending powers), z = -1 and the
    ``pad`` roots nearest z = 0 (a lower-order section's padding) left out."""
    poly = np.trim_zeros(np.asarray(poly, float), "f")
    if poly.size < 2:
        return np.array([], complex)
    z = np.roots(poly)
    z = z[np.argsort(np.abs(z), kind="stable")][pad:]
    z = z[np.abs(z + 1.0) > 1e-9]
    return 2.0 / sample_time * (z - 1.0) / (z + 1.0)


def _move(before: np.ndarray, after: np.ndarray) -> tuple:
    """Largest move (rad/s) of a root of ``before`` to its nearest root of ``after``, and the
    largest such move relative to the root's own magnitude (0 for a root at s = 0)."""
    if not before.size:
        return 0.0, 0.0
    if not after.size:
        return math.inf, math.inf
    dist = np.min(np.abs(before[:, None] - after[None, :]), axis=1)
    mag = np.abs(before)
    rel = np.where(mag > 0, dist / np.where(mag > 0, mag, 1.0), 0.0)
    return float(np.max(dist)), float(np.max(rel))


def section_sensitivity(sec, word: int, sample_time: float) -> list:
    """One row per stored coefficient of the :class:`.quantize.QSection` ``sec``.

    Parameters
    ----------
    sec : QSection
    word : int
        Coefficient word (fraction plus integer bits, sign excluded).
    sample_time : float
        Sample time (s) of the section.

    Returns
    -------
    list of dict
        ``section``, ``coefficient`` (n0, n1, n2, d1, d2), ``integer``, ``format``,
        ``value`` (integer domain), ``lsb``, ``root_shift_hz_per_lsb`` and
        ``root_shift_relative_per_lsb`` (largest over the numerator's roots for n0..n2, the
        denominator's for d1, d2; None when that polynomial has no root but padding, as a
        pure gain's).
    """
    n, d = (list(v) for v in sec.about_one())
    ints = tuple(sec.b_int) + tuple(sec.a_int)
    fracs = tuple(sec.fb) + tuple(sec.fa)
    b, a = direct_form(n, d)
    pad = padding((1.0, *a))
    base = (_roots_s(b, sample_time, pad), _roots_s((1.0, *a), sample_time, pad))
    rows = []
    for k, name in enumerate(COEFFICIENTS):
        lsb = 2.0**-fracs[k]
        nn, dd = list(n), list(d)
        if k < 3:
            nn[k] += lsb
        else:
            dd[k - 3] += lsb
        pb, pa = direct_form(nn, dd)
        after = _roots_s(pb, sample_time, pad) if k < 3 else _roots_s((1.0, *pa), sample_time, pad)
        before = base[0] if k < 3 else base[1]
        shift, rel = _move(before, after) if before.size else (None, None)
        rows.append({"section": sec.name, "coefficient": name, "integer": int(ints[k]),
                     "format": q_name(word, fracs[k]), "value": ints[k] * lsb, "lsb": lsb,
                     "root_shift_hz_per_lsb": None if shift is None else shift / (2 * math.pi),
                     "root_shift_relative_per_lsb": rel})
    return rows


def coefficient_sensitivity(quantized, sample_time: float) -> list:
    """:func:`section_sensitivity` of every section of a :class:`.quantize.Quantized`, in
    signal order."""
    return [row for sec in quantized.sections() for row in section_sensitivity(sec, quantized.word, sample_time)]
