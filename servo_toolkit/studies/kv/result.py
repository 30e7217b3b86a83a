"""The result of a Kv study: :class:`KvCase` (one motion at one external inertia) and
:class:`KvResult` (a study's cases, its table, figure and card)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ...core.output_units import OutputUnit
from ...display.cards import RichDisplay, card, esc, num, svg, table
from ...display.html import column
from ...display.units import DisplayUnits


@dataclass(frozen=True)
class KvCase:
    """One motion at one external inertia, with its Kv against the zero-inertia case.

    Attributes
    ----------
    amplitude : float
        Output amplitude (rad).
    frequency : float
        Hz.
    load_inertia : float
        External inertia (kg*m^2).
    peak_motor_torque : float
        N*m.
    peak_screw_thrust, peak_rod_force : float or None
        N.
    kv_motor, kv_screw, kv_rod : float or None
        Peak / peak of the same motion at zero external inertia.
    """

    amplitude: float
    frequency: float
    load_inertia: float
    peak_motor_torque: float
    peak_screw_thrust: float | None
    peak_rod_force: float | None
    kv_motor: float
    kv_screw: float | None
    kv_rod: float | None

    def to_dict(self, unit: OutputUnit = OutputUnit()) -> dict:
        """JSON-ready dictionary (the amplitude in deg, or mm and the load mass in kg for an
        output travel)."""
        load_key = "load_mass_kg" if unit.linear else "load_inertia_kg_m2"
        return {load_key: self.load_inertia, unit.key("amplitude"): float(unit.show(self.amplitude)),
                "peak_motor_torque_Nm": self.peak_motor_torque, "peak_screw_thrust_N": self.peak_screw_thrust,
                "kv_motor": self.kv_motor, "kv_screw": self.kv_screw, "frequency_hz": self.frequency,
                "peak_rod_force_N": self.peak_rod_force, "kv_rod": self.kv_rod}


@dataclass(frozen=True, repr=False)
class KvResult(RichDisplay):
    """A Kv study: cases over amplitudes and external inertias.

    Attributes
    ----------
    scene, study : str
    motion : str
        Description of the prescribed motion.
    amplitude_at : str
        "output" or "motor" (how the study's amplitudes were read).
    losses : str
        Stage-loss model of the inverse dynamics.
    cases : tuple of KvCase
        Ordered by amplitude, then inertia.
    notes : tuple of str
        Including which model the loads come from and what it leaves out.
    compliance_effect : float
        Relative change of the inertial motor torque that the drivetrain compliance would
        make, (f / f_n)^2 at the lowest mode over the load inertias (:func:`rigid_model_effect`).
    output_unit : {"rad", "m"}
    display : DisplayUnits
        Unit :meth:`table` and :meth:`plot` show a load inertia in (the scene's ``[display]``;
        default SI); :meth:`to_dict` stays SI.
    """

    scene: str
    study: str
    motion: str
    amplitude_at: str
    losses: str
    cases: tuple
    notes: tuple = field(default=())
    compliance_effect: float = 0.0
    output_unit: str = "rad"
    display: DisplayUnits = DisplayUnits()

    @property
    def unit(self) -> OutputUnit:
        """The output coordinate's units (deg or mm shown)."""
        return OutputUnit(self.output_unit)

    @property
    def amplitudes(self) -> list:
        """Distinct output amplitudes (rad), in order."""
        return list(dict.fromkeys(c.amplitude for c in self.cases))

    def kv_against_first(self) -> list[float]:
        """Peak motor torque / the first case's (smallest amplitude, zero inertia): the seed's
        table-4 reading, which mixes amplitude and inertia."""
        ref = self.cases[0].peak_motor_torque
        return [c.peak_motor_torque / ref for c in self.cases]

    def to_dict(self) -> dict:
        """JSON-ready dictionary with the ``cases`` list."""
        return {"scene": self.scene, "study": self.study, "motion": self.motion,
                "amplitude_at": self.amplitude_at, "losses": self.losses,
                "cases": [c.to_dict(self.unit) for c in self.cases], "notes": list(self.notes),
                "compliance_effect_relative": self.compliance_effect}

    def table(self) -> str:
        """Plain-text table in the spirit of seed 000's tables 2-4."""
        u = self.unit
        j_unit = "[" + self.display.inertia_unit(u.linear) + "]"
        w = max(8, len(j_unit))
        head = (f"{'amplitude':>10s} {'J_load':>{w}s} {'motor torque':>13s} {'Kv motor':>9s} "
                f"{'screw thrust':>13s} {'Kv screw':>9s} {'rod force':>11s}")
        units = f"{'[' + u.shown + ']':>10s} {j_unit:>{w}s} {'[N*m]':>13s} {'':>9s} {'[N]':>13s} {'':>9s} {'[N]':>11s}"
        lines = [f"{self.study}: {self.motion} ({self.amplitude_at} amplitude, losses: {self.losses})",
                 head, units, "-" * len(head)]
        def num(x, fmt):
            return f"{'-':>{len(format(0.0, fmt))}s}" if x is None else format(x, fmt)
        loads = column([self.display.show("inertia", c.load_inertia, u.linear) for c in self.cases], 3)
        for c, load in zip(self.cases, loads):
            lines.append(f"{u.show(c.amplitude):>10.4g} {load:>{w}s} "
                         f"{c.peak_motor_torque:>13.4f} {c.kv_motor:>9.3f} "
                         f"{num(c.peak_screw_thrust, '>13.1f')} {num(c.kv_screw, '>9.3f')} "
                         f"{num(c.peak_rod_force, '>11.1f')}")
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def plot(self, ax=None):
        """Kv of the motor torque and screw thrust against external inertia; returns the Axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
        for a in self.amplitudes:
            cs = [c for c in self.cases if c.amplitude == a]
            j = [self.display.show("inertia", c.load_inertia, self.unit.linear) for c in cs]
            tag = self.unit.text(a, 3)
            line, = ax.plot(j, [c.kv_motor for c in cs], "o-", label=f"motor torque, {tag}")
            if cs[0].kv_screw is not None:
                ax.plot(j, [c.kv_screw for c in cs], "s--", color=line.get_color(),
                        label=f"screw thrust, {tag}")
        ax.set_xlabel(f"external load {'mass' if self.unit.linear else 'inertia'} "
                      f"[{self.display.inertia_unit(self.unit.linear)}]")
        ax.set_ylabel("Kv")
        ax.set_title(f"{self.study}: dynamic-load factor")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        return ax

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


def _card_line(k) -> str:
    """The one-line repr of a result of this module."""
    top = max((c.kv_motor for c in k.cases), default=math.nan)
    return f"{k.scene}, study {k.study}: {len(k.cases)} cases, largest Kv of the motor torque {num(top, 4)}"


def _card_html(k) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    u = k.unit
    rows = [(u.text(c.amplitude), num(k.display.show("inertia", c.load_inertia, u.linear)), num(c.peak_motor_torque),
             num(c.kv_motor, 4),
             num(c.peak_screw_thrust) if c.peak_screw_thrust is not None else "-",
             num(c.kv_screw, 4) if c.kv_screw is not None else "-") for c in k.cases]
    load = f"load {'mass' if u.linear else 'inertia'} [{k.display.inertia_unit(u.linear)}]"
    parts = [f'<p class="st-note">{esc(k.motion)}</p>',
             table(("amplitude", load, "motor torque [N*m]", "Kv motor", "screw thrust [N]", "Kv screw"), rows),
             svg(lambda ax: k.plot(ax), size=(6.0, 3.4))]
    return card(f"Kv of {k.scene}, study {k.study}", parts=parts, notes=k.notes)


__all__ = ["KvCase", "KvResult"]
