"""Stiffness chain study (seed 001): each stage's stiffness at the output and its share."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEFAULT_ANGLES_DEG = (-30.0, 0.0, 10.0, 30.0)


@dataclass(frozen=True)
class StiffnessResult:
    """Stiffness chain at a set of output angles.

    Attributes
    ----------
    angles_deg : numpy.ndarray
    names : tuple of str
        One per compliant stage, motor side last.
    stage_stiffness : numpy.ndarray
        (n_stages, n_angles), N*m/rad at the output.
    shares : numpy.ndarray
        Compliance shares (n_stages, n_angles).
    total : numpy.ndarray
        Series total, N*m/rad.
    ratio : numpy.ndarray
        Motor angle per output angle N(q).
    reflected_inertia : numpy.ndarray
        J(q) at the output, kg*m^2.
    negligible : numpy.ndarray of bool
        Per stage: compliance share below 1e-3 at every angle (seed 001 criterion).
    """

    angles_deg: np.ndarray
    names: tuple
    stage_stiffness: np.ndarray
    shares: np.ndarray
    total: np.ndarray
    ratio: np.ndarray
    reflected_inertia: np.ndarray
    negligible: np.ndarray

    def to_dict(self) -> dict:
        """JSON-ready dictionary (lists over angles)."""
        return {
            "angles_deg": self.angles_deg.tolist(),
            "stages": [{"name": n, "stiffness_Nm_per_rad": k.tolist(), "share": s.tolist(),
                        "negligible": bool(neg)}
                       for n, k, s, neg in zip(self.names, self.stage_stiffness, self.shares, self.negligible)],
            "total_Nm_per_rad": self.total.tolist(),
            "total_Nm_per_deg": (self.total * math.pi / 180).tolist(),
            "ratio": self.ratio.tolist(),
            "reflected_inertia_kg_m2": self.reflected_inertia.tolist(),
        }

    def table(self) -> str:
        """Plain-text table, one block of columns per angle."""
        head = f"{'stage':28s}" + "".join(f"{a:>+10.1f} deg   share " for a in self.angles_deg)
        lines = [head, "-" * len(head)]
        for n, k, s, neg in zip(self.names, self.stage_stiffness, self.shares, self.negligible):
            row = f"{n[:28]:28s}" + "".join(f"{ki * math.pi / 180:>14.6g} {si:>7.2%}" for ki, si in zip(k, s))
            lines.append(row + ("   (negligible)" if neg else ""))
        lines.append("-" * len(head))
        lines.append(f"{'series total [N*m/deg]':28s}" + "".join(f"{t * math.pi / 180:>14.6g}        " for t in self.total))
        lines.append(f"{'ratio N [rad/rad]':28s}" + "".join(f"{r:>14.5g}        " for r in self.ratio))
        lines.append(f"{'reflected inertia [kg*m^2]':28s}" + "".join(f"{j:>14.5g}        " for j in self.reflected_inertia))
        return "\n".join(lines)

    def plot(self, ax=None):
        """Bar chart of compliance shares per angle; returns the Axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.5))
        bottom = np.zeros_like(self.total)
        labels = [f"{a:+.0f} deg" for a in self.angles_deg]
        for n, s in zip(self.names, self.shares):
            ax.bar(labels, s * 100, bottom=bottom * 100, label=n)
            bottom = bottom + s
        ax.set_ylabel("share of compliance [%]")
        ax.set_title("Series compliance at the output")
        ax.legend(fontsize="small")
        return ax


def stiffness_study(scene, angles_deg=DEFAULT_ANGLES_DEG) -> StiffnessResult:
    """Reflect each stage's stiffness to the output at the given angles.

    Parameters
    ----------
    scene : Scene
    angles_deg : sequence of float
        Output angles (deg); q for a cam chain.

    Returns
    -------
    StiffnessResult
    """
    dt = scene.drivetrain
    angles = np.asarray(angles_deg, dtype=float)
    q = np.radians(angles)
    chain = dt.stiffness(q)
    n, _ = dt.ratio(q)
    j, _ = dt.inertia(q)
    return StiffnessResult(angles, chain.names, chain.stage_stiffness, chain.shares, chain.total,
                           n, j, chain.negligible())
