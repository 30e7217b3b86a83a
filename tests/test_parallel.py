"""Parallel runs: ``run_cases`` keeps order with any executor; a Kv grid on a dask cluster."""

import math
from concurrent.futures import ThreadPoolExecutor

import pytest

from servo_toolkit.parallel import chunks, run_cases
from servo_toolkit.scene import load_scene
from servo_toolkit.studies.kv import kv_grid, kv_study
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


def test_kv_grid_on_a_dask_cluster_equals_the_serial_run():
    distributed = pytest.importorskip("distributed")
    scene = load_scene(SCENES / "ema_reference.toml")
    serial = kv_study(scene, "kv_8hz", samples_per_period=200, progress=False)
    motions = [SineMotion(math.radians(a), 8.0) for a in (2.0, 4.0)]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        executor = client.get_executor()
        on_cluster = kv_study(scene, "kv_8hz", samples_per_period=200, progress=False, executor=executor)
        grid = kv_grid(scene.drivetrain, motions, [2.3], samples_per_period=200, executor=executor,
                       progress=False)
    assert on_cluster.to_dict() == serial.to_dict()
    here = kv_grid(scene.drivetrain, motions, [2.3], samples_per_period=200, progress=False)
    assert grid == here
