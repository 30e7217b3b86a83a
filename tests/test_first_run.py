"""A fresh install: light imports (no numerical library, not the compiled kernels, for a\n``--help``), the kernels loaded from the package and no JIT, a complete first report."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from servo_toolkit import cli

from .conftest import ROOT

HEAVY = ("control", "scipy", "numba", "llvmlite", "matplotlib", "pint")
#: the compiled physics, loaded by the first simulation and never by a --help
KERNELS = "servo_toolkit._physics._kernels"


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
            f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})"
            f" | {{m for m in sys.modules if m == {KERNELS!r}}})))")
    proc = _run(code)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_import_and_help_load_no_numerical_library():
    assert _heavy_loaded(None) == []
    assert _heavy_loaded(["--help"]) == []


@pytest.mark.parametrize("command", list(cli.COMMANDS))
def test_a_commands_help_loads_no_numerical_library(command):
    """``servo-toolkit CMD --help`` builds the command's parser from the light command-line
    modules alone: no scipy, python-control, matplotlib, pint nor the compiled kernels."""
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
libraries = sorted(m for m in ("control", "matplotlib", "scipy.signal") if m in sys.modules)
print(json.dumps({"code": code, "importer": Watch.importer, "toolkit": toolkit, "libraries": libraries}))
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
    and no toolkit module imports matplotlib on its way."""
    assert check_imports["code"] == 0
    plotting = [m for m in check_imports["toolkit"] if m.split(".")[1] in ("report", "tuner") or m.endswith("_plot")]
    assert plotting == []
    importer = check_imports["importer"]
    assert importer is None or not importer.startswith("servo_toolkit"), importer


def test_a_text_verdict_imports_no_matplotlib(check_imports):
    """The verdict is computed on the toolkit's own state-space blocks: neither
    python-control (which loads matplotlib.pyplot and scipy.signal when imported) nor a
    plotting library is loaded."""
    assert check_imports["importer"] is None
    assert check_imports["libraries"] == []


def test_a_robust_verdict_imports_no_matplotlib():
    """A robust design's check (the variants' grid, the worst case rebuilt from the scene)
    computes on the toolkit's own blocks too."""
    proc = subprocess.run([sys.executable, "-c", _FIRST_IMPORTER, "check", str(ROOT / "scenes" / "ema_robust.toml")],
                          capture_output=True, text=True, timeout=900, cwd=ROOT)
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["code"] == 1  # the scene misses its worst-case Ms: a verdict all the same
    assert got["importer"] is None and got["libraries"] == []


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


def test_a_simulation_loads_the_compiled_kernels_and_no_jit():
    """The physics comes compiled with the package: a run loads the extension module and
    neither numba nor llvmlite, and writes nothing to a cache."""
    code = ("import sys\nfrom servo_toolkit import load_scene, simulate\n"
            "r = simulate(load_scene(), duration=0.02)\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'llvmlite'}), "
            "'servo_toolkit._physics._kernels' in sys.modules)")
    proc = _run(code)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split("\n")[-2] == "[] True"


@pytest.mark.slow
def test_first_report_of_a_fresh_process_is_complete(tmp_path):
    """The README's first command: every section present, exit 0, nothing compiled at run
    time. The section time limit is raised so that a busy machine cannot fail the test."""
    out = tmp_path / "report"
    code = ("import sys\nfrom servo_toolkit.cli import main\n"
            f"sys.exit(main(['report', '-o', {str(out)!r}, '--section-time-limit', '600']))")
    proc = _run(code, {"MPLBACKEND": "Agg"}, timeout=900)
    assert "compiling" not in proc.stderr
    assert proc.returncode == 0, proc.stderr[-3000:]
    html = (out / "index.html").read_text()
    assert "stopped after" not in html
    assert 'class="unavailable-box"' not in html and 'class="badge unavailable"' not in html
