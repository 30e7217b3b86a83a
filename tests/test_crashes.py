"""Real options that used to crash: signals, a closed stdout, process pools, extreme values
and runs far beyond the work budget. Each is one stderr line and a documented exit code."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from servo_toolkit.cli import main

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
EMA = str(SCENES / "ema_reference.toml")


def _env():
    return dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.startswith("servo-toolkit:")
             and not ln.startswith(("servo-toolkit: compiling", "servo-toolkit: note:"))]
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    return lines[0]


# --- signals -------------------------------------------------------------------------------

def test_sigterm_during_report_exits_143_and_keeps_the_earlier_report(tmp_path):
    out = tmp_path / "rep"
    out.mkdir()
    earlier = '<meta name="generator" content="servo_toolkit 0">earlier report'
    (out / "index.html").write_text(earlier)
    proc = subprocess.Popen([sys.executable, "-m", "servo_toolkit", "report",
                             str(SCENES / "deflection_platform.toml"), "-o", str(out)],
                            cwd=ROOT, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 600  # generous: a fresh kernel cache compiles first
    seen = False
    while proc.poll() is None and time.monotonic() < deadline:
        if any(p.name.startswith(".rep.") for p in tmp_path.iterdir()):
            seen = True
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the report finished before its temporary folder was seen"
    assert seen
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 143, err
    assert _one_error_line(err) == "servo-toolkit: terminated"
    assert [p.name for p in tmp_path.iterdir()] == ["rep"]  # no temporary folder left
    assert (out / "index.html").read_text() == earlier


def test_sigterm_in_process_is_an_interrupt(monkeypatch, capsys):
    """The handler is installed while a command runs and turns SIGTERM into exit 143."""
    import servo_toolkit.cli.cmd_stiffness as cmd

    def run(args):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler raises before this returns
        return 0
    monkeypatch.setattr(cmd, "run", run)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["stiffness", EMA]) == 143
    assert capsys.readouterr().err.strip() == "servo-toolkit: terminated"
    assert signal.getsignal(signal.SIGTERM) is before  # restored


@pytest.mark.parametrize("signalled, code, line", [("sigterm", 143, "servo-toolkit: terminated"),
                                                   ("ctrl-c", 130, "servo-toolkit: interrupted")])
def test_a_signal_landing_in_a_late_imports_class_body_still_ends_the_command(monkeypatch, capsys, signalled,
                                                                                code, line):
    """A signal that arrives while a library defines its classes (the report's PDF engine is
    imported late) reaches the command as the cause of a RuntimeError on Python 3.11: it is
    still the signal's exit code and one line."""
    import servo_toolkit.cli.cmd_stiffness as cmd
    from servo_toolkit.cli import Terminated

    class Described:
        def __set_name__(self, owner, name):
            raise Terminated() if signalled == "sigterm" else KeyboardInterrupt()

    def run(args):
        type("LibraryClass", (), {"attribute": Described()})  # a class body, as an import runs it
        return 0
    monkeypatch.setattr(cmd, "run", run)
    assert main(["stiffness", EMA]) == code
    assert capsys.readouterr().err.strip() == line


def test_an_error_not_caused_by_a_signal_is_not_taken_for_one(monkeypatch):
    import servo_toolkit.cli.cmd_stiffness as cmd

    def run(args):
        try:
            raise ValueError("inner")
        except ValueError as exc:
            raise RuntimeError("a defect") from exc
    monkeypatch.setattr(cmd, "run", run)
    with pytest.raises(RuntimeError, match="a defect"):
        main(["stiffness", EMA])


# --- closed stdout ------------------------------------------------------------------------

@pytest.mark.parametrize("require, code", [([], 0), (["--require", "phase_margin=179 deg"], 1)])
def test_closed_stdout_keeps_the_verdict(require, code):
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", "check", EMA, "--linear-only", *require],
                          cwd=ROOT, env=_env(), stderr=subprocess.PIPE, text=True, timeout=600,
                          preexec_fn=lambda: os.close(1))
    assert proc.returncode == code, proc.stderr
    assert "Traceback" not in proc.stderr


def test_closed_stdout_in_process(monkeypatch):
    monkeypatch.setattr(sys, "stdout", None)
    assert main(["stiffness", EMA]) == 0


