"""``--scheduler`` (and ``DASK_SCHEDULER_ADDRESS``): the commands send their chunks to a
running dask.distributed cluster and print what they print in one process.

The cluster is real: a ``dask scheduler`` on the loopback address and a ``dask worker`` with
two worker processes of one thread, started as separate programs (this checkout on their
path) and stopped at the end. The commands run in this process, once without the cluster and
once with it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from argparse import Namespace
from pathlib import Path
from types import SimpleNamespace

import pytest

from servo_toolkit.cli import main
from servo_toolkit.core.cluster import ENV_VAR, INSTALL_HINT, SchedulerAddress, scheduler_address

ROOT = Path(__file__).resolve().parents[1]
EMA = str(ROOT / "scenes" / "ema_reference.toml")
EMA_ROBUST = str(ROOT / "scenes" / "ema_robust.toml")
EMA_TOLERANCES = str(ROOT / "scenes" / "examples" / "ema_tolerances.toml")


def _env(**extra) -> dict:
    """The environment of a child process: this checkout first, no scheduler from outside."""
    env = {k: v for k, v in os.environ.items() if k != ENV_VAR}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    env.update(extra)
    return env


def _stop(process: subprocess.Popen) -> None:
    """SIGTERM to the process's own group (it and the workers it started), then SIGKILL."""
    if process.poll() is not None:
        return
    for sig, wait in ((signal.SIGTERM, 15), (signal.SIGKILL, 5)):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            return
        try:
            process.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


@pytest.fixture(scope="module")
def cluster(tmp_path_factory, request):
    """The address of a scheduler on 127.0.0.1 with two single-thread workers."""
    distributed = pytest.importorskip("distributed")
    folder = tmp_path_factory.mktemp("dask")
    scheduler_file = folder / "scheduler.json"
    dask = [sys.executable, "-m", "dask"]
    logs = []

    def start(args, name):
        log = open(folder / f"{name}.log", "wb")
        logs.append(log)
        process = subprocess.Popen(dask + args, cwd=folder, env=_env(), stdout=log, stderr=subprocess.STDOUT,
                                   start_new_session=True)
        request.addfinalizer(lambda: _stop(process))
        return process

    request.addfinalizer(lambda: [log.close() for log in logs])
    scheduler = start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                       "--scheduler-file", str(scheduler_file)], "scheduler")
    deadline = time.monotonic() + 60
    while not scheduler_file.exists() or not scheduler_file.read_text().strip().endswith("}"):
        assert scheduler.poll() is None, (folder / "scheduler.log").read_text()
        assert time.monotonic() < deadline, "the scheduler did not start within 60 s"
        time.sleep(0.2)
    address = json.loads(scheduler_file.read_text())["address"]
    start(["worker", address, "--nthreads", "1", "--nworkers", "2", "--host", "127.0.0.1", "--no-dashboard",
           "--local-directory", str(folder)], "worker")
    with distributed.Client(address, timeout=30, set_as_default=False) as client:
        client.wait_for_workers(2, timeout=60)
    return address


def _chunks_run(address) -> int:
    """Chunks of cases (the tasks of ``run_cases``, prefix ``apply_chunk``) the cluster has computed so far."""
    import distributed
    with distributed.Client(address, timeout=30, set_as_default=False) as client:
        counts = client.run_on_scheduler(
            lambda dask_scheduler: {k: dict(p.state_counts) for k, p in dask_scheduler.task_prefixes.items()})
    return counts.get("apply_chunk", {}).get("memory", 0)


def _run(args, capsys) -> tuple:
    """``servo-toolkit ARGS --json`` (in this process): (exit code, JSON, stderr)."""
    code = main([*args, "--json"])
    captured = capsys.readouterr()
    assert code in (0, 1), captured.err
    return code, json.loads(captured.out), captured.err


def _without_wall_clock(value):
    """``value`` without its wall-clock fields (``wall_s``, anywhere)."""
    if isinstance(value, dict):
        return {k: _without_wall_clock(v) for k, v in value.items() if k != "wall_s"}
    if isinstance(value, list):
        return [_without_wall_clock(v) for v in value]
    return value


@pytest.mark.parametrize("args, how", [
    (["montecarlo", EMA, "--samples", "16", "--duration", "0.02"], "option"),
    (["check", EMA_ROBUST, "--linear-only", "--samples", "200"], "option"),
    (["sweep", EMA, "--frequency", "4", "--frequency", "8", "--amplitude", "0.5 deg"], "environment"),
    (["tolerances", EMA_TOLERANCES, "--samples", "64", "--nonlinear", "--duration", "0.02"], "option"),
])
def test_a_command_on_the_cluster_prints_what_it_prints_in_one_process(cluster, args, how, capsys, monkeypatch):
    """The chunks run in the cluster's worker processes (the scheduler counts them) and the
    JSON equals the one-process run's, but for the wall-clock fields."""
    monkeypatch.delenv(ENV_VAR, raising=False)
    here_code, here, _ = _run(args, capsys)
    before = _chunks_run(cluster)
    if how == "option":
        code, there, err = _run(args + ["--scheduler", cluster], capsys)
    else:  # dask's own variable, when --scheduler is absent
        monkeypatch.setenv(ENV_VAR, cluster)
        code, there, err = _run(args, capsys)
    assert _chunks_run(cluster) > before
    assert f"dask cluster at {cluster}" in err and "2 worker threads" in err
    assert code == here_code
    assert _without_wall_clock(there) == _without_wall_clock(here)


