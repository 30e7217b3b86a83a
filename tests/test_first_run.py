"""A fresh install: light imports, a complete first report on an empty compiled-code cache,
and a cache that follows the kernel sources and works for a read-only installation."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from servo_toolkit import cli
from servo_toolkit.core import jit_cache

from .conftest import ROOT

HEAVY = ("control", "scipy", "numba", "llvmlite", "matplotlib", "pint")


def _run(code, env=None, timeout=120):
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                          cwd=ROOT, env={**os.environ, **(env or {})})


def _heavy_loaded(argv) -> list:
    """The numerical libraries in ``sys.modules`` after ``import servo_toolkit.cli`` and, with
    ``argv``, after the command line ``argv`` (a ``--help``) ran in a new process."""
    code = ("import sys, contextlib, io, json\n"
            "import servo_toolkit.cli\n"
            f"argv = {argv!r}\n"
            "if argv is not None:\n"
            "    with contextlib.redirect_stdout(io.StringIO()):\n"
            "        try:\n            servo_toolkit.cli.main(argv)\n        except SystemExit:\n            pass\n"
            f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r}))))")
    proc = _run(code)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_import_and_help_load_no_numerical_library():
    assert _heavy_loaded(None) == []
    assert _heavy_loaded(["--help"]) == []


@pytest.mark.parametrize("command", list(cli.COMMANDS))
def test_a_commands_help_loads_no_numerical_library(command):
    """``servo-toolkit CMD --help`` builds the command's parser from the light command-line
    modules alone: no scipy, python-control, numba, matplotlib nor pint."""
    assert _heavy_loaded([command, "--help"]) == []


#: records, in a new process, which module first imported matplotlib during a command
_FIRST_IMPORTER = """
import contextlib, io, json, sys

class Watch:
    importer = None

    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] == "matplotlib" and Watch.importer is None:
            frame = sys._getframe(1)
            while frame is not None and (frame.f_code.co_filename.startswith("<frozen")
                                         or frame.f_globals.get("__name__") == __name__):
                frame = frame.f_back
            Watch.importer = frame.f_globals.get("__name__") if frame is not None else "?"
        return None

sys.meta_path.insert(0, Watch())
import servo_toolkit.cli
with contextlib.redirect_stdout(io.StringIO()):
    code = servo_toolkit.cli.main(sys.argv[1:])
toolkit = sorted(m for m in sys.modules if m.startswith("servo_toolkit."))
print(json.dumps({"code": code, "importer": Watch.importer, "toolkit": toolkit}))
"""


@pytest.fixture(scope="module")
def check_imports():
    """What a text verdict of the reference scene imports: ``check`` run in a new process."""
    proc = subprocess.run([sys.executable, "-c", _FIRST_IMPORTER, "check",
                           str(ROOT / "servo_toolkit" / "data" / "ema_reference.toml")],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_a_text_verdict_loads_no_plotting_of_its_own(check_imports):
    """``check`` prints a table: it loads no report, tuner or figure module of the toolkit,
    and no toolkit module imports matplotlib on its way (python-control does, below)."""
    assert check_imports["code"] == 0
    plotting = [m for m in check_imports["toolkit"] if m.split(".")[1] in ("report", "tuner") or m.endswith("_plot")]
    assert plotting == []
    importer = check_imports["importer"]
    assert importer is None or not importer.startswith("servo_toolkit"), importer


@pytest.mark.xfail(strict=True, reason="python-control 0.10 imports matplotlib.pyplot (and scipy.signal) when it "
                                       "is imported, and the loop's systems are python-control's")
def test_a_text_verdict_imports_no_matplotlib(check_imports):
    assert check_imports["importer"] is None


def test_a_commands_process_defers_the_cyclic_collector(tmp_path):
    """The console script runs one command per process: the collector runs seldom while the
    libraries load and leaves the objects that live until the end out of its collection at
    exit."""
    code = ("import atexit, gc, sys\n"
            "from servo_toolkit.cli import GC_THRESHOLD, entry\n"
            "atexit.register(lambda: print(gc.get_threshold()[0] == GC_THRESHOLD, gc.get_freeze_count() > 1000))\n"
            f"sys.argv = ['servo-toolkit', 'new', {str(tmp_path / 'a.toml')!r}]\n"
            "entry()\n")
    proc = _run(code)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[-2:] == ["True", "True"]
    assert (tmp_path / "a.toml").is_file()


def test_lazy_names_resolve():
    import servo_toolkit as st
    assert callable(st.design) and callable(st.load_scene) and callable(st.simulate) and callable(st.export)
    with pytest.raises(AttributeError):
        st.no_such_name  # noqa: B018


def test_command_table_matches_each_command_module():
    """The help shown for every command without importing it is the module's own."""
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    helps = {a.dest: a.help for a in sub._choices_actions}
    assert helps == cli.COMMANDS