@pytest.mark.parametrize("require, code", [([], 0), (["--require", "phase_margin=179 deg"], 1)])
def test_an_ascii_stdout_keeps_the_verdict_of_a_scene_named_with_an_accent(tmp_path, monkeypatch, require, code):
    import io
    scene = tmp_path / "actionneur.toml"
    scene.write_text(Path(EMA).read_text(encoding="utf-8").replace('name = "ema_reference"', 'name = "vérin"', 1),
                     encoding="utf-8")
    raw = io.BytesIO()
    monkeypatch.setattr(sys, "stdout", io.TextIOWrapper(raw, encoding="ascii"))  # LANG=C without UTF-8 mode
    assert main(["check", str(scene), "--linear-only", *require]) == code
    sys.stdout.flush()
    assert raw.getvalue().decode("ascii").startswith("v\\xe9rin (")


# --- process pools -------------------------------------------------------------------------

def _montecarlo_json(capsys, *extra):
    import json
    assert main(["montecarlo", EMA, "--samples", "16", "--duration", "0.05", "--json", *extra]) == 0
    data = json.loads(capsys.readouterr().out)
    data.pop("wall_s")
    return data


def test_montecarlo_workers_match_one_process(capsys):
    """Workers are spawned (a forked child of a process running OpenMP threads aborts)."""
    assert _montecarlo_json(capsys, "--workers", "2") == _montecarlo_json(capsys)


def test_process_pool_spawns():
    from servo_toolkit.core.parallel import process_pool
    with process_pool(1) as pool:
        assert pool._mp_context.get_start_method() == "spawn"


# --- extreme values that raised tracebacks --------------------------------------------------

