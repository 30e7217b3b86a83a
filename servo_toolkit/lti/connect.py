"""Blocks connected by their signal names into one block, in numpy.

:func:`interconnect` reproduces python-control 0.10's ``interconnect`` of state-space
blocks with implicit (name-matched) connections. python-control forms the connected
block's matrices by linearizing the interconnection numerically: it perturbs each state
and each input by ``1e-6`` at the origin, propagates the static signals through the
blocks' feedthrough by fixed-point iteration, and divides the change by ``1e-6``. Those
quotients equal the exact algebra to rounding; this module takes the same steps in the
same order, so the matrices are the same numbers.
"""

from __future__ import annotations

import re

import numpy as np

from .system import StateSpace, as_system

#: Step python-control's ``linearize`` perturbs each state and input by.
_EPS = 1e-6


class AlgebraicLoopError(ValueError, RuntimeError):
    """A loop of feedthrough terms the signal propagation does not settle
    (python-control raises ``RuntimeError("algebraic loop detected")`` there)."""


def _find_signals(name: str, labels) -> list | None:
    """Indices of signal ``name`` in ``labels`` (a bare name also matches ``name[k]``),
    as python-control's ``_find_signals`` for one name; None when there is none."""
    ms = re.match(r'([\w$]+)\[([\d]*):([\d]*)\]$', name)
    if ms:
        start = None if ms.group(2) == '' else int(ms.group(2))
        stop = None if ms.group(3) == '' else int(ms.group(3))
        out = []
        for k, var in enumerate(labels):
            msig = re.match(r'([\w$]+)\[([\d]+)\]$', var)
            if msig and msig.group(1) == ms.group(1) and (start is None or int(msig.group(2)) >= start) \
                    and (stop is None or int(msig.group(2)) < stop):
                out.append(k)
        return out or None
    if re.match(r'([\w$]+)$', name) and name not in labels:
        out = [k for k, var in enumerate(labels) if re.match(re.escape(name) + r'\[([\d]+)\]$', var)]
        return out or None
    return [list(labels).index(name)] if name in labels else None


def _split_sign(spec: str) -> tuple[str, int]:
    return (spec[1:], -1) if spec.startswith('-') else (spec, 1)


def _sysnames(systems) -> list:
    """Names of the blocks as the interconnection knows them (an unnamed block is
    ``sys[k]`` by its place; a repeated name gets ``_1``, ``_2``, ...)."""
    names, count = [], {}
    for k, s in enumerate(systems):
        base = s.name or f"sys[{k}]"
        if base in count:
            names.append(f"{base}_{count[base]}")
            count[base] += 1
        else:
            names.append(base)
            count[base] = 1
    return names


def _parse_dotted(systems, sysnames, spec: str, kind: str):
    """``block.signal`` of ``kind`` ('input' or 'output'): (block index, signal indices, gain)."""
    sname, gain = _split_sign(spec)
    block, _, signal = sname.partition('.')
    if block not in sysnames:
        raise ValueError(f"could not find system {block!r}")
    k = sysnames.index(block)
    labels = systems[k].inputs if kind == 'input' else systems[k].outputs
    idx = _find_signals(signal, labels)
    if idx is None:
        raise ValueError(f"could not find {kind} signal {sname!r}")
    return k, idx, gain


def _expand(systems, sysnames, names, kind: str) -> list:
    """python-control's pre-processing of ``inplist`` / ``outlist`` of signal names: one
    entry per connected signal, each a list of (block, signal, gain) with ``signal`` an
    index into the block's inputs, or into its outputs (``kind == 'output'``), or
    ``('in', k)`` for a block input listed as an output."""
    if isinstance(names, str):
        names = [names]
    out = []
    for spec in names:
        if not isinstance(spec, str):
            raise TypeError(f"{kind} list entries are signal names, got {spec!r}")
        if '.' in spec:
            try:
                k, idx, gain = _parse_dotted(systems, sysnames, spec, kind)
                out += [[(k, i, gain)] for i in idx]
            except ValueError:
                if kind != 'output':
                    raise
                k, idx, gain = _parse_dotted(systems, sysnames, spec, 'input')
                out += [[(k, ('in', i), gain)] for i in idx]
            continue
        sname, gain = _split_sign(spec)
        found_system, found_signal, conns = False, False, []
        for k, s in enumerate(systems):
            labels = s.inputs if kind == 'input' else s.outputs
            idx = _find_signals(sname, labels)
            if sname == sysnames[k]:
                out += [[(k, i, gain)] for i in range(len(labels))]
                found_system = True
            elif idx:
                if not conns:
                    conns = [[(k, i, gain)] for i in idx]
                else:
                    for c, i in zip(conns, idx):
                        c.append((k, i, gain))
                found_signal = True
        if found_system and found_signal:
            raise ValueError(f"signal '{sname}' is both signal and system name")
        if found_signal:
            out += conns
        elif not found_system:
            raise ValueError(f"could not find signal {sname}")
    return out


