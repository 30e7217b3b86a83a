"""A long compiled run honours Ctrl-C and SIGTERM: the fixed-step loops and the batch of
variants run in chunks, one compiled call each, whose numbers are bit for bit those of one
call; the command line then exits 130 (SIGINT) or 143 (SIGTERM) with one line and leaves no
output behind, from a simulation as from a Monte Carlo batch."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from servo_toolkit.loop.default_controller import default_controller
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model
from servo_toolkit.sim import batch_run
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.batch import run_variants
from servo_toolkit.sim.integrators import integrate
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.tables import frozen_tables
from servo_toolkit.sim.variants import VariantBuilder

from .conftest import SCENES

ROOT = Path(__file__).resolve().parents[1]


def _run(model, P, x0, dt, n_steps, paper, chunk):
    """Every output of one :func:`integrate` call in ``chunk`` steps per compiled call."""
    rec = 37  # records that straddle the chunks' ends
    n_rec = n_steps // rec + 2
    x = x0.copy()
    out_t, out_x, out_aux = np.zeros(n_rec), np.zeros((n_rec, model.nx)), np.zeros((n_rec, lo.NAUX))
    fig, snap = np.full(lo.NFIG, np.nan), np.zeros((lo.NSNAP, model.nx + 2))
    sub = int(round(model.sample_time / dt))
    ret = integrate(x, P, model.T, 0.0, dt, n_steps, sub, 0.0, paper, rec, out_t, out_x, out_aux, fig, snap,
                    chunk=chunk)
    return ret, x, out_t, out_x, out_aux, fig, snap


@pytest.mark.parametrize("chain, friction, paper", [("full", "stick", False), ("two_mass", "smooth", True)])
def test_a_run_in_chunks_gives_the_numbers_of_one_call(chain, friction, paper):
    """The full chain with friction that holds (split steps, a sampled controller, every
    figure and snapshot) and the paper's scheme: chunks of 7 steps (they end between two
    controller samples and between two records), 1000 steps and the adaptive default equal
    one call exactly."""
    scene = load_scene(SCENES / "ema_reference.toml")
    model = build_model(scene, default_controller(scene), ModelOptions(chain=chain, friction=friction))
    P = fill(model, Reference.sine(math.radians(2.0), 8.0))
    x0 = initial_state(model, P)
    dt = model.sample_time / 20
    n_steps = 6000
    whole = _run(model, P, x0, dt, n_steps, paper, n_steps + 1)
    assert whole[0][0] == lo.OK and whole[0][1] == n_steps
    assert whole[0][2] == n_steps // 37 + 2 and np.all(np.isfinite(whole[3]))
    for chunk in (7, 1000, None):
        got = _run(model, P, x0, dt, n_steps, paper, chunk)
        assert got[0] == whole[0], chunk
        for a, b in zip(got[1:], whole[1:]):
            assert np.array_equal(a, b, equal_nan=True), chunk


@pytest.mark.parametrize("threads", [1, 2])
def test_variants_in_calls_of_a_few_give_the_numbers_of_one_call(monkeypatch, threads):
    """43 variants of load inertia and stiffness in :func:`batch_run.integrate_variants`' calls
    of one variant per thread each equal one call of the batch on one thread, bit for bit."""
    scene = load_scene(SCENES / "ema_reference.toml")
    controller = default_controller(scene)
    ref = Reference.sine(math.radians(2.0), 8.0)
    builder = VariantBuilder.create(scene, controller, ModelOptions())
    rng = np.random.default_rng(3)
    n = 43
    values = {"load_inertia": rng.uniform(0.0, 4.0, n), "stiffness": rng.uniform(0.7, 1.3, n)}
    P, T, tix = builder.rows(fill(builder.model, ref), values, lambda m: fill(m, ref))
    X0 = np.array([initial_state(builder.model, p) for p in P])
    dt, n_steps = builder.model.sample_time / 10, 2000
    calls = []
    real = batch_run.run_variants

    def counted(X, *args):
        calls.append(len(X))
        return real(X, *args)

    monkeypatch.setattr(batch_run, "CHUNK_S", 0.0)  # the fewest variants a call: one per thread
    monkeypatch.setattr(batch_run, "run_variants", counted)
    X, figs, snaps, _ = batch_run.integrate_variants(P, T, tix, X0, dt, n_steps, 10, threads=threads)
    assert len(calls) == -(-n // threads) and max(calls) == threads
    one = (X0.copy(), np.zeros_like(figs), np.zeros_like(snaps))
    run_variants(one[0], np.ascontiguousarray(P), frozen_tables(T), np.ascontiguousarray(tix, dtype=np.int64), dt,
                 n_steps, 10, one[1], one[2], 1)
    assert np.all(figs[:, lo.F_STATUS] == lo.OK) and np.all(figs[:, lo.F_STEP] == n_steps)
    for a, b in zip((X, figs, snaps), one):
        assert np.array_equal(a, b)


_CHILD = textwrap.dedent("""
    import sys
    from servo_toolkit.sim import fixed_run
    real = fixed_run.integrate

    def integrate(*args, **kwargs):
        if args[5] > 1000:  # the run itself, not the zero-step warm-up
            print("long run started", file=sys.stderr, flush=True)
        return real(*args, **kwargs)

    fixed_run.integrate = integrate
    from servo_toolkit.cli import main
    sys.exit(main(sys.argv[1:]))