def test_bandwidth_requirement_below_the_design_grid_is_one_line(capsys):
    assert main(["design", EMA, "--require", "bandwidth=1e-300 Hz", "--linear-only"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("servo-toolkit: error: --require bandwidth=1e-300 Hz: must lie in [0.01, 5000] Hz")


def test_two_stiffnesses_in_series_fit_and_say_why_not_identified(tmp_path, capsys):
    """Two stiffnesses in series (the housing and the link rod, the arm's inertia between them):
    the response separates them only weakly. The fit's optimum sat on a kink of the model (the
    chain's lowest mode changes the segment it takes its damping from), where the Jacobian gave
    intervals of +-0.1 % that missed the truth. The profile follows the cost along the ridge:
    both 95 % intervals contain the truth, and the rod's spans several times its value (its
    profile stays low toward stiffer rods, which the housing trades against)."""
    import json

    import numpy as np

    from servo_toolkit import load_scene
    from servo_toolkit.identify import FrequencyData
    from servo_toolkit.identify.model import plant_response
    from servo_toolkit.identify.params import SceneTemplate

    keys = ["drivetrain[3].stiffness", "drivetrain[2].rod_axial_stiffness"]
    template = SceneTemplate(load_scene(EMA), keys)
    truth = np.array(template.initial) * np.array([0.8, 1.2])
    f = np.logspace(0, np.log10(300), 60)
    rng = np.random.default_rng(1)
    h = plant_response(template.scene(truth), f) * 10 ** (rng.normal(0, 0.2, f.size) / 20) \
        * np.exp(1j * np.radians(rng.normal(0, 1.0, f.size)))
    data = FrequencyData.from_complex(f, h)
    csv = tmp_path / "rig.csv"
    np.savetxt(csv, np.column_stack([data.frequency_hz, data.gain_db, data.phase_deg]), delimiter=",",
               header="frequency_hz,gain_db,phase_deg", comments="", fmt="%.9g")
    assert main(["fit", EMA, str(csv), "--param", keys[0], "--param", keys[1], "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] == "not identifiable"
    warnings = "\n".join(out["warnings"])
    assert "identify only a combination of them" in warnings
    assert f"{keys[1]}: the data cannot identify it" in warnings
    for par, t in zip(out["parameters"], truth):
        lo, hi = par["ci95"]
        assert lo < t < hi, (par["key"], lo, t, hi)
    profiles = {p["key"]: p for p in out["profiles"]}
    assert set(profiles) == set(keys)
    rod = profiles[keys[1]]
    assert rod["interval"][1] > 3 * rod["value"]  # the weak separation: +-0.1 % before
    for p in profiles.values():  # an end of the interval is where the rise crosses the threshold
        values, rise = np.array(p["values"]), np.array(p["rise"])
        assert rise.min() > -0.01  # no point below the optimum's cost
        for end, open_ in zip(p["interval"], p["unbounded"]):
            if not open_:  # points at or below and at or past the threshold within 0.1 % of the end
                near = rise[np.abs(np.log(values / end)) < 1e-3] / p["threshold"]
                assert near.min() < 1 + 1e-5 and near.max() > 1 - 1e-5


def test_exact_fit_has_a_correlation(tmp_path):
    """Noise-free data (residual 0) still give the parameters' correlation."""
    import numpy as np

    from servo_toolkit.identify.fit import _intervals
    jac = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])
    half, corr, singular = _intervals(jac, np.zeros(3), 1)
    assert np.all(half == 0) and not singular.any()
    assert np.all(np.isfinite(corr)) and corr[0, 0] == 1.0


# --- work budgets ---------------------------------------------------------------------------

def _scene_file(tmp_path, name, old, new, source=EMA):
    text = Path(source).read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return str(path)


def test_a_picosecond_sample_time_is_refused_by_the_budget(tmp_path, capsys):
    scene = _scene_file(tmp_path, "ps.toml", 'sample_time = "0.1 ms"', 'sample_time = "1e-12 s"')
    assert main(["simulate", scene]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("servo-toolkit: error: sensors.sample_time: the run is estimated at")
    assert "--force" in line and "(got 1e-12 s)" in line


def test_forced_picosecond_reference_run_is_one_line_not_7_tib(tmp_path, capsys):
    scene = _scene_file(tmp_path, "ps.toml", 'sample_time = "0.1 ms"', 'sample_time = "1e-12 s"')
    assert main(["simulate", scene, "--method", "reference", "--force"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("servo-toolkit: simulation error: the reference solver restarts at every controller sample")


@pytest.mark.parametrize("args, key", [(["--duration", "inf"], "--duration: must be finite"),
                                       (["--duration", "nan"], "--duration: must be positive"),
                                       (["--samples", "1000000000"], "--samples: must be at most 1000000"),
                                       (["--samples", "1000000"], "--samples: the run is estimated at"),
                                       (["--duration", "1e6"], "--duration: the run is estimated at"),
                                       (["--workers", "100000"], "--workers: must be at most 256")])
def test_montecarlo_extremes_are_one_line(args, key, capsys):
    assert main(["montecarlo", EMA, *args]) == 2
    assert _one_error_line(capsys.readouterr().err).startswith(f"servo-toolkit: error: {key}")


def test_a_million_robustness_samples_are_refused_before_the_design(tmp_path, capsys):
    scene = _scene_file(tmp_path, "rob.toml", "samples = 1000\n", "samples = 1000000\n",
                        source=SCENES / "ema_robust.toml")
    for command in (["check", scene], ["design", scene], ["report", scene, "-o", str(tmp_path / "rep")]):
        assert main(command) == 2
        err = capsys.readouterr().err
        line = _one_error_line(err)
        assert "robustness.samples: the run is estimated at" in line and "variants of a robust design" in line
    assert not (tmp_path / "rep").exists()


def test_check_samples_option_is_the_knob_named(capsys):
    assert main(["check", str(SCENES / "ema_robust.toml"), "--samples", "1000000"]) == 2
    assert ": --samples: the run is estimated at" in _one_error_line(capsys.readouterr().err)


def test_kv_of_a_thousand_stage_chain_is_refused(tmp_path, capsys):
    gear = ('[[drivetrain]]\nkind = "gear"\nteeth = [30, 30]\ninertia = ["1e-6 kg*m^2", "1e-6 kg*m^2"]\n'
            'efficiency = 0.999\ntorsional_stiffness = "1.6e6 N*m/rad"\n\n')
    scene = _scene_file(tmp_path, "chain.toml", "[[drivetrain]]", gear * 1000 + "[[drivetrain]]")
    assert main(["kv", scene]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("servo-toolkit: error: drivetrain: the run is estimated at")
    assert "1004 stages" in line


@pytest.mark.parametrize("command", ["check", "design", "report"])
def test_a_design_on_a_thousand_stage_chain_is_refused_before_it_runs(tmp_path, capsys, monkeypatch, command):
    """The loop's margins on the n-mass plant of 1004 modes are hours of work: refused with one
    line naming the drivetrain and --force, before any design starts."""
    import importlib
    loop_design = importlib.import_module("servo_toolkit.loop.design")

    def no_design(*args, **kwargs):
        raise AssertionError("the design started")
    monkeypatch.setattr(loop_design, "design", no_design)
    monkeypatch.setattr(loop_design, "evaluate", no_design)
    gear = ('[[drivetrain]]\nkind = "gear"\nteeth = [30, 30]\ninertia = ["1e-6 kg*m^2", "1e-6 kg*m^2"]\n'
            'efficiency = 0.999\ntorsional_stiffness = "1.6e6 N*m/rad"\n\n')
    scene = _scene_file(tmp_path, "chain.toml", "[[drivetrain]]", gear * 1000 + "[[drivetrain]]")
    extra = ["-o", str(tmp_path / "rep")] if command == "report" else []
    assert main([command, scene, *extra]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert "drivetrain: the run is estimated at" in line and " h (" in line
    assert "1004 drivetrain modes" in line and "--force" in line and "(got 1004 stages)" in line
    assert not (tmp_path / "rep").exists()


def test_a_ten_thousand_point_sweep_is_refused(tmp_path, capsys):
    text = Path(EMA).read_text()
    scene = tmp_path / "sweep.toml"
    scene.write_text(text + '\n[studies.dense]\nkind = "frequency_sweep"\namplitude = "1 deg"\n'
                     'frequencies = { start = "1 Hz", stop = "100 Hz", points = 10000 }\n')
    assert main(["sweep", str(scene), "--study", "dense"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("servo-toolkit: error: studies.dense.frequencies: the run is estimated at")
    assert main(["reduce", str(scene), "--study", "dense"]) == 2
    assert "studies.dense.frequencies: the run is estimated at" in _one_error_line(capsys.readouterr().err)


def test_accuracy_at_a_picosecond_sample_time_is_refused(tmp_path, capsys):
    scene = _scene_file(tmp_path, "ps.toml", 'sample_time = "0.1 ms"', 'sample_time = "1e-12 s"')
    assert main(["accuracy", scene]) == 2
    assert "sensors.sample_time: the run is estimated at" in _one_error_line(capsys.readouterr().err)


def test_budget_estimates_are_stated_in_one_place():
    from servo_toolkit.cli import budget
    assert budget.TIME_BUDGET_S == 600.0
    with pytest.raises(Exception, match="--force"):
        budget.check_time(1e9, "knob", "work", 1)
    budget.check_time(1e9, "knob", "work", 1, force=True)  # forced: no refusal


def test_a_vanishing_current_sample_time_is_refused(tmp_path, capsys):
    assert main(["export", EMA, "-o", str(tmp_path / "o"), "--current-sample-time", "1e-300 s"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("servo-toolkit: error: --current-sample-time: must be at least 0.1 us")
    assert not (tmp_path / "o").exists()


def test_reduce_tolerance_is_one_line(capsys):
    assert main(["reduce", EMA, "--estimate-only", "--tolerance", "1e300"]) == 2
    assert _one_error_line(capsys.readouterr().err).startswith("servo-toolkit: error: --tolerance: must lie in (0, 1)")


def test_a_long_simulate_study_names_its_duration(tmp_path, capsys):
    text = Path(EMA).read_text()
    scene = tmp_path / "long.toml"
    scene.write_text(text + '\n[studies.long]\nkind = "simulate"\namplitude = "1 deg"\nfrequency = "2 Hz"\n'
                     'duration = "900 s"\nmethod = "reference"\n')
    assert main(["simulate", str(scene), "--study", "long"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line.startswith("servo-toolkit: error: studies.long.duration: the run is estimated at")
    assert "reference-solver segments" in line and line.endswith("(got 900 s)")
