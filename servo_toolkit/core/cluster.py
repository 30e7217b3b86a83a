"""Chunks of a study on an existing dask.distributed cluster.

The studies take any ``concurrent.futures.Executor`` (:mod:`.parallel`); this module opens
the one of a running dask scheduler, given its address, and closes it afterwards. The
``distributed`` package (the ``cluster`` extra) is imported only here and only when a
cluster is asked for. Every failure before the work starts (the package missing, an address
that does not parse or answers no scheduler, a scheduler without workers, workers that
cannot import this toolkit or run another version of it) is a
:class:`~servo_toolkit.errors.SceneError` naming the option or variable that gave the
address, so the command line reports it in one line (exit 2).

The results do not depend on where a chunk runs: a study draws every variant from its seed
before it cuts them into chunks, and each chunk is a pure function of its own inputs.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import os
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

from ..errors import SceneError
from .version import __version__

#: the environment variable dask itself reads for the scheduler's address
ENV_VAR = "DASK_SCHEDULER_ADDRESS"
#: seconds to reach the scheduler
CONNECT_TIMEOUT_S = 5.0
#: seconds for the scheduler's first worker to join (a cluster that is scaling up)
WORKER_TIMEOUT_S = 30.0
#: what to do when ``distributed`` is missing
INSTALL_HINT = "install the cluster extra: pip install 'servo-toolkit[cluster]'"


@dataclass(frozen=True)
class SchedulerAddress:
    """Where a dask scheduler listens, and what gave the address.

    Attributes
    ----------
    address : str
        E.g. ``tcp://10.0.0.5:8786`` or ``10.0.0.5:8786``.
    key : str
        The option (``--scheduler``) or environment variable (``DASK_SCHEDULER_ADDRESS``)
        that gave it: the key an error names.
    """

    address: str
    key: str = "--scheduler"


@dataclass(frozen=True)
class Cluster:
    """An open connection to a dask cluster.

    Attributes
    ----------
    executor : concurrent.futures.Executor
        The client's executor (``Client.get_executor()``), for the studies' ``executor=``.
    address : str
        The scheduler's address as resolved.
    threads : int
        Worker threads of the cluster when it was opened (at least 1): how many chunks run
        at once.
    """

    executor: object
    address: str
    threads: int

    def __repr__(self) -> str:
        return f"<Cluster at {self.address}: {self.threads} worker threads>"


def scheduler_address(option: str | None, environ: Mapping[str, str] | None = None) -> SchedulerAddress | None:
    """The scheduler to use: ``option`` (``--scheduler``) when given, else dask's own
    ``DASK_SCHEDULER_ADDRESS`` from ``environ`` (default ``os.environ``) when set and not
    empty, else None (run here).

    Parameters
    ----------
    option : str or None
    environ : mapping, optional

    Returns
    -------
    SchedulerAddress or None

    Raises
    ------
    SceneError
        ``option`` is given but empty.
    """
    if option is not None:
        if not option.strip():
            raise SceneError("--scheduler", "must be a scheduler address such as tcp://HOST:8786 (got '')")
        return SchedulerAddress(option.strip(), "--scheduler")
    value = (os.environ if environ is None else environ).get(ENV_VAR, "").strip()
    return SchedulerAddress(value, ENV_VAR) if value else None


def toolkit_version() -> str:
    """This toolkit's version where it runs (a worker runs it to show it can import the
    toolkit, and which version it has)."""
    return __version__


def _import_distributed(key: str):
    try:
        import distributed
    except ImportError:
        raise SceneError(key, f"needs dask.distributed, which is not installed; {INSTALL_HINT}") from None
    return distributed


def _resolve(address: str, key: str) -> str:
    """``address`` with its protocol (``tcp://`` by default), or a SceneError."""
    from distributed.comm import resolve_address
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return resolve_address(address)
    except Exception as exc:  # a malformed address, an unknown host or protocol
        raise SceneError(key, f"is not a dask scheduler address such as tcp://HOST:8786: {_first_line(exc)} "
                              f"(got {address})") from None


def _first_line(exc: BaseException) -> str:
    try:
        text = str(exc).strip().splitlines()
    except Exception:  # an exception that cannot say what it is
        text = []
    return text[0] if text else type(exc).__name__


def _worker_check(client, address: str, key: str, timeout: float = WORKER_TIMEOUT_S) -> int:
    """Worker threads of the cluster, once it has a worker that runs this toolkit's version."""
    try:
        client.wait_for_workers(1, timeout=timeout)
    except Exception:
        raise SceneError(key, f"the dask scheduler has no worker (none joined within {timeout:g} s) "
                              f"(got {address})") from None
    try:
        versions = client.run(toolkit_version)
    except Exception as exc:
        raise SceneError(key, f"the cluster's workers cannot import servo_toolkit ({_first_line(exc)}); install "
                              f"servo-toolkit {__version__} where they run (got {address})") from None
    other = sorted({v for v in versions.values() if v != __version__})
    if other:
        raise SceneError(key, f"the cluster's workers run servo-toolkit {', '.join(other)}, this is "
                              f"{__version__}: install the same version there (got {address})")
    return max(1, sum(client.nthreads().values()))


def is_cluster_failure(exc: BaseException) -> bool:
    """True when ``exc`` comes from the cluster rather than from the work: an error of dask
    or its network layer (a worker that died, a closed connection, a cancelled task) or a
    lost connection. An error a chunk raises itself comes back with its own type."""
    module = type(exc).__module__ or ""
    return module.split(".")[0] in ("distributed", "tornado") or \
        isinstance(exc, (ConnectionError, TimeoutError, cf.CancelledError))


@contextlib.contextmanager
def open_cluster(scheduler: SchedulerAddress, *, timeout: float = CONNECT_TIMEOUT_S,
                 worker_timeout: float = WORKER_TIMEOUT_S) -> Iterator[Cluster]:
    """Connect to the dask scheduler at ``scheduler.address``, yield its executor, close the
    connection on leaving (the cluster itself keeps running).

    Parameters
    ----------
    scheduler : SchedulerAddress
    timeout : float
        Seconds to reach the scheduler.
    worker_timeout : float
        Seconds for its first worker to join.

    Yields
    ------
    Cluster

    Raises
    ------
    SceneError
        Naming ``scheduler.key``: ``distributed`` is not installed (the message says how to
        install the ``cluster`` extra), the address does not parse, no scheduler answers
        there within ``timeout``, no worker joins within ``worker_timeout``, or the workers cannot
        import this toolkit or have another version of it; or, while the work runs, the
        cluster fails (:func:`is_cluster_failure`: a worker dies, the scheduler goes away).
    """
    key, address = scheduler.key, scheduler.address
    distributed = _import_distributed(key)
    resolved = _resolve(address, key)
    try:
        client = distributed.Client(resolved, timeout=timeout, set_as_default=False)
    except Exception:  # OSError: nothing answers there; TimeoutError
        raise SceneError(key, f"cannot reach a dask scheduler within {timeout:g} s (got {address})") from None
    try:
        threads = _worker_check(client, address, key, worker_timeout)
        try:
            yield Cluster(client.get_executor(), resolved, threads)
        except Exception as exc:
            if isinstance(exc, SceneError) or not is_cluster_failure(exc):
                raise
            raise SceneError(key, f"the dask cluster failed during the run: {type(exc).__name__}: "
                                  f"{_first_line(exc)} (got {address})") from None
    finally:
        with contextlib.suppress(Exception):  # a scheduler already gone: nothing left to close
            client.close()
