"""Parallel runs: ``run_cases`` keeps order with any executor; Kv grids, sine-dwell sweeps and
robustness evaluations on a dask cluster of worker processes equal the serial runs."""

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import servo_toolkit as st
from servo_toolkit.loop.robustness import robustness
from servo_toolkit.core.parallel import chunks, run_cases
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.studies.kv.study import kv_grid, kv_study
from servo_toolkit.studies.sine_dwell import DwellPlan
from servo_toolkit.studies.sweep.compute import sweep
from servo_toolkit.studies.trajectories import SineMotion

from .conftest import SCENES


def _square(x):
    return x * x


def _fail_on_three(x):
    if x == 3:
        raise ValueError("case 3")
    return x


@pytest.mark.parametrize("chunksize", [1, 3, 10])
def test_run_cases_keeps_order_with_an_executor(chunksize):
    with ThreadPoolExecutor(2) as pool:
        assert run_cases(_square, range(10), executor=pool, chunksize=chunksize, progress=False) == \
            [x * x for x in range(10)]
    assert run_cases(_square, [], executor=None) == []
    assert [list(c) for c in chunks([1, 2, 3, 4, 5], 2)] == [[1, 2], [3, 4], [5]]


def test_run_cases_raises_the_case_error():
    with ThreadPoolExecutor(2) as pool, pytest.raises(ValueError, match="case 3"):
        run_cases(_fail_on_three, range(6), executor=pool, progress=False)
    with pytest.raises(ValueError, match="chunksize"):
        run_cases(_square, [1], chunksize=0)


@pytest.fixture(scope="module")
def dask_executor():
    """A local dask cluster of 2 worker processes (1 thread each): the cases are pickled and
    run in other interpreters, as on a real cluster."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        yield client.get_executor()


@pytest.fixture(scope="module")
def ema():
    return load_scene(SCENES / "ema_reference.toml")


def test_kv_grid_on_a_dask_cluster_equals_the_serial_run(ema, dask_executor):
    assert dask_executor.submit(os.getpid).result() != os.getpid()     # other processes
    serial = kv_study(ema, "kv_8hz", samples_per_period=200, progress=False)
    motions = [SineMotion(math.radians(a), 8.0) for a in (2.0, 4.0)]
    on_cluster = kv_study(ema, "kv_8hz", samples_per_period=200, progress=False, executor=dask_executor)
    grid = kv_grid(ema.drivetrain, motions, [2.3], samples_per_period=200, executor=dask_executor,
                   progress=False)
    assert on_cluster.to_dict() == serial.to_dict()
    here = kv_grid(ema.drivetrain, motions, [2.3], samples_per_period=200, progress=False)
    assert grid == here


def test_sweep_on_a_dask_cluster_equals_the_serial_run(ema, dask_executor):
    """Sine dwells of the compiled model run in the worker processes (the model is pickled
    there) and give the same responses, flags and peaks as here."""
    kw = dict(frequencies=[2.0, 8.0], amplitudes=[math.radians(0.5), math.radians(2.0)],
              plan=DwellPlan(settling_time_constants=3.0, estimation_cycles=2), progress=False)
    serial = sweep(ema, **kw)
    on_cluster = sweep(ema, executor=dask_executor, **kw)
    np.testing.assert_array_equal(on_cluster.response, serial.response)
    np.testing.assert_array_equal(on_cluster.saturated, serial.saturated)
    np.testing.assert_array_equal(on_cluster.peak_current_A, serial.peak_current_A)
    assert on_cluster.errors == serial.errors and np.all(np.isfinite(serial.response))


def test_robustness_on_a_dask_cluster_equals_the_serial_run(ema, dask_executor):
    """Margins of 200 load-inertia/stiffness variants in chunks of 50 on the cluster equal
    the serial evaluation, and so do the worst cases."""
    design = st.design(ema, resonance_filter="none")
    serial = robustness(ema, design, samples=200, seed=5, progress=False)
    on_cluster = robustness(ema, design, samples=200, seed=5, executor=dask_executor, chunk_size=50,
                            progress=False)
    for key in serial.figures:
        np.testing.assert_array_equal(on_cluster.figures[key], serial.figures[key])
    assert [c.achieved for c in on_cluster.requirements] == [c.achieved for c in serial.requirements]


def test_montecarlo_chunks_on_a_dask_cluster_equal_the_serial_run(ema, dask_executor):
    """Chunks of nonlinear closed-loop variants run in the cluster's worker processes (the
    batched kernel compiled or loaded there) and give the same figures as here."""
    from servo_toolkit.studies.montecarlo import montecarlo
    kw = dict(samples=12, seed=7, duration=0.2, progress=False)
    variants = {"load_inertia": (0.0, 4.0), "stiffness": (0.8, 1.2)}
    serial = montecarlo(ema, variants, **kw)
    on_cluster = montecarlo(ema, variants, executor=dask_executor, chunk_size=4, **kw)
    for name in variants:
        np.testing.assert_array_equal(on_cluster.values[name], serial.values[name])
    np.testing.assert_array_equal(on_cluster.tracking_error, serial.tracking_error)
    np.testing.assert_array_equal(on_cluster.peak_current, serial.peak_current)
    np.testing.assert_array_equal(on_cluster.failed, serial.failed)
    assert np.all(np.isfinite(serial.tracking_error))
