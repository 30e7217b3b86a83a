"""A linear state-space block with named signals, in numpy alone.

``x' = A x + B u``, ``y = C x + D u`` (continuous, ``dt == 0``) or ``x[k+1] = A x[k] + B
u[k]`` (sampled every ``dt`` s). It is what the toolkit's own analyses compute on: a text
verdict needs the matrices, the poles and the frequency response, not a plotting library.
:meth:`StateSpace.to_control` gives the python-control system with the same matrices and
signal names for everything python-control does (plots, time responses, interconnection
with a user's own blocks); :func:`as_system` takes one back.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _matrix(m, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    a = np.array(m, dtype=float, ndmin=2)
    if a.size == 0:
        a = np.zeros((rows or 0, cols or 0))
    a.setflags(write=False)
    return a


def _labels(given, n: int, prefix: str) -> tuple[str, ...]:
    if given is None:
        return tuple(f"{prefix}[{k}]" for k in range(n))
    if isinstance(given, str):
        given = [given]
    names = tuple(str(x) for x in given)
    if len(names) != n:
        raise ValueError(f"{len(names)} {prefix} names for {n} {prefix}s")
    return names


@dataclass(frozen=True, eq=False, repr=False)
class StateSpace:
    """A state-space block: matrices, signal names and sample time.

    Attributes
    ----------
    A, B, C, D : numpy.ndarray
        Read-only float matrices, shapes ``(n, n)``, ``(n, m)``, ``(p, n)``, ``(p, m)``.
    inputs, outputs, states : tuple of str
        Signal names (as python-control's ``input_labels``, ...).
    name : str
    dt : float
        Sample time (s); 0 for a continuous-time block.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: tuple = field(default=None)
    outputs: tuple = field(default=None)
    states: tuple = field(default=None)
    name: str = ""
    dt: float = 0.0

    def __post_init__(self):
        D = _matrix(self.D)
        p, m = D.shape
        A = _matrix(self.A)
        n = A.shape[0]
        B, C = _matrix(self.B, n, m), _matrix(self.C, p, n)
        if A.shape != (n, n) or B.shape != (n, m) or C.shape != (p, n):
            raise ValueError(f"inconsistent state-space shapes A {A.shape}, B {B.shape}, C {C.shape}, D {D.shape}")
        for key, value in (("A", A), ("B", B), ("C", C), ("D", D),
                           ("inputs", _labels(self.inputs, m, "u")),
                           ("outputs", _labels(self.outputs, p, "y")),
                           ("states", _labels(self.states, n, "x")),
                           ("dt", float(self.dt))):
            object.__setattr__(self, key, value)

    # python-control's names for the sizes and labels
    @property
    def nstates(self) -> int:
        return self.A.shape[0]

    @property
    def ninputs(self) -> int:
        return self.B.shape[1]

    @property
    def noutputs(self) -> int:
        return self.C.shape[0]

    @property
    def input_labels(self) -> list:
        return list(self.inputs)

    @property
    def output_labels(self) -> list:
        return list(self.outputs)

    @property
    def state_labels(self) -> list:
        return list(self.states)

    def isctime(self) -> bool:
        return self.dt == 0

    def issiso(self) -> bool:
        return self.ninputs == 1 and self.noutputs == 1

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` (complex), as python-control's ``poles``."""
        if not self.nstates:
            return np.array([], dtype=complex)
        return np.linalg.eigvals(self.A).astype(complex)

    def zeros(self) -> np.ndarray:
        """Transmission zeros of a square block: the finite generalized eigenvalues of
        ``([A B; C D], [I 0; 0 0])`` (python-control's algorithm without Slycot)."""
        if not self.nstates:
            return np.array([], dtype=complex)
        if self.noutputs != self.ninputs:
            raise NotImplementedError("zeros of a block with as many inputs as outputs only")
        from scipy.linalg import eigvals
        n, p, m = self.nstates, self.noutputs, self.ninputs
        L = np.block([[self.A, self.B], [self.C, self.D]])
        M = np.pad(np.eye(n), ((0, p), (0, m)), "constant")
        return np.array([x for x in eigvals(L, M, overwrite_a=True) if not np.isinf(x)], dtype=complex)

    def __call__(self, s) -> np.ndarray:
        """Frequency response at complex frequencies ``s``: ``C (s I - A)^-1 B + D``
        (``z`` for a sampled block). A SISO block gives an array shaped as ``s``; otherwise
        ``(noutputs, ninputs) + shape(s)``. A point on a pole gives ``inf``."""
        from .response import evaluate
        s = np.asarray(s, complex)
        out = evaluate(self.A, self.B, self.C, self.D, s.reshape(-1))  # (k, p, m)
        out = np.moveaxis(out, 0, -1).reshape((self.noutputs, self.ninputs) + s.shape)
        return out[0, 0] if self.issiso() else out

    def dcgain(self):
        """Steady-state gain (``s = 0``, ``z = 1``), real when the response there is
        (python-control's ``dcgain``)."""
        zeroresp = self(1.0 + 0j if self.dt else 0j)
        if np.all(np.logical_or(np.isreal(zeroresp), np.isnan(zeroresp.imag))):
            return zeroresp.real
        return zeroresp

    def _index(self, key, names, what):
        keys = key if isinstance(key, (list, tuple)) else [key]
        if isinstance(key, slice):
            return list(range(len(names)))[key]
        out = []
        for k in keys:
            if isinstance(k, str):
                if k not in names:
                    raise KeyError(f"no {what} named {k!r} (the block's {what}s: {', '.join(names)})")
                out.append(names.index(k))
            else:
                out.append(int(k))
        return out

    def __getitem__(self, key):
        """The sub-block from outputs ``key[0]`` to inputs ``key[1]`` (names, indices,
        lists of either or slices), as python-control's ``sys[outputs, inputs]``."""
        if not (isinstance(key, tuple) and len(key) == 2):
            raise KeyError("index a block with [outputs, inputs]")
        o = self._index(key[0], self.outputs, "output")
        i = self._index(key[1], self.inputs, "input")
        return StateSpace(self.A, self.B[:, i], self.C[o, :], self.D[np.ix_(o, i)],
                          inputs=[self.inputs[k] for k in i], outputs=[self.outputs[k] for k in o],
                          states=self.states, name=f"{self.name}$indexed", dt=self.dt)

    def to_control(self):
        """The python-control ``StateSpace`` with these matrices, names and sample time."""
        import control as ct
        return ct.ss(np.array(self.A), np.array(self.B), np.array(self.C), np.array(self.D),
                     self.dt if self.dt else 0, inputs=list(self.inputs), outputs=list(self.outputs),
                     states=list(self.states), name=self.name or None)

    def __repr__(self) -> str:
        kind = "continuous" if self.isctime() else f"sampled every {self.dt:g} s"
        return (f"<StateSpace {self.name or '(unnamed)'}: {self.nstates} states, inputs "
                f"{', '.join(self.inputs)}; outputs {', '.join(self.outputs)}; {kind}>")


def ss(A, B, C, D, *, inputs=None, outputs=None, states=None, name: str = "", dt: float = 0.0) -> StateSpace:
    """A :class:`StateSpace` block (python-control's ``ss`` signature for named signals)."""
    return StateSpace(A, B, C, D, inputs=inputs, outputs=outputs, states=states, name=name, dt=dt)


def as_system(sys) -> StateSpace:
    """A :class:`StateSpace` from one, or from a python-control state-space system (its
    matrices, names and sample time; python-control itself is not imported), or from a
    python-control transfer function (python-control's ``ss`` realization of it)."""
    if isinstance(sys, StateSpace):
        return sys
    if type(sys).__module__.startswith("control.") and hasattr(sys, "num") and hasattr(sys, "den"):
        import control as ct  # the caller's own python-control object: it is loaded
        sys = ct.ss(sys)
    if hasattr(sys, "A") and hasattr(sys, "input_labels"):
        dt = sys.dt
        return StateSpace(sys.A, sys.B, sys.C, sys.D, inputs=sys.input_labels, outputs=sys.output_labels,
                          states=getattr(sys, "state_labels", None), name=sys.name or "",
                          dt=0.0 if dt in (0, None) else (float(dt) if dt is not True else 1.0))
    raise TypeError(f"not a state-space system: {type(sys).__name__}")
