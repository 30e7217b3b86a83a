"""How far one LSB of each stored fixed-point coefficient moves its section's poles and zeros.

A section's roots are mapped back to the continuous plane with the inverse Tustin map
``s = (2 / Ts) (z - 1) / (z + 1)``; a coefficient's sensitivity is the largest move of a root
(Hz, and relative to that root's own frequency) when the coefficient changes by one LSB of
its Q format, every other coefficient kept. Roots at z = -1 (s infinite) are left out.
"""

from __future__ import annotations

import math

import numpy as np

from .quantize import direct_form, q_name

#: names of the stored coefficients of a section (:mod:`.quantize`: about z = 1)
COEFFICIENTS = ("n0", "n1", "n2", "d1", "d2")


def _roots_s(poly, sample_time: float) -> np.ndarray:
    """Continuous roots (rad/s) of a polynomial in z (descending powers), z = -1 left out."""
    poly = np.trim_zeros(np.asarray(poly, float), "f")
    if poly.size < 2:
        return np.array([], complex)
    z = np.roots(poly)
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
        denominator's for d1, d2).
    """
    n, d = (list(v) for v in sec.about_one())
    ints = tuple(sec.b_int) + tuple(sec.a_int)
    fracs = tuple(sec.fb) + tuple(sec.fa)
    b, a = direct_form(n, d)
    base = (_roots_s(b, sample_time), _roots_s((1.0, *a), sample_time))
    rows = []
    for k, name in enumerate(COEFFICIENTS):
        lsb = 2.0**-fracs[k]
        nn, dd = list(n), list(d)
        if k < 3:
            nn[k] += lsb
        else:
            dd[k - 3] += lsb
        pb, pa = direct_form(nn, dd)
        after = _roots_s(pb, sample_time) if k < 3 else _roots_s((1.0, *pa), sample_time)
        shift, rel = _move(base[0] if k < 3 else base[1], after)
        rows.append({"section": sec.name, "coefficient": name, "integer": int(ints[k]),
                     "format": q_name(word, fracs[k]), "value": ints[k] * lsb, "lsb": lsb,
                     "root_shift_hz_per_lsb": shift / (2 * math.pi), "root_shift_relative_per_lsb": rel})
    return rows


def coefficient_sensitivity(quantized, sample_time: float) -> list:
    """:func:`section_sensitivity` of every section of a :class:`.quantize.Quantized`, in
    signal order."""
    return [row for sec in quantized.sections() for row in section_sensitivity(sec, quantized.word, sample_time)]
