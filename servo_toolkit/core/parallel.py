"""Running many independent cases: an optional executor and a progress bar."""

from __future__ import annotations

import concurrent.futures as cf
from collections.abc import Callable, Iterable, Sequence

from .progress import progress_bar


def _apply_chunk(function: Callable, chunk: Sequence) -> list:
    """``[function(c) for c in chunk]``; module level so that executors can pickle it."""
    return [function(case) for case in chunk]


def run_cases(function: Callable, cases: Sequence, *, executor=None, progress: bool | str = True,
              description: str = "cases", chunksize: int = 1) -> list:
    """Evaluate ``function(case)`` for every case; results keep the order of ``cases``.

    Parameters
    ----------
    function : callable
        A picklable function of one case (a module-level function for process pools and
        dask clusters).
    cases : sequence
    executor : concurrent.futures.Executor, optional
        E.g. :func:`process_pool` (a ``ProcessPoolExecutor`` with spawned workers) or a dask
        ``Client.get_executor()``; None runs here.
    progress : bool
        Show a tqdm progress bar (stderr in a terminal, a widget in Jupyter); it advances as
        cases finish, in whatever order they finish.
    description : str
        Label of the progress bar.
    chunksize : int
        Cases sent to the executor per task (larger chunks cut per-task overhead for many
        cheap cases). Ignored without an executor.

    Returns
    -------
    list
        Results in the order of ``cases``.

    Raises
    ------
    Exception
        The first exception a case raised (in the order cases finished); the cases not
        started yet are cancelled.
    """
    cases = list(cases)
    if chunksize < 1:
        raise ValueError(f"chunksize must be >= 1, got {chunksize}")
    bar = progress_bar(total=len(cases), show=bool(progress) and len(cases) >= 2, desc=description, leave=False)
    try:
        if executor is None:
            results = []
            for case in cases:
                results.append(function(case))
                bar.update()
            return results
        chunks_ = list(chunks(cases, chunksize))
        futures = {executor.submit(_apply_chunk, function, chunk): i for i, chunk in enumerate(chunks_)}
        out: list = [None] * len(chunks_)
        try:
            for future in cf.as_completed(futures):
                out[futures[future]] = future.result()
                bar.update(len(chunks_[futures[future]]))
        except BaseException:
            for future in futures:
                future.cancel()
            raise
        return [r for chunk in out for r in chunk]
    finally:
        bar.close()


def process_pool(workers: int) -> cf.ProcessPoolExecutor:
    """A process pool of ``workers`` processes started with the ``spawn`` method.

    ``fork`` (Linux's default) copies a process whose OpenMP / BLAS threads are
    already running, and GNU OpenMP aborts the child ("fork() called from a process already
    using GNU OpenMP"): the pool breaks. Spawned workers import the toolkit afresh (its compiled
    kernels are part of the installed package), which is safe with every threaded library.

    Parameters
    ----------
    workers : int
        Number of processes (at least 1).

    Returns
    -------
    concurrent.futures.ProcessPoolExecutor
    """
    import multiprocessing

    return cf.ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))


def chunks(items: Sequence, size: int) -> Iterable[Sequence]:
    """Consecutive slices of at most ``size`` items."""
    for start in range(0, len(items), size):
        yield items[start:start + size]