class _Network:
    """The blocks and maps of an interconnection, with python-control's signal propagation."""

    def __init__(self, systems, connect_map, input_map, output_map):
        self.blocks = [tuple(np.array(m, dtype=float) for m in (s.A, s.B, s.C, s.D)) for s in systems]
        self.connect_map, self.input_map, self.output_map = connect_map, input_map, output_map

    def static_io(self, x, u):
        """python-control's ``InterconnectedSystem._compute_static_io``."""
        ninputs, noutputs = self.connect_map.shape
        ulist = np.dot(self.input_map, u)
        ylist = np.zeros((noutputs + ninputs,))
        cycle_count = len(self.blocks) + 1
        while cycle_count > 0:
            si = ii = oi = 0
            for A, B, C, D in self.blocks:
                n, m, p = A.shape[0], B.shape[1], C.shape[0]
                ysys = np.asarray(C @ np.atleast_1d(x[si:si + n]) + D @ np.atleast_1d(ulist[ii:ii + m])).reshape(-1)
                ylist[oi:oi + p] = ysys.reshape((-1,))
                ylist[noutputs + ii:noutputs + ii + m] = ulist[ii:ii + m]
                si, ii, oi = si + n, ii + m, oi + p
            new_ulist = self.connect_map @ ylist[:noutputs] + np.dot(self.input_map, u)
            if (ulist == new_ulist).all():
                break
            ulist = new_ulist
            cycle_count -= 1
        if cycle_count == 0:
            raise AlgebraicLoopError(
                "algebraic loop: the blocks' feedthrough terms form a loop the signals do not "
                "settle through; break it with a block that has states")
        return ulist, ylist

    def rhs(self, x, u):
        x, u = np.array(x, ndmin=1), np.array(u, ndmin=1)
        ulist, _ = self.static_io(x, u)
        xdot = np.zeros((sum(b[0].shape[0] for b in self.blocks),))
        si = ii = 0
        for A, B, _, _ in self.blocks:
            n, m = A.shape[0], B.shape[1]
            if n != 0:
                xdot[si:si + n] = np.asarray(A @ np.atleast_1d(x[si:si + n]) + B @ np.atleast_1d(ulist[ii:ii + m])).reshape(-1)
            si, ii = si + n, ii + m
        return xdot

    def out(self, x, u):
        x, u = np.array(x, ndmin=1), np.array(u, ndmin=1)
        _, ylist = self.static_io(x, u)
        return self.output_map @ ylist

    def linearize(self, nstates: int, ninputs: int):
        """python-control's ``NonlinearIOSystem.linearize(0, 0)`` (forward differences)."""
        x0, u0 = np.ones((nstates,)) * 0, np.ones((ninputs,)) * 0
        F0, H0 = self.rhs(x0, u0), self.out(x0, u0)
        noutputs = self.output_map.shape[0]
        A, B = np.zeros((nstates, nstates)), np.zeros((nstates, ninputs))
        C, D = np.zeros((noutputs, nstates)), np.zeros((noutputs, ninputs))
        for i in range(nstates):
            dx = np.zeros((nstates,))
            dx[i] = _EPS
            A[:, i] = (self.rhs(x0 + dx, u0) - F0) / _EPS
            C[:, i] = (self.out(x0 + dx, u0) - H0) / _EPS
        for i in range(ninputs):
            du = np.zeros((ninputs,))
            du[i] = _EPS
            B[:, i] = (self.rhs(x0, u0 + du) - F0) / _EPS
            D[:, i] = (self.out(x0, u0 + du) - H0) / _EPS
        return A, B, C, D


def _names(given, n: int, what: str, key: str):
    if given is None:
        return None
    given = [given] if isinstance(given, str) else list(given)
    if len(given) != n:
        raise ValueError(f"`{key}` incompatible with `{what}`")
    return given