""")


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_long_simulation_ends_on_a_signal_with_one_line_and_no_output(tmp_path, sig, code, word):
    """``simulate --full --friction stick`` of a 59 s study at a 0.2 us step (3e8 steps, far
    more than a minute of the compiled loop) is signalled once its run has started: it exits
    with 130 or 143 and one line, long before the run would end, and writes no trace file."""
    scene = tmp_path / "long.toml"
    scene.write_text((SCENES / "ema_reference.toml").read_text() + textwrap.dedent("""
        [studies.long]
        kind = "simulate"
        amplitude = "2 deg"
        frequency = "1 Hz"
        duration = "59 s"
        """))
    out = tmp_path / "out" / "trace.npz"
    out.parent.mkdir()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    child = subprocess.Popen([sys.executable, "-c", _CHILD, "simulate", str(scene), "--study", "long", "--full",
                              "--friction", "stick", "--method", "rk4", "--dt", "2e-7", "--force", "-o", str(out)],
                             cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        for line in child.stderr:  # compiling, notes ... until the long run starts
            lines.append(line)
            if "long run started" in line:
                break
        assert child.poll() is None, "".join(lines)
        time.sleep(1.0)
        child.send_signal(sig)
        rest_out, rest_err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == code, rest_err
    assert rest_err.strip().splitlines() == [f"servo-toolkit: {word}"]
    assert rest_out == ""
    assert list(out.parent.iterdir()) == []


_BATCH_CHILD = textwrap.dedent("""
    import sys
    from servo_toolkit.sim import batch_run
    real = batch_run.run_variants

    def run_variants(X, P, T, tix, dt, n_steps, *args):
        print("long batch started", file=sys.stderr, flush=True)
        return real(X, P, T, tix, dt, n_steps, *args)

    batch_run.run_variants = run_variants
    from servo_toolkit.cli import main
    sys.exit(main(sys.argv[1:]))
""")


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_long_batch_ends_on_a_signal_with_one_line(tmp_path, sig, code, word):
    """``montecarlo`` of 2000 variants of a 59 s run (minutes of the compiled batch on every
    core) is signalled once its first call of the batch has started: between two of
    :func:`~servo_toolkit.sim.batch_run.integrate_variants`' calls it exits with 130 or 143
    and one line, long before the batch would end."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    child = subprocess.Popen([sys.executable, "-c", _BATCH_CHILD, "montecarlo", str(SCENES / "ema_reference.toml"),
                              "--samples", "2000", "--duration", "59", "--force"],
                             cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        for line in child.stderr:  # notes ... until the batch starts
            lines.append(line)
            if "long batch started" in line:
                break
        assert child.poll() is None, "".join(lines)
        time.sleep(1.0)
        signalled = time.perf_counter()
        child.send_signal(sig)
        rest_out, rest_err = child.communicate(timeout=60)
        waited = time.perf_counter() - signalled
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == code, rest_err
    assert [line for line in rest_err.strip().splitlines() if line != "long batch started"] == \
        [f"servo-toolkit: {word}"]
    assert rest_out == ""
    assert waited < 10.0, waited  # a few calls of about CHUNK_S each, not the batch
