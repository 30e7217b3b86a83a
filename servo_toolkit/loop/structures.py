"""Controller structures as transfer-function pieces (numpy polynomials, descending powers).

``cascade``: position P (+ resonance filter) -> speed PI on the motor speed -> current
command, the usual EMA structure: i_ref = Cv (Cp (theta_ref - theta) - omega_m / N).
``pid``, ``lead_lag`` and ``pi``: one compensator on the position error, no speed feedback.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..lti.convert import tf2ss
from ..lti.system import StateSpace, ss

STRUCTURES = ("cascade", "pid", "lead_lag", "pi")
FILTERS = ("none", "notch", "lowpass")


def notch(wn: float, zeta_zero: float, zeta_pole: float):
    """Notch at ``wn`` (rad/s): (s^2 + 2 zz wn s + wn^2) / (s^2 + 2 zp wn s + wn^2)."""
    return np.array([1.0, 2 * zeta_zero * wn, wn**2]), np.array([1.0, 2 * zeta_pole * wn, wn**2])


def lowpass(wn: float, zeta: float = 0.5):
    """Second-order low-pass at ``wn`` (rad/s)."""
    return np.array([wn**2]), np.array([1.0, 2 * zeta * wn, wn**2])


#: gain or filter parameter -> (meaning, unit with OUT for the output's unit, rad or m; "" for
#: a dimensionless one)
PARAMETERS = {"kp": ("position gain", "1/s"), "kv": ("speed gain", "A*s/OUT"), "wvi": ("speed PI corner", "rad/s"),
              "kc": ("controller gain", "A/OUT"), "wi": ("integral corner", "rad/s"), "wz": ("lead zero", "rad/s"),
              "wp": ("lead pole", "rad/s"), "wn": ("filter frequency", "rad/s"),
              "zeta_zero": ("notch depth: damping of the zeros", ""),
              "zeta_pole": ("notch width: damping of the poles", ""),
              "zeta": ("low-pass damping", "")}


def parameter_unit(name: str, out: str = "rad") -> str:
    """The unit of a gain or filter parameter for an output in ``out`` (``"rad"`` or ``"m"``)."""
    return PARAMETERS.get(name, (name, ""))[1].replace("OUT", out)


@dataclass(frozen=True)
class Motion:
    """A motion-controller design: structure, gains and resonance filter.

    Attributes
    ----------
    structure : str
    gains : dict
        cascade: ``kp`` (1/s), ``kv`` (A per output rad/s), ``wvi`` (rad/s);
        pid: ``kc`` (A/rad), ``wi``, ``wz``, ``wp`` (rad/s); lead_lag: ``kc``, ``wz``, ``wp``;
        pi: ``kc``, ``wi``.
    filter : str
        ``none``, ``notch`` or ``lowpass``, on the position path.
    filter_params : dict
        notch: ``wn``, ``zeta_zero``, ``zeta_pole``; lowpass: ``wn``, ``zeta``.
    ratio : float
        N, to convert the motor speed to the output.
    """

    structure: str
    gains: dict
    filter: str = "none"
    filter_params: dict = field(default_factory=dict)
    ratio: float = 1.0

    def filter_polys(self):
        if self.filter == "notch":
            return notch(**self.filter_params)
        if self.filter == "lowpass":
            return lowpass(**self.filter_params)
        return np.array([1.0]), np.array([1.0])

    def pieces(self):
        """``(position path (num, den), speed path (num, den) or None)``: the position path
        maps the error to omega_ref (cascade) or to i_ref, the speed path is Cv."""
        fn, fd = self.filter_polys()
        g = self.gains
        if self.structure == "cascade":
            pos = (g["kp"] * fn, fd)
            return pos, (g["kv"] * np.array([1.0, g["wvi"]]), np.array([1.0, 0.0]))
        if self.structure == "pid":
            num = g["kc"] * np.polymul([1.0, g["wi"]], [1 / g["wz"], 1.0])
            den = np.polymul([1.0, 0.0], [1 / g["wp"], 1.0])
        elif self.structure == "lead_lag":
            num, den = g["kc"] * np.array([1 / g["wz"], 1.0]), np.array([1 / g["wp"], 1.0])
        elif self.structure == "pi":
            num, den = g["kc"] * np.array([1.0, g["wi"]]), np.array([1.0, 0.0])
        else:
            raise ValueError(f"unknown structure {self.structure!r}; known: {STRUCTURES}")
        return (np.polymul(num, fn), np.polymul(den, fd)), None

    def responses(self, s):
        """``(Cy, Cw)``: gains from -theta and from -omega_m to i_ref at ``s``."""
        (pn, pd), speed = self.pieces()
        cp = np.polyval(pn, s) / np.polyval(pd, s)
        if speed is None:
            return cp, np.zeros_like(cp)
        cv = np.polyval(speed[0], s) / np.polyval(speed[1], s)
        return cp * cv, cv / self.ratio

    def state_space(self) -> StateSpace:
        """Inputs ``theta_ref``, ``theta`` (rad), ``omega_m`` (rad/s); output ``i_ref`` (A), as
        the toolkit's own state-space block (``.to_control()``: python-control's)."""
        (pn, pd), speed = self.pieces()
        if speed is None:
            c = tf2ss(pn, pd)
            z = np.zeros((c.nstates, 1))
            return ss(c.A, np.hstack([c.B, -c.B, z]), c.C, np.hstack([c.D, -c.D, [[0.0]]]),
                      inputs=["theta_ref", "theta", "omega_m"], outputs=["i_ref"], name="motion")
        # x = [position states, speed states]; ev = Cp x_p + Dp (theta_ref - theta) - omega_m / N
        pos, vel = tf2ss(pn, pd), tf2ss(*speed)
        Ap, Bp, Cp, Dp = (np.atleast_2d(np.asarray(m, float)) for m in (pos.A, pos.B, pos.C, pos.D))
        Av, Bv, Cv, Dv = (np.atleast_2d(np.asarray(m, float)) for m in (vel.A, vel.B, vel.C, vel.D))
        npos, nvel = pos.nstates, vel.nstates
        Ap, Bp, Cp = Ap.reshape(npos, npos), Bp.reshape(npos, 1), Cp.reshape(1, npos)
        Av, Bv, Cv = Av.reshape(nvel, nvel), Bv.reshape(nvel, 1), Cv.reshape(1, nvel)
        e_in = np.array([[1.0, -1.0, 0.0]])
        w_in = np.array([[0.0, 0.0, -1.0 / self.ratio]])
        A = np.block([[Ap, np.zeros((npos, nvel))], [Bv @ Cp, Av]])
        B = np.vstack([Bp @ e_in, Bv @ (Dp @ e_in + w_in)])
        C = np.hstack([Dv @ Cp, Cv])
        D = Dv @ (Dp @ e_in + w_in)
        states = [f"position[{k}]" for k in range(npos)] + [f"speed[{k}]" for k in range(nvel)]
        return ss(A, B, C, D, inputs=["theta_ref", "theta", "omega_m"], outputs=["i_ref"],
                  states=states, name="motion")

    def describe(self, out: str = "rad") -> str:
        """One line for reports, each value with its unit; ``out``: the output's unit, ``"rad"``
        or ``"m"`` (a speed gain is A*s/rad or A*s/m)."""
        def shown(params):
            return ", ".join(f"{k}={v:.4g} {parameter_unit(k, out)}".rstrip() for k, v in params.items())
        f = "" if self.filter == "none" else f" + {self.filter} " + shown(self.filter_params)
        return f"{self.structure} ({shown(self.gains)}){f}"