def _one_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and captured.out == "", captured.err
    return lines[0]


@pytest.mark.parametrize("command", [["montecarlo", EMA, "--workers", "2"], ["sweep", EMA, "--workers", "2"]])
def test_scheduler_and_workers_exclude_each_other(command, capsys):
    assert main([*command, "--scheduler", "tcp://127.0.0.1:8786"]) == 2
    line = _one_line(capsys)
    assert line.startswith("servo-toolkit: error: --scheduler: excludes --workers") and "(got --workers 2)" in line


def test_an_unreachable_scheduler_is_one_line_naming_the_option_and_address(capsys, monkeypatch):
    pytest.importorskip("distributed")
    import socket
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.delenv(ENV_VAR, raising=False)
    address = f"tcp://127.0.0.1:{port}"
    assert main(["montecarlo", EMA, "--samples", "2", "--duration", "0.02", "--scheduler", address]) == 2
    line = _one_line(capsys)
    assert line.startswith("servo-toolkit: error: --scheduler: cannot reach a dask scheduler") and address in line


def test_a_bad_address_from_the_environment_names_the_variable(capsys, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setenv(ENV_VAR, "no-port-here")
    assert main(["sweep", EMA, "--frequency", "8"]) == 2
    line = _one_line(capsys)
    assert line.startswith(f"servo-toolkit: error: {ENV_VAR}: is not a dask scheduler address") and \
        "(got no-port-here)" in line


def test_without_distributed_the_line_says_to_install_the_cluster_extra(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    assert main(["check", EMA_ROBUST, "--linear-only", "--samples", "20", "--scheduler", "127.0.0.1:8786"]) == 2
    line = _one_line(capsys)
    assert line.startswith("servo-toolkit: error: --scheduler:") and line.endswith(INSTALL_HINT)


def test_the_environment_gives_the_scheduler_unless_an_option_decides(monkeypatch):
    env = {ENV_VAR: " tcp://10.0.0.5:8786 "}
    assert scheduler_address(None, {}) is None and scheduler_address(None, {ENV_VAR: ""}) is None
    assert scheduler_address(None, env) == SchedulerAddress("tcp://10.0.0.5:8786", ENV_VAR)
    assert scheduler_address("10.0.0.6:8786", env) == SchedulerAddress("10.0.0.6:8786", "--scheduler")
    from servo_toolkit.cli.common import scheduler_of
    monkeypatch.delenv(ENV_VAR, raising=False)
    assert scheduler_of(Namespace(scheduler=None, workers=None)) is None


def test_workers_on_the_command_line_win_over_the_environment(monkeypatch):
    from servo_toolkit.cli.common import scheduler_of
    monkeypatch.setenv(ENV_VAR, "tcp://10.0.0.5:8786")
    assert scheduler_of(Namespace(scheduler=None, workers=2)) is None
    assert scheduler_of(Namespace(scheduler=None, workers=None)) == SchedulerAddress("tcp://10.0.0.5:8786", ENV_VAR)
    assert scheduler_of(Namespace(scheduler=None)).key == ENV_VAR  # check has no --workers


def test_a_cluster_failure_during_the_run_is_one_error_naming_the_option(cluster):
    """A worker lost mid-run (dask's KilledWorker) becomes a SceneError naming the key and the
    address; an error of the work itself keeps its type."""
    import distributed

    from servo_toolkit.core.cluster import open_cluster
    from servo_toolkit.errors import SceneError
    with pytest.raises(SceneError, match=r"^--scheduler: the dask cluster failed during the run: KilledWorker"):
        with open_cluster(SchedulerAddress(cluster)):
            raise distributed.KilledWorker("apply_chunk-0", SimpleNamespace(address="tcp://127.0.0.1:1"), 3)
    with pytest.raises(ValueError, match="the work's own error"):
        with open_cluster(SchedulerAddress(cluster, ENV_VAR)):
            raise ValueError("the work's own error")


@pytest.mark.parametrize("command", ["montecarlo", "sweep", "check", "tolerances"])
def test_help_names_the_option_and_the_environment_variable(command, monkeypatch):
    from servo_toolkit.cli import build_parser
    monkeypatch.setenv("COLUMNS", "1000")  # no line wrapped inside a word
    parser = build_parser(only=command)
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    text = " ".join(sub.format_help().split())
    assert "--scheduler ADDRESS" in text and ENV_VAR in text and "servo-toolkit[cluster]" in text
