"""Crossed-arch two-axis deflection platform (seed 003): description and validation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.ranges import range_rule
from ...core.fields import Fields, require
from ...core.units import parse_quantity

_INERTIAS = ("inertia_large_arch", "inertia_small_arch", "inertia_small_guide", "inertia_pin_8",
             "inertia_pin_11_about_o", "inertia_pin_11_spin", "inertia_large_guide",
             "inertia_pinion_15", "inertia_pinion_16")


@dataclass(frozen=True)
class CrossedArchPlatform:
    """Two motors drive crossed arches that tilt a platform by alpha (X) and beta (Y).

    Parameters
    ----------
    ratio_x, ratio_y : float
        z4/z3 and z2/z1.
    inertias : dict
        Part inertias (kg*m^2) keyed by the scene names (``inertia_large_arch`` ...).
    platform_inertia : numpy.ndarray
        2x2 symmetric positive-definite platform inertia about X and Y (kg*m^2).
    """

    ratio_x: float
    ratio_y: float
    inertias: dict
    platform_inertia: np.ndarray

    @classmethod
    def from_table(cls, f: Fields) -> "CrossedArchPlatform":
        """Build from a ``[mechanism]`` table of kind ``crossed_arch_platform``."""
        inertias = {k: f.quantity(k, "kg*m^2", 0.0, rule="nonnegative") for k in _INERTIAS}
        raw = f.raw("platform_inertia")
        key = f.key("platform_inertia")
        require(isinstance(raw, list) and len(raw) == 2 and all(isinstance(r, list) and len(r) == 2 for r in raw),
                key, "must be a 2x2 matrix [[Ixx, Ixy], [Ixy, Iyy]]")
        matrix = np.array([[parse_quantity(v, "kg*m^2", f"{key}[{i}][{j}]")
                            for j, v in enumerate(row)] for i, row in enumerate(raw)])
        for (i, j), v in np.ndenumerate(matrix):
            broken = range_rule(float(v), "nonnegative" if i == j else "finite", "kg*m^2") if np.isfinite(v) \
                else "must be finite"
            require(broken is None, f"{key}[{i}][{j}]", broken or "")
        require(abs(matrix[0, 1] - matrix[1, 0]) <= 1e-12 * np.abs(matrix).max(), key,
                "inertia matrix must be symmetric (Ixy written twice must agree)")
        eig = np.linalg.eigvalsh(matrix)
        require(bool(eig.min() > 0), key,
                f"inertia matrix is not positive definite (eigenvalues {eig[0]:.4g}, {eig[1]:.4g} kg*m^2): "
                "|Ixy| must be below sqrt(Ixx*Iyy)")
        platform = cls(ratio_x=f.number("ratio_x", rule="positive"),
                       ratio_y=f.number("ratio_y", rule="positive"),
                       inertias=inertias, platform_inertia=matrix)
        f.check_unknown()
        return platform