def test_tolerances_method_choices_are_the_scenes():
    """``tolerances --method`` offers exactly the sampling methods a scene's ``[tolerances]``
    accepts (the parser names them without loading the scene reader)."""
    from servo_toolkit.cli import cmd_tolerances
    from servo_toolkit.scene import tolerances
    assert cmd_tolerances.METHODS == tolerances.METHODS
    from servo_toolkit.cli import cmd_new
    from servo_toolkit.scene import template
    assert cmd_new.OUTPUTS == template.OUTPUTS


def test_cache_path_follows_the_kernel_sources(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    path = jit_cache.cache_dir()
    assert path.is_relative_to(tmp_path / "servo_toolkit" / "numba")
    assert path.name.endswith(jit_cache.sources_hash())
    # a copy of the package with one kernel file edited hashes differently
    code = ("import pathlib, shutil, sys, tempfile\n"
            "src = pathlib.Path(sys.argv[1]); dst = pathlib.Path(tempfile.mkdtemp()) / 'servo_toolkit'\n"
            "shutil.copytree(src, dst, ignore=shutil.ignore_patterns('__pycache__'))\n"
            "k = dst / 'sim' / 'kernel.py'; k.write_text(k.read_text() + '\\n# edited\\n')\n"
            "sys.path.insert(0, str(dst.parent)); import servo_toolkit.core.jit_cache as j; print(j.sources_hash())")
    proc = subprocess.run([sys.executable, "-c", code, str(ROOT / "servo_toolkit")], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() != jit_cache.sources_hash()


def test_a_users_numba_cache_dir_is_still_keyed_on_the_kernel_sources(tmp_path):
    """NUMBA_CACHE_DIR chooses where the compiled kernels go; the sources hash still decides
    which compiled code is current, so an edited kernel never loads stale machine code."""
    env = {"NUMBA_CACHE_DIR": str(tmp_path)}
    code = ("from servo_toolkit.components.cam import kernels as cam_kernels\n"
            "cam_kernels.law(0.5, 1.0)\n"
            "from servo_toolkit.core.jit_cache import cache_dir, sources_hash; print(cache_dir()); print(sources_hash())")
    proc = _run(code, env)
    assert proc.returncode == 0, proc.stderr
    folder, digest = proc.stdout.split()
    assert folder.startswith(str(tmp_path / "servo_toolkit" / "numba")) and folder.endswith(digest)
    cached = list(Path(folder).rglob("kernels.law-*.nbi"))
    assert cached, "no index file in the hash-keyed folder under NUMBA_CACHE_DIR"


def test_kernels_cache_outside_a_read_only_package(tmp_path):
    """Compiled code goes to the per-user folder, never beside the package's sources."""
    env = {"XDG_CACHE_HOME": str(tmp_path), "NUMBA_CACHE_DIR": ""}
    code = ("import os; os.environ.pop('NUMBA_CACHE_DIR', None)\n"
            "from servo_toolkit.components.cam import kernels as cam_kernels\n"
            "cam_kernels.law(0.5, 1.0)\n"
            "from servo_toolkit.core.jit_cache import cache_dir; print(cache_dir())")
    proc = _run(code, env)
    assert proc.returncode == 0, proc.stderr
    cached = list((tmp_path / "servo_toolkit").rglob("kernels.law-*.nbi"))
    assert cached, "no index file in the per-user cache folder"


@pytest.mark.slow
def test_first_report_on_an_empty_cache_is_complete(tmp_path):
    """The README's first command on a fresh install: a fresh compiled-code cache, every
    section present, exit 0. The section time limit is raised so that a busy machine cannot
    fail the test (compilation happens before the sections; ``test_report`` checks that)."""
    out = tmp_path / "report"
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba-cache"), "MPLBACKEND": "Agg"}
    code = ("import sys\nfrom servo_toolkit.cli import main\n"
            f"sys.exit(main(['report', '-o', {str(out)!r}, '--section-time-limit', '600']))")
    proc = _run(code, env, timeout=900)
    assert "compiling the simulation kernels" in proc.stderr
    assert proc.returncode == 0, proc.stderr[-3000:]
    html = (out / "index.html").read_text()
    assert "stopped after" not in html
    assert 'class="unavailable-box"' not in html and 'class="badge unavailable"' not in html


def test_one_warm_up_compiles_every_kernel_and_says_so(tmp_path, monkeypatch, capsys):
    """Any command that simulates warms every kernel a user meets next (the single run's, the
    paper scheme's and the Monte Carlo batch's): with only the batch missing it still says
    that it compiles, and with every entry point cached it neither says nor warms anything
    (a command loads what it calls when it calls it)."""
    from servo_toolkit import load_scene
    from servo_toolkit.core import jit_cache
    from servo_toolkit.cli.common import prepare_kernels
    from servo_toolkit.studies import warmup
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "integrators._rk4-145.py311.nbi").write_bytes(b"")
    (tmp_path / "sim" / "integrators._paper-200.py311.nbi").write_bytes(b"")
    monkeypatch.setattr(jit_cache, "cache_dir", lambda: tmp_path)
    calls = []
    monkeypatch.setattr(warmup, "compile_kernels", lambda: calls.append("warm"))
    scene = load_scene()
    prepare_kernels(scene)
    assert "compiling the simulation kernels" in capsys.readouterr().err
    (tmp_path / "sim" / "batch_lanes.run_lanes-250.py311.nbi").write_bytes(b"")
    prepare_kernels(scene)
    assert "compiling" not in capsys.readouterr().err
    assert calls == ["warm"]


def test_the_warm_up_compiles_the_batch_beside_the_single_run(tmp_path, monkeypatch):
    """A cold batch compiles in a second process while the single run's kernels compile here;
    an interrupted warm-up stops that process too."""
    from servo_toolkit.studies import warmup
    order = []

    class Child:
        def wait(self):
            order.append("wait")

        def terminate(self):
            order.append("terminate")
    monkeypatch.setattr(warmup, "_batch_cached", lambda: False)
    monkeypatch.setattr(warmup, "_start_batch_process", lambda: order.append("start") or Child())
    monkeypatch.setattr(warmup, "_warm_single", lambda: order.append("single"))
    monkeypatch.setattr(warmup, "_warm_batch", lambda: order.append("batch"))
    warmup.compile_kernels()
    assert order == ["start", "single", "wait", "batch"]
    order.clear()

    def interrupted():
        raise KeyboardInterrupt
    monkeypatch.setattr(warmup, "_warm_single", interrupted)
    with pytest.raises(KeyboardInterrupt):
        warmup.compile_kernels()
    assert order == ["start", "terminate", "wait"]


def test_the_report_compiles_the_kernels_before_its_first_section(monkeypatch):
    """Compilation is never charged to a section's time limit: ``build_report`` loads (or
    compiles) every kernel before the first section starts its clock."""
    import servo_toolkit.report.builder as builder
    from servo_toolkit import load_scene
    from servo_toolkit.report.section import Section
    from servo_toolkit.studies import warmup
    order = []
    monkeypatch.setattr(warmup, "compile_kernels", lambda *a, **k: order.append("compile"))

    def section(key, title, build, ctx, time_limit=None):
        order.append(key)
        return Section(title, "", status="info")
    monkeypatch.setattr(builder, "run_section", section)
    monkeypatch.setattr(builder.loop, "requirement_rows", lambda ctx: ())
    builder.build_report(load_scene(), progress=False)
    assert order[0] == "compile" and order.count("compile") == 1 and len(order) > 5
