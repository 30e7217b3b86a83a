"""Running many independent cases: an optional executor and a progress bar."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from tqdm.auto import tqdm


def run_cases(function: Callable, cases: Sequence, *, executor=None, progress: bool | str = True,
              description: str = "cases") -> list:
    """Evaluate ``function(case)`` for every case, in order.

    Parameters
    ----------
    function : callable
        A picklable function of one case (a module-level function for process pools and
        dask clusters).
    cases : sequence
    executor : concurrent.futures.Executor, optional
        E.g. ``ProcessPoolExecutor()`` or a dask ``Client.get_executor()``; None runs here.
    progress : bool
        Show a tqdm progress bar (stderr in a terminal, a widget in Jupyter).
    description : str
        Label of the progress bar.

    Returns
    -------
    list
        Results in the order of ``cases``.
    """
    cases = list(cases)
    bar = tqdm(total=len(cases), desc=description, disable=not progress or len(cases) < 2, leave=False)
    try:
        if executor is None:
            results = []
            for case in cases:
                results.append(function(case))
                bar.update()
            return results
        futures = [executor.submit(function, case) for case in cases]
        results = []
        for future in futures:
            results.append(future.result())
            bar.update()
        return results
    finally:
        bar.close()


def chunks(items: Sequence, size: int) -> Iterable[Sequence]:
    """Consecutive slices of at most ``size`` items."""
    for start in range(0, len(items), size):
        yield items[start:start + size]