def interconnect(systems, inplist, outlist, *, inputs=None, outputs=None, name: str = "",
                 check_unused: bool = True) -> StateSpace:
    """Connect state-space blocks by their signal names.

    Reproduces ``control.interconnect(systems, inplist=..., outlist=..., inputs=...,
    outputs=..., name=...)`` with implicit connections: every block input is fed by the
    sum of the block outputs of the same name. The matrices are the same numbers
    python-control gives (see the module note).

    Parameters
    ----------
    systems : list of StateSpace or python-control state-space systems
    inplist : list of str
        External inputs: a signal name feeds every block input of that name (a block's
        name, all its inputs; ``name[k]`` ranges as python-control).
    outlist : list of str
        External outputs: a block output name (``-name`` negates it), or
        ``block.signal`` naming a block output or, failing that, a block input.
    inputs, outputs : list of str, optional
        Names of the connected block's signals (default ``u[k]``, ``y[k]``).
    name : str
    check_unused : bool
        Accepted for python-control's signature; unused signals only warn there.

    Returns
    -------
    StateSpace
        States in block order, named ``block_state``.

    Raises
    ------
    ValueError
        A signal that no block has, a sign on an input, names that do not match the
        lists, blocks with different sample times, or (:class:`AlgebraicLoopError`) a loop
        of feedthrough terms.
    """
    del check_unused
    systems = [as_system(s) for s in systems]
    dts = {s.dt for s in systems}
    if len(dts) > 1:
        raise ValueError("blocks with different sample times cannot be connected")
    sysnames = _sysnames(systems)
    in_off = np.cumsum([0] + [s.ninputs for s in systems])
    out_off = np.cumsum([0] + [s.noutputs for s in systems])
    ninputs, noutputs, nstates = in_off[-1], out_off[-1], sum(s.nstates for s in systems)

    connect_map = np.zeros((ninputs, noutputs))
    for k, s in enumerate(systems):
        for i, label in enumerate(s.inputs):
            for j, t in enumerate(systems):
                if label in t.outputs:
                    connect_map[in_off[k] + i, out_off[j] + t.outputs.index(label)] += 1

    inps = _expand(systems, sysnames, inplist, 'input')
    outs = _expand(systems, sysnames, outlist, 'output')
    inputs = _names(inputs, len(inps), 'inplist', 'inputs')
    outputs = _names(outputs, len(outs), 'outlist', 'outputs')

    input_map = np.zeros((ninputs, len(inps)))
    for index, specs in enumerate(inps):
        for k, i, gain in specs:
            if gain != 1:
                raise ValueError(f"gain not allowed in input {inplist[index]!r}")
            input_map[in_off[k] + i, index] += 1
    output_map = np.zeros((len(outs), noutputs + ninputs))
    for index, specs in enumerate(outs):
        for k, i, gain in specs:
            col = noutputs + in_off[k] + i[1] if isinstance(i, tuple) else out_off[k] + i
            output_map[index, col] += gain

    A, B, C, D = _Network(systems, connect_map, input_map, output_map).linearize(nstates, len(inps))
    states = [f"{sysnames[k]}_{x}" for k, s in enumerate(systems) for x in s.states]
    return StateSpace(A, B, C, D, inputs=inputs, outputs=outputs, states=states, name=name,
                      dt=systems[0].dt if systems else 0.0)


def feedback(sys1, sys2=1.0, sign: int = -1) -> StateSpace:
    """``sys1`` with ``sys2`` in its feedback path (negative feedback for ``sign=-1``):
    python-control's ``StateSpace.feedback``, the same arithmetic (one LU of
    ``I - sign D2 D1`` for both right-hand sides), so the same numbers. A number for either
    is a static gain.

    Raises
    ------
    ValueError
        Blocks whose sizes do not close a loop, or ``I - sign D2 D1`` singular (an algebraic
        loop without a solution).
    """
    def block(s):
        if isinstance(s, (int, float, np.number)):
            return StateSpace(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[float(s)]])
        return as_system(s)
    s1, s2 = block(sys1), block(sys2)
    if s1.ninputs != s2.noutputs or s1.noutputs != s2.ninputs:
        raise ValueError("the blocks' inputs and outputs do not close a feedback loop")
    A1, B1, C1, D1 = s1.A, s1.B, s1.C, s1.D
    A2, B2, C2, D2 = s2.A, s2.B, s2.C, s2.D
    F = np.eye(s1.ninputs) - sign * D2 @ D1
    if np.linalg.matrix_rank(F) != s1.ninputs:
        raise ValueError("I - sign * D2 * D1 is singular to working precision.")
    E_D2_C2 = np.linalg.solve(F, np.concatenate((D2, C2), axis=1))
    E_D2, E_C2 = E_D2_C2[:, :s2.ninputs], E_D2_C2[:, s2.ninputs:]
    T1 = np.eye(s1.noutputs) + sign * D1 @ E_D2
    T2 = np.eye(s1.ninputs) + sign * E_D2 @ D1
    A = np.concatenate((np.concatenate((A1 + sign * B1 @ E_D2 @ C1, sign * B1 @ E_C2), axis=1),
                        np.concatenate((B2 @ T1 @ C1, A2 + sign * B2 @ D1 @ E_C2), axis=1)), axis=0)
    B = np.concatenate((B1 @ T2, B2 @ D1 @ T2), axis=0)
    C = np.concatenate((T1 @ C1, sign * D1 @ E_C2), axis=1)
    return StateSpace(A, B, C, D1 @ T2, dt=s1.dt if s1.nstates else s2.dt)
