"""Studies of the multi-stage planetary roller screw (seed 004): the single-stage carrier
step against Jones et al. and the efficiency over the friction coefficients (figures 9-10)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...components.roller_screw.model import RollerScrewModel
from ...components.roller_screw.stages import efficiency_eq35
from ...core.parallel import run_cases
from ...errors import SceneError


@dataclass(frozen=True)
class CarrierStepResult:
    """Carrier/screw speed ratio after a screw-speed step (seed 004 section 3.1 or 3.2).

    Attributes
    ----------
    t : numpy.ndarray
    ratio : numpy.ndarray
        zeta_PSk = theta_Pk' / theta_S', shape (n_stages, n).
    closed_form : numpy.ndarray or None
        zeta_ss (1 - exp(-t / tau)) for the viscous single-stage case.
    steady_ratio : numpy.ndarray
    time_constants : numpy.ndarray
    """

    t: np.ndarray
    ratio: np.ndarray
    closed_form: np.ndarray | None
    steady_ratio: np.ndarray
    time_constants: np.ndarray

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {"study": "carrier_step", "t_s": self.t.tolist(), "carrier_ratio": self.ratio.tolist(),
                "steady_ratio": self.steady_ratio.tolist(), "time_constants_s": self.time_constants.tolist(),
                "closed_form_max_abs_difference": (None if self.closed_form is None else
                                                   float(np.abs(self.closed_form - self.ratio).max()))}

    def table(self) -> str:
        """Plain-text summary."""
        lines = ["carrier/screw speed ratio after a screw-speed step"]
        for k, (z, tau) in enumerate(zip(self.steady_ratio, self.time_constants)):
            lines.append(f"stage {k + 1}: steady ratio {z:.4f}, reached {self.ratio[k, -1]:.4f}, "
                         f"time constant {tau * 1e3:.4g} ms")
        if self.closed_form is not None:
            lines.append(f"max |ODE - closed form| = {np.abs(self.closed_form - self.ratio).max():.2e}")
        return "\n".join(lines)

    def plot(self, ax=None):
        """Ratio against time; returns the axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3.5))
        for k, z in enumerate(self.ratio):
            ax.plot(self.t * 1e3, z, label=f"stage {k + 1}")
        if self.closed_form is not None:
            ax.plot(self.t * 1e3, self.closed_form[0], "k:", label="closed form")
        ax.set_xlabel("time [ms]")
        ax.set_ylabel("carrier / screw speed")
        ax.legend(fontsize="small")
        return ax


def carrier_step(scene, viscous: float = 25.0, load: float = 100.0, speed: float = 1.0,
                 duration: float | None = None) -> CarrierStepResult:
    """Single-stage check against Jones et al.: viscous friction, F_N1 = 100 N, 1 rad/s step."""
    model = RollerScrewModel.from_scene(scene, stages=1, viscous_mu_rs=viscous)
    tau = model.time_constants(speed, load)
    t, w = model.step_response(speed, load, duration or 8 * tau.max())
    ratio = w / speed
    closed = model.steady_carrier_ratios[:, None] * (1 - np.exp(-t / tau[:, None]))
    return CarrierStepResult(t, ratio, closed, model.steady_carrier_ratios, tau)


@dataclass(frozen=True)
class EfficiencyResult:
    """Efficiency of the multi-stage screw after a speed step, against mu_SS and mu_NS.

    Attributes
    ----------
    t : numpy.ndarray
    cases : list of dict
        ``{"mu_ss", "mu_ns", "efficiency" (array over t), "steady", "carrier_ratio"}``.
    eq35 : float
        Eq 35 for the first mu_SS (spline friction only).
    reflected_inertia : float
        kg*m^2 at the first screw.
    """

    t: np.ndarray
    cases: list
    eq35: float
    reflected_inertia: float

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {"study": "efficiency", "t_s": self.t.tolist(), "eq35_efficiency": self.eq35,
                "reflected_inertia_kg_m2": self.reflected_inertia,
                "cases": [{"mu_ss": c["mu_ss"], "mu_ns": c["mu_ns"], "efficiency": c["efficiency"].tolist(),
                           "initial_efficiency": float(c["efficiency"][0]),
                           "steady_efficiency": c["steady"],
                           "carrier_ratio": c["carrier_ratio"].tolist()} for c in self.cases]}

    def table(self) -> str:
        """Plain-text summary."""
        lines = [f"eq 35 (spline friction only): {self.eq35:.4f}; reflected inertia at the screw "
                 f"{self.reflected_inertia:.4g} kg*m^2",
                 f"{'mu_SS':>6s} {'mu_NS':>6s} {'eta at start':>13s} {'eta reached':>12s} {'eta steady':>11s}"]
        for c in self.cases:
            lines.append(f"{c['mu_ss']:6.3f} {c['mu_ns']:6.3f} {c['efficiency'][0]:13.4f} "
                         f"{c['efficiency'][-1]:12.4f} {c['steady']:11.4f}")
        return "\n".join(lines)

    def plot(self, ax=None):
        """Efficiency against time for every case; returns the axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.5))
        for c in self.cases:
            ax.semilogx(self.t[1:] * 1e3, c["efficiency"][1:], label=f"mu_SS {c['mu_ss']:g}, mu_NS {c['mu_ns']:g}")
        ax.set_xlabel("time [ms]")
        ax.set_ylabel("efficiency (eq 32)")
        ax.legend(fontsize="small")
        return ax


def efficiency_study(scene, duration: float | None = None, executor=None) -> EfficiencyResult:
    """Seed 004 figures 9-10: the speed step with each mu_SS (mu_NS first) and each mu_NS (mu_SS first)."""
    op = scene.operating
    if op is None:
        raise SceneError("operating", "the efficiency study needs an [operating] table")
    if len(scene.roller_screw) < 2:
        raise SceneError("stages", "the efficiency study needs at least two [[stages]]")
    pairs = [(ss, op.nut_screw_friction[0]) for ss in op.screw_screw_friction]
    pairs += [(op.screw_screw_friction[0], ns) for ns in op.nut_screw_friction[1:]]
    base = RollerScrewModel.from_scene(scene)
    duration = duration or base.settling_time(op.screw_speed, op.load)
    runs = run_cases(_efficiency_case, [(scene, ss, ns, duration) for ss, ns in pairs], executor=executor,
                     description="roller-screw cases")
    t = runs[0][0]
    cases = [{"mu_ss": ss, "mu_ns": ns, "efficiency": eta, "steady": steady, "carrier_ratio": ratio}
             for (ss, ns), (_, eta, steady, ratio) in zip(pairs, runs)]
    return EfficiencyResult(t, cases, efficiency_eq35(scene.roller_screw, op.screw_screw_friction[0]),
                            base.reflected_inertia())


def _efficiency_case(case):
    scene, mu_ss, mu_ns, duration = case
    op = scene.operating
    model = RollerScrewModel.from_scene(scene, mu_ss=mu_ss, mu_ns=mu_ns)
    t, w = model.step_response(op.screw_speed, op.load, duration)
    eta = np.array([model.efficiency(model.forces(op.screw_speed, w[:, i], op.load)["screw_torque"], op.load)
                    for i in range(t.size)])
    return t, eta, model.steady_efficiency(), w / op.screw_speed
